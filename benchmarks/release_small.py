"""The last level's weakly held bounds released at a tick's start (``HierarchicalQP.
release_small``, :mod:`wbc.compiled.lsq_release`), against main's start, on the same inputs.

Capture a walk with the option on (its marks are in each tick's warm sets), then count::

    python benchmarks/cascade_replay.py --capture OUT.pkl --trajectory walk10 \
        --stack walk_strict --release-small 0.03
    python benchmarks/release_small.py OUT.pkl [--ticks N]
    NUMBA_DISABLE_JIT=1 python benchmarks/release_small.py OUT.pkl --calls 305,310

Each tick's ``solve_level_in`` subproblems (the kernels as Python, in a child process with
``NUMBA_DISABLE_JIT=1``: :func:`cascade_replay.counts`) with the capture's ratio
(``params[5]``) and with 0 — main's path: the marks read as the bounds held —, the sum, p99
and largest per tick, the ticks worse and better, an estimate of the solves' µs (a fresh
subproblem 7 µs, an update or a factored one 2.7: benchmarks/self_collision.md, twenty-first
session), and the largest |Δq| between the two answers (the compiled cascade, this process).
Timing: ``python benchmarks/cascade_replay.py OUT.pkl --against MAIN`` (main ignores the marks).
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

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import cascade_replay as R  # noqa: E402

#: µs per subproblem in the estimate, by kind (cascade_replay.counts' names)
COST = {"fresh": 7.0, "fresh row": 7.0, "factored": 2.7, "upd": 2.7}


def variants(ticks: list[dict]) -> dict[str, list[dict]]:
    """The ticks with the capture's ratio, and with 0 (main's path)."""
    off = [dict(t, params=np.where(np.arange(t["params"].size) == 5, 0.0, t["params"]))
           for t in ticks]  # fmt: skip
    return {"on": ticks, "off": off}


def _counted(path: str, out: str, upto: int) -> None:
    """(child, kernels as Python) each variant's per-tick subproblems and estimated µs."""
    with open(path, "rb") as f:
        ticks = pickle.load(f)["ticks"][:upto]
    result = {}
    for name, ts in variants(ticks).items():
        calls = R.counts(ts, list(range(len(ts))))
        n = np.array([sum(c["count"] for c in calls[i]) for i in range(len(ts))])
        est = np.array(
            [sum(COST.get(k, 0.0) * v for c in calls[i] for k, v in c["kinds"].items())
             for i in range(len(ts))]
        )  # fmt: skip
        result[name] = dict(n=n, est=est)
    with open(out, "wb") as f:
        pickle.dump(result, f)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("path", help="a capture made with --release-small R")
    parser.add_argument("--ticks", type=int, default=0, help="the first N ticks only")
    parser.add_argument(
        "--calls", metavar="I,J,...",
        help="each solve_level_in call of these solves, on and off (kernels as Python)",
    )  # fmt: skip
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    with open(args.path, "rb") as f:
        cap = pickle.load(f)
    if args.calls:
        which = [int(i) for i in args.calls.split(",")]
        for name, ts in variants(cap["ticks"]).items():
            calls = R.counts(ts, which)  # (needs NUMBA_DISABLE_JIT=1)
            for i in which:
                print(i, name, [(c["level"], c["m"], c["cont"], c["count"], c["kinds"])
                                for c in calls[i]])  # fmt: skip
            print(name, "subproblems", sum(c["count"] for i in which for c in calls[i]))
        return
    upto = args.ticks or len(cap["ticks"])
    if args.child:
        _counted(args.path, args.child, upto)
        return
    ticks = cap["ticks"][:upto]
    ratio = float(ticks[0]["params"][5]) if ticks[0]["params"].size > 5 else 0.0
    marked = sum(int((np.abs(t["states"]) == 2).sum()) for t in ticks)
    answers = {k: R.replay(ts, 1)["dq"] for k, ts in variants(ticks).items()}
    with tempfile.NamedTemporaryFile(suffix=".pkl", delete=False) as f:
        out = f.name
    try:
        env = dict(os.environ, NUMBA_DISABLE_JIT="1")
        cmd = [sys.executable, __file__, args.path, "--child", out, "--ticks", str(upto)]
        subprocess.run(cmd, env=env, check=True)
        with open(out, "rb") as f:
            res = pickle.load(f)
    finally:
        os.unlink(out)
    on, off = res["on"], res["off"]
    print(
        f"{args.path}: {cap['robot']} {cap['trajectory']} {cap['stack']}, {len(ticks)} ticks, "
        f"release_small {ratio:g}, {marked} bounds marked in the warm sets; "
        f"max |Δq on − off| {np.abs(answers['on'] - answers['off']).max():.2e}"
    )
    print("| start | subproblems sum / p99 / max a tick | est. µs sum / p99 / max |")
    print("|---|---|---|")
    for name, r in (("main's (off)", off), (f"weak released ({ratio:g})", on)):
        n, e = r["n"], r["est"]
        print(
            f"| {name} | {n.sum()} / {np.percentile(n, 99):.1f} / {n.max()} | "
            f"{e.sum():.0f} / {np.percentile(e, 99):.1f} / {e.max():.1f} |"
        )
    worse, better = int((on["n"] > off["n"]).sum()), int((on["n"] < off["n"]).sum())
    print(f"ticks with more subproblems {worse}, fewer {better}")
    d = on["est"] - off["est"]
    slow = np.argsort(off["est"])[::-1][: max(1, len(ticks) // 100)]
    print(
        f"main's slowest 1 % ({slow.size} ticks): est. µs {off['est'][slow].sum():.0f} -> "
        f"{on['est'][slow].sum():.0f}; largest increase {d.max():.1f} µs (tick {int(d.argmax())})"
    )


if __name__ == "__main__":
    main()
