"""In-numba time of wbc.compiled.lsq.solve_level on the walk's problems, working tree vs HEAD.

Run from the repository root: python benchmarks/lsq_level.py [--rev HEAD]
The problems are those of the walk10 reference (core walk stack, as benchmarks/qp_tick.py):
the weighted QP (single support m=6 p=30, double support m=12 p=24) and the three levels of
the hierarchical QP, at ticks whose final active set is empty, solved from a zero warm start;
plus the mean over all 565 weighted ticks with the warm start the loop actually had. Each
figure is the best of 7 runs of an @njit loop calling solve_level K times (so no Python
dispatch), in µs per call.
"""

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, ".")
sys.path.insert(0, "benchmarks")
from qp_tick import core_walk_spec

from wbc import load_robot
from wbc.bench.trajectories import build
from wbc.stacks import build_stack
from wbc.walking.loop import Session, StackController


def capture():
    robot = load_robot()
    ref = build("walk10", robot)
    weighted, hier = [], []
    ctl = StackController(build_stack({**core_walk_spec(), "solver": "weighted"}, robot))
    s = Session(ctl, robot, ref)
    for i in range(len(ref.t)):
        f = ctl.solver.fast
        st0 = f.state.copy() if f is not None else np.zeros(robot.nv, np.int8)
        s.tick(i)
        f = ctl.solver.fast
        weighted.append(
            (
                f.hard.J.copy(),
                f.hard.b.copy(),
                f.soft.J.copy(),
                f.soft.b.copy(),
                float(f.params[1]),
                f.lower.copy(),
                f.upper.copy(),
                st0,
                f.state.copy(),
            )
        )
    ctl = StackController(build_stack({**core_walk_spec(), "solver": "hierarchical"}, robot))
    s = Session(ctl, robot, ref)
    for i in range(len(ref.t)):
        s.tick(i)
        f = ctl.solver.fast
        hier.append(
            (
                f.rows.J.copy(),
                f.rows.b.copy(),
                f.level_rows.copy(),
                f.lower.copy(),
                f.upper.copy(),
                f.achieved.copy(),
                f.states.copy(),
                float(f.params[1]),
            )
        )
    return weighted, hier


def cases(weighted, hier):
    out = {}
    for name, m in (("weighted m=6 p=30", 6), ("weighted m=12 p=24", 12)):
        ws = [w for w in weighted if w[0].shape[0] == m and not w[8].any()]
        A, a, B, r, mu, lo, up, _, _ = ws[len(ws) // 2]
        out[name] = (A, a, B, r, mu, lo, up, 1e-9, 30)
    hs = [h for h in hier if h[2][1] == 6 and not h[6].any()]
    J, b, lr, lo, up, ach, _, mu = hs[len(hs) // 2]
    for k, ridge, it in ((0, 0.0, 12), (1, 0.0, 12), (2, mu, 30)):
        r0, r1 = lr[k], lr[k + 1]
        name = f"hierarchical level {k} m={r0} p={r1 - r0}"
        out[name] = (
            J[:r0].copy(),
            ach[:r0].copy(),
            J[r0:r1].copy(),
            b[r0:r1].copy(),
            ridge,
            lo,
            up,
            1e-9,
            it,
        )
    return out


def timer(mod):
    solve = mod.solve_level

    @njit
    def loop(k, A, a, B, r, ridge, lo, up, st0, state, x, rtol, max_iter):
        s = 0
        for _ in range(k):
            state[:] = st0
            s += solve(A, a, B, r, ridge, lo, up, state, x, rtol, max_iter)
        return s

    def run(A, a, B, r, ridge, lo, up, rtol, max_iter, st0=None, k=2000, reps=7):
        st0 = np.zeros(A.shape[1], np.int8) if st0 is None else st0
        args = (
            A,
            a,
            B,
            r,
            ridge,
            lo,
            up,
            st0,
            np.zeros_like(st0),
            np.zeros(A.shape[1]),
            rtol,
            max_iter,
        )
        loop(10, *args)
        best = np.inf
        for _ in range(reps):
            t0 = time.perf_counter()
            loop(k, *args)
            best = min(best, (time.perf_counter() - t0) / k * 1e6)
        return best

    return run


def load(sources: dict[str, str], name: str, tmp: Path):
    """The solver's modules (``wbc/compiled/lsq*.py`` and what they import) as package
    ``name`` in ``tmp``, its ``lsq`` module."""
    package = tmp / name
    package.mkdir()
    (package / "__init__.py").write_text("")
    for file, text in sources.items():
        (package / file).write_text(text)
    sys.path.insert(0, str(tmp))
    return importlib.import_module(f"{name}.lsq")


def sources_at(rev: str) -> dict[str, str]:
    """The solver's files at git revision ``rev``."""
    files = subprocess.run(
        ["git", "ls-tree", "--name-only", rev, "wbc/compiled/"],
        capture_output=True, text=True, check=True,
    ).stdout.split()  # fmt: skip
    return {
        Path(f).name: subprocess.run(
            ["git", "show", f"{rev}:{f}"], capture_output=True, text=True, check=True
        ).stdout
        for f in files
        if Path(f).name.startswith("lsq") or Path(f).name == "_cache.py"
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--rev", default="HEAD")
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp())
    tree = {
        f.name: f.read_text()
        for f in Path("wbc/compiled").glob("*.py")
        if f.name.startswith("lsq") or f.name == "_cache.py"
    }
    mods = {
        args.rev: load(sources_at(args.rev), "lsq_rev", tmp),
        "working tree": load(tree, "lsq_tree", tmp),
    }
    weighted, hier = capture()
    timers = {k: timer(m) for k, m in mods.items()}
    print(f"{'case':38s}" + "".join(f"{k:>16s}" for k in mods))
    for name, c in cases(weighted, hier).items():
        print(f"{name:38s}" + "".join(f"{t(*c):14.2f}µs" for t in timers.values()))
    means = []
    for t in timers.values():
        means.append(
            np.mean(
                [
                    t(w[0], w[1], w[2], w[3], w[4], w[5], w[6], 1e-9, 30, st0=w[7], k=200, reps=3)
                    for w in weighted
                ]
            )
        )
    print(f"{'weighted, mean over all 565 ticks':38s}" + "".join(f"{v:14.2f}µs" for v in means))


if __name__ == "__main__":
    main()
