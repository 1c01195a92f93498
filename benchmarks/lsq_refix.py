"""Subproblems of the hierarchy's level solves on captured walks, by ``lsq.REFIX_GUARD`` (0, 1, 2).

Each tick of a :mod:`cascade_replay` capture is solved again through ``cascade_solve`` with the
kernels as Python (``NUMBA_DISABLE_JIT=1``, set here before numba is imported), once per
guard value in separate processes; printed per guard: the level calls, their subproblems
(fresh and updated) in sum, the per-tick p99 and max, the calls where PDAS fixed a variable
again on the side the step before released it from (``re-fixed``), the ``_hard_multipliers``
calls per tick, and the largest difference of the answers Δq from the guard 0 run (and the
ticks answered bit for bit the same)::

    python benchmarks/cascade_replay.py --capture walk10.pkl --trajectory walk10 --stack walk_strict
    NUMBA_DISABLE_JIT=1 python benchmarks/lsq_refix.py walk10.pkl [--guards 0 1 2]

Guards other than 0 need a checkout with ``lsq.REFIX_GUARD`` (commit 7247334 of the twentieth
session's branch i34h: measured, not merged — it cost the default path 2-3 % replayed,
benchmarks/self_collision.md); on main only ``--guards 0`` (the counts).
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def trace(path: str, guard: int) -> dict:
    """The capture's ticks solved with REFIX_GUARD = ``guard`` (kernels as Python)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import cascade_replay as replay

    from wbc.compiled import lsq, lsq_update
    from wbc.compiled import ticks as T

    if not hasattr(lsq, "REFIX_GUARD") and guard != 0:
        raise SystemExit(f"--guards {guard}: this checkout has no lsq.REFIX_GUARD (only 0)")
    lsq.REFIX_GUARD = guard
    with open(path, "rb") as f:
        ticks = pickle.load(f)["ticks"]
    seq: list = []
    calls: list[dict] = []
    hard = [0]
    now = [0]
    sub, upd, level, mult = lsq._subproblem, lsq._updated, T.solve_level_in, T._hard_multipliers

    def sub_counted(*a):
        seq.append(a[13][lsq._I_FIXED, : len(a[5])].copy())
        return sub(*a)

    def upd_counted(*a):
        code = upd(*a)
        if int(code) == lsq_update._UPDATED:
            seq.append(a[11][lsq._I_FIXED, : len(a[4])].copy())
        return code

    def level_counted(*a):
        seq.clear()
        status, count = level(*a)
        refix = any(
            np.any((seq[k - 1] != 0) & (seq[k] == 0) & (seq[k + 1] == seq[k - 1]))
            for k in range(1, len(seq) - 1)
        )
        calls.append(dict(tick=now[0], count=int(count), refix=refix))
        return status, count

    def mult_counted(*a):
        hard[0] += 1
        return mult(*a)

    lsq._subproblem, lsq._updated = sub_counted, upd_counted
    T.solve_level_in, T._hard_multipliers = level_counted, mult_counted
    space = replay.work_space(ticks)
    dq = []
    for i, tick in enumerate(ticks):
        now[0] = i
        args = replay.call_args(tick, space)
        T.cascade_solve(*args)
        dq.append(args[replay.ARGS.index("dq")].copy())
    per_tick = np.zeros(len(ticks), np.int64)
    for c in calls:
        per_tick[c["tick"]] += c["count"]
    return dict(
        calls=len(calls), subproblems=int(per_tick.sum()), p99=float(np.percentile(per_tick, 99)),
        max=int(per_tick.max()), refix=sum(c["refix"] for c in calls),
        hard=hard[0] / len(ticks), dq=np.array(dq),
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("path", help="a benchmarks/cascade_replay.py capture")
    parser.add_argument("--guards", type=int, nargs="+", default=[0])
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--guard", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        with open(args.child, "wb") as f:
            pickle.dump(trace(args.path, args.guard), f)
        return
    from wbc.compiled import lsq

    if not hasattr(lsq, "REFIX_GUARD") and any(g != 0 for g in args.guards):
        raise SystemExit("--guards: this checkout has no lsq.REFIX_GUARD (only 0 is allowed)")
    env = dict(os.environ, NUMBA_DISABLE_JIT="1", WBC_REPLAY_CHILD="1")
    runs = {}
    for g in args.guards:
        with tempfile.NamedTemporaryFile(suffix=".pkl", delete=False) as f:
            out = f.name
        cmd = [sys.executable, __file__, args.path, "--child", out, "--guard", str(g)]
        subprocess.run(cmd, env=env, check=True)
        with open(out, "rb") as f:
            runs[g] = pickle.load(f)
        Path(out).unlink()
    base = runs[args.guards[0]]["dq"]
    print(f"{args.path}: {len(base)} solves; kernels as Python")
    print("| guard | level calls | subproblems | per tick p99 / max | calls re-fixing | "
          "hard multipliers a tick | max abs dq diff | ticks bit for bit |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for g, r in runs.items():
        diff = float(np.abs(r["dq"] - base).max())
        same = int(np.all(r["dq"] == base, axis=1).sum())
        print(f"| {g} | {r['calls']} | {r['subproblems']} | {r['p99']:.0f} / {r['max']} | "
              f"{r['refix']} | {r['hard']:.3f} | {diff:.1e} | {same} |")  # fmt: skip


if __name__ == "__main__":
    main()
