"""Cold start on a fresh install: numba's and wbc's caches pointed at empty directories, then
(1) the ``walk`` stack ticked with each solver in a new interpreter until both ticks run
compiled: when the first tick is answered (on the numpy path while the workers compile),
when the first compiled tick runs, and the CPU of all of it (workers included); (2) the
README's quick-start job, ``wbc bench --json … --plots …``: the time to its first result
line and to its end; each run cold (empty caches), then warm (the caches it filled).

Run: ``python benchmarks/cold_start.py [--job first|solve|bench|both|interim] [--backend B]``
(``first``: (1) until the first answers only, the workers stopped then, on backend ``B``;
``interim``: with warm caches, a tick's time on the numpy path, as while the ticks compile,
against the compiled tick). Prints a
markdown table; the caches live in a temporary directory, the user's own are left alone
(``interim``: uses them). Figures in cold_start.md.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

FIRST_TICKS = """
import time
start = time.perf_counter()
from wbc import load_robot
from wbc.solvers.plan import package_ticks
from wbc.stacks import load_stack
robot = load_robot()
q = robot.configuration("walk_ready")
solvers = {
    k: load_stack("walk", robot, solver=k, backend=BACKEND).solver
    for k in ("weighted", "hierarchical")
}
seen = set()
goal = 2 if FIRST_ONLY else 4
while len(seen) < goal and time.perf_counter() - start < 1200:
    for kind, s in solvers.items():
        s.step(q, 0.01)  # (a loop ticking every 20 ms)
        t = time.perf_counter() - start
        for what, done in (("answered", True), ("compiled", s.compiled_ticks > 0)):
            if done and (kind, what) not in seen:
                seen.add((kind, what))
                cpu = time.process_time()  # (this process's own)
                print(f"{kind}: first {what} tick after {t:.1f} s ({cpu:.1f} s CPU)", flush=True)
    time.sleep(0.02)
if FIRST_ONLY:  # the first answers only: stop the workers
    for worker in package_ticks().builders.values():
        worker.kill()
package_ticks().wait_all()  # (their CPU counts)
"""


TICKS = "FIRST_ONLY = False\nBACKEND = None\n" + FIRST_TICKS

INTERIM_COST = """
import time
import numpy as np
from wbc import load_robot
from wbc.solvers.plan import _Plan
from wbc.stacks import load_stack
robot = load_robot()
q = robot.configuration("walk_ready")
for interim in (False, True):
    if interim:  # as while the workers compile: the numpy path
        _Plan.ready = lambda self: False
    for kind in ("weighted", "hierarchical"):
        s = load_stack("walk", robot, solver=kind).solver
        s.step(q, 0.01)
        t = []
        for _ in range(300):
            t0 = time.perf_counter()
            s.step(q, 0.01)
            t.append(time.perf_counter() - t0)
        path = "interim (numpy path)" if interim else "compiled"
        print(f"| {kind} | {path} | {np.median(t) * 1e6:.0f} |", flush=True)
"""


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(cmd: list[str], env: dict, marks: list[str]) -> tuple[float, float, list]:
    """(wall s, CPU s of the process and the workers it waited for, wall s until the first
    stdout line containing each of ``marks``, None if none did)."""
    cpu = children_cpu()
    start = time.perf_counter()
    seen: list[float | None] = [None] * len(marks)
    with subprocess.Popen(
        cmd, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    ) as p:
        for line in p.stdout:
            for i, mark in enumerate(marks):
                if seen[i] is None and mark in line:
                    seen[i] = time.perf_counter() - start
            sys.stderr.write("    | " + line)
    if p.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode})")
    return time.perf_counter() - start, children_cpu() - cpu, seen


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--job",
        choices=("first", "solve", "bench", "both", "interim"),
        default="both",
        help="first: the walk stack's first answers only (the workers stopped then); "
        "interim: a tick's time on the numpy path meanwhile against the compiled one (warm)",
    )
    parser.add_argument(
        "--backend",
        choices=("daqp", "proxqp", "quadprog", "osqp"),
        help="--job first: the solvers' QP backend (default: the stack's); the cold first tick "
        "answers on the numpy path on every backend (benchmarks/stress.md, issue 28)",
    )
    args = parser.parse_args()
    if args.job == "interim":  # warm caches (the user's own): one tick's time on each path
        print("| solver | path | step µs (median of 300) |\n|---|---|---|", flush=True)
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        return subprocess.run([sys.executable, "-c", INTERIM_COST], env=env, cwd=ROOT).returncode
    with tempfile.TemporaryDirectory() as out:
        rows = measure(args.job, Path(out), args.backend)
    print("| job | cache | wall s | CPU s | " + " | ".join(MARKS) + " |")
    print("|---|---|---|---|" + "---|" * len(MARKS))
    for label, state, wall, cpu, seen in rows:
        cells = ["–" if s is None else f"{s:.0f}" for s in seen]
        print(f"| {label} | {state} | {wall:.0f} | {cpu:.0f} | " + " | ".join(cells) + " |")
    return 0


#: the moments each job's output is scanned for (columns of the table)
MARKS = {
    "first answer s": ("weighted: first answered", "thesis_step"),
    "weighted compiled s": ("weighted: first compiled", None),
    "hierarchical answered s": ("hierarchical: first answered", None),
    "hierarchical compiled s": ("hierarchical: first compiled", None),
}


def measure(job: str, out: Path, backend: str | None = None) -> list[tuple]:
    """(label, cold/warm, wall s, CPU s, [s to each of MARKS]) of each run."""
    bench = [
        sys.executable, "-m", "wbc.cli", "bench", "--json", str(out / "bench.json"),
        "--plots", str(out / "plots"),
    ]  # fmt: skip
    first = f"FIRST_ONLY = True\nBACKEND = {backend!r}\n" + FIRST_TICKS
    jobs = {  # (label, command, index of its marks)
        "first": ("walk stack, first ticks", [sys.executable, "-c", first], 0),
        "solve": ("walk stack ticked, both solvers", [sys.executable, "-c", TICKS], 0),
        "bench": ("`wbc bench --json … --plots …`", bench, 1),  # a result line
    }
    rows = []
    for label, cmd, k in [jobs[job]] if job in jobs else [jobs["solve"], jobs["bench"]]:
        marks = [m[k] for m in MARKS.values()]
        with tempfile.TemporaryDirectory() as tmp:  # each job starts from empty caches
            env = {
                **os.environ,
                "NUMBA_CACHE_DIR": f"{tmp}/numba",
                "WBC_CACHE_DIR": f"{tmp}/wbc",
                "PYTHONPATH": str(ROOT),
                "PYTHONUNBUFFERED": "1",
            }
            env.pop("WBC_WAIT_FOR_COMPILE", None)
            for state in ("cold", "warm"):
                print(f"{label}, {state}...", file=sys.stderr, flush=True)
                wall, cpu, seen = timed(cmd, env, [m or "\0" for m in marks])
                rows.append((label, state, wall, cpu, seen))
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
