"""A compile change measured side by side in one process: a reference tree's file (an export of
an older commit, ``--before DIR``) loaded under another module name beside this tree's, both
compiled against the same cached callees, then both run alternately on the same inputs (the
answers compared bit for bit, per-call medians). CPU seconds of this process
(``time.process_time``); the order of the two compilations is ``--order`` (``ba``: the
reference first). Figures in cold_start.md (2026-12-07, twenty-first session).

    python benchmarks/compile_ab.py packed --before DIR [--order ba|ab]
    python benchmarks/compile_ab.py tick --before DIR [--order ba|ab] [--rounds 3]
    python benchmarks/compile_ab.py generated --before DIR [--order ba|ab]

``packed``: :func:`wbc.limits.collision_packed.packed_rows` (a third copy of this tree's file
compiled first, so that the shared collision kernels are cached for both; this tree's file is
copied beside it for a cache of its own), then 3000 random configurations near Walk Ready.
``tick``: the generated tick module of the reference's ``wbc/compiled/template.py`` against
this tree's, the ``walk`` stack's weighted and hierarchical solvers of each stepped on 300
configurations near Walk Ready (``--rounds`` times). ``generated``: the same two templates'
tick modules compiled (the first step of each solver), each text suffixed with a comment so
that neither is cached. ``tick`` and ``generated`` compile in this process
(``WBC_COMPILE_WORKER=1`` is set); the callees load from the numba cache when there.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
os.environ.setdefault("WBC_COMPILE_WORKER", "1")  # (the ticks compile here, timed)


def _load(name: str, path: Path, package: str | None = None):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    if package:
        module.__package__ = package
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def packed(before: Path, order: str) -> None:
    from wbc import load_robot
    from wbc.limits.self_collision import SelfCollisionConstraint
    from wbc.model import Kinematics

    own = Path(tempfile.mkdtemp(prefix="compile_ab_"))
    for f in ("collision_packed.py", "collision_kernels.py", "joint_limits.py"):
        shutil.copy(ROOT / "wbc" / "limits" / f, own / f)
    files = {
        "warm": ROOT / "wbc" / "limits" / "collision_packed.py",
        "before": before / "wbc" / "limits" / "collision_packed.py",
        "after": own / "collision_packed.py",
    }
    mods = {k: _load(f"wbc.limits.cp_{k}", f, "wbc.limits") for k, f in files.items()}
    robot = load_robot()
    q0 = robot.configuration("walk_ready")
    rng = np.random.default_rng(0)
    qs = [q0.copy() for _ in range(3000)]
    for q in qs:
        q[7:] += rng.normal(scale=0.15, size=q.size - 7)
    calls = {}
    for k in mods:
        lim = SelfCollisionConstraint(robot)
        kin = Kinematics(robot, q0)
        G, h = np.zeros((lim.max_rows + 1, robot.nv)), np.zeros(lim.max_rows + 1)
        calls[k] = (kin, lim._bind(kin), G, h)
    accessors = ("_f1", "_i1", "_f2", "_f3", "_j1", "_b1", "_b2")
    for k in ["warm", *(("before", "after") if order == "ba" else ("after", "before"))]:
        kin, call, G, h = calls[k]
        t = time.process_time()
        r = mods[k].packed_rows(kin.q, *call[1:], G, h, 0)
        n = sum(len(getattr(mods[k], a).signatures) for a in accessors)
        print(f"{k}: compile + first call {time.process_time() - t:.2f} CPU s ({r} rows), "
              f"accessor signatures {n}", flush=True)  # fmt: skip
    times: dict[str, list] = {"before": [], "after": []}
    outs: dict[str, list] = {"before": [], "after": []}
    for i, q in enumerate(qs):
        for k in ("before", "after") if i % 2 else ("after", "before"):
            kin, call, G, h = calls[k]
            kin.update(q)
            t = time.perf_counter()
            r = mods[k].packed_rows(kin.q, *call[1:], G, h, 0)
            times[k].append(time.perf_counter() - t)
            outs[k].append((r, G[: max(r, 0)].copy(), h[: max(r, 0)].copy()))
    same = all(
        a[0] == b[0] and np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])
        for a, b in zip(outs["before"], outs["after"], strict=True)
    )
    print("rows bit for bit:", same, "mean rows", np.mean([o[0] for o in outs["after"]]))
    for k, t in times.items():
        us = np.array(t) * 1e6
        print(f"{k}: warm call median {np.median(us):.2f} µs, p90 {np.percentile(us, 90):.2f}")
    print("after/before median ratio", np.median(times["after"]) / np.median(times["before"]))


def _sources(before: Path, tag: str = ""):
    from wbc.compiled import dispatch

    old = _load("template_before", before / "wbc" / "compiled" / "template.py")
    new = dispatch.source
    return {
        "before": lambda *a, **k: old.source(*a, **k) + tag,
        "after": lambda *a, **k: new(*a, **k) + tag,
    }


def _solvers(before: Path, order: str, tag: str = "") -> dict:
    """Each version's walk solvers, their ticks compiled (timed) by a first step."""
    from wbc import load_robot
    from wbc.compiled import dispatch
    from wbc.stacks import load_stack

    robot = load_robot()
    q0 = robot.configuration("walk_ready")
    sources = _sources(before, tag)
    solvers = {}
    for version in ("before", "after") if order == "ba" else ("after", "before"):
        dispatch.source = sources[version]  # (its text: a tick module of its own name)
        dispatch._ticks.cache_clear()
        for kind in ("weighted", "hierarchical"):
            s = load_stack("walk", robot, solver=kind).solver
            t = time.process_time()
            s.step(q0, 0.01)
            print(f"{version} {kind}: first step {time.process_time() - t:.1f} CPU s, "
                  f"compiled ticks {s.compiled_ticks}", flush=True)  # fmt: skip
            solvers[(version, kind)] = s
    return solvers


def tick(before: Path, order: str, rounds: int) -> None:
    from wbc import load_robot

    q0 = load_robot().configuration("walk_ready")
    rng = np.random.default_rng(1)
    qs = [q0.copy() for _ in range(300)]
    for q in qs:
        q[7:] += rng.normal(scale=0.01, size=q.size - 7)
    solvers = _solvers(before, order)
    out: dict = {k: [] for k in solvers}
    times: dict = {k: [] for k in solvers}
    for rnd in range(rounds):
        for i, q in enumerate(qs):
            for kind in ("weighted", "hierarchical"):
                for version in ("before", "after") if (i + rnd) % 2 else ("after", "before"):
                    s = solvers[(version, kind)]
                    t = time.perf_counter()
                    try:
                        x = s.step(q, 0.01)
                    except Exception as e:  # (the same failure both: compared)
                        x = repr(e)
                    times[(version, kind)].append(time.perf_counter() - t)
                    if rnd == 0:
                        out[(version, kind)].append(x)
    for kind in ("weighted", "hierarchical"):
        a, b = out[("after", kind)], out[("before", kind)]
        same = all(
            (x == y) if isinstance(x, str) else np.array_equal(x, y)
            for x, y in zip(a, b, strict=True)
        )
        fails = sum(isinstance(x, str) for x in a)
        ta = np.median(times[("after", kind)]) * 1e6
        tb = np.median(times[("before", kind)]) * 1e6
        print(f"{kind}: bit for bit {same} ({fails} failed steps of {len(a)}); step median "
              f"before {tb:.1f} µs, after {ta:.1f} µs, ratio {ta / tb:.3f}")  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("what", choices=("packed", "tick", "generated"))
    parser.add_argument("--before", type=Path, required=True, help="an export of the reference")
    parser.add_argument("--order", choices=("ba", "ab"), default="ba")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    if args.what == "packed":
        packed(args.before, args.order)
    elif args.what == "tick":
        tick(args.before, args.order, args.rounds)
    else:
        _solvers(args.before, args.order, tag=f"\n# compile_ab {time.time()}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
