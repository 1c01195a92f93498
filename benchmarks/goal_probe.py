"""The start-up goal probe against the plants it runs on (issue 30).

For each randomised plant (:func:`wbc.bench.variation.models`, the sweep's plants), the
closed loop's start-up rest with the goal probe on (``Gains.probe_step``,
:mod:`wbc.balance.goal_probe`) and the walk's first ``--walk-s`` s: the probe's fitted goal
latency and response time beside the plant's drawn latency, stiffness and damping (what the
probe must find without reading them), the stiffness identified at rest from the sag, and
their correlations.

    nice -n 10 python benchmarks/goal_probe.py --seed 0 --plants 18 37 10 48 --step 0.05
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from plant_sweep import plant_run

from wbc.bench.closed_loop import play_closed_loop


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plants", type=int, nargs="+", default=list(range(10)))
    ap.add_argument("--walk", default="walk10_wb")
    ap.add_argument("--step", type=float, default=0.05, help="rad (Gains.probe_step)")
    ap.add_argument("--walk-s", type=float, default=0.1, help="s of the walk after the rest")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    rows = []
    print(
        "| plant | latency ms | stiffness × | damping N·m·s/rad | identified × | probe L ms "
        "| probe T ms | reached | fit rms |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for p in a.plants:
        run = plant_run(a.walk, a.seed, p, {"probe_step": a.step})
        rest = 1.0  # (the closed loop's start-up rest, CALIBRATE_S, first)
        _, loop = play_closed_loop(run.spec, run.robot, run.plant, duration=rest + a.walk_s)
        fit = loop.goal_probe
        s = (
            run.plant.summary
            if run.plant is not None
            else dict(latency_ms=0.0, stiffness=1.0, damping=np.nan)
        )
        k = loop.stabilizer.stiffness_scale
        row = dict(
            plant=p,
            latency_ms=s["latency_ms"],
            stiffness=s["stiffness"],
            damping=float(np.mean(s["damping"])),
            identified=k,
            L_ms=None if fit is None else fit.latency * 1e3,
            T_ms=None if fit is None else fit.response * 1e3,
            gain=None if fit is None else fit.gain,
            rms=None if fit is None else fit.rms,
        )
        rows.append(row)
        f = lambda v, d=1: "-" if v is None else f"{v:.{d}f}"  # noqa: E731
        print(
            f"| {p} | {row['latency_ms']:.1f} | {row['stiffness']:.2f} | {row['damping']:.3f} "
            f"| {f(k, 2)} | {f(row['L_ms'])} | {f(row['T_ms'])} | {f(row['gain'], 2)} "
            f"| {f(row['rms'], 3)} |",
            flush=True,
        )
    ok = [r for r in rows if r["L_ms"] is not None]
    if len(ok) >= 3:
        lat = np.array([r["latency_ms"] for r in ok])
        L = np.array([r["L_ms"] for r in ok])
        T = np.array([r["T_ms"] for r in ok])
        ratio = np.array([r["damping"] / r["stiffness"] for r in ok])
        print(
            f"corr(L, latency) {np.corrcoef(L, lat)[0, 1]:.3f}; L − latency: median "
            f"{np.median(L - lat):+.1f} ms, spread (p90 − p10) "
            f"{np.percentile(L - lat, 90) - np.percentile(L - lat, 10):.1f} ms; "
            f"corr(T, damping / stiffness) {np.corrcoef(T, ratio)[0, 1]:.3f}"
        )
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
