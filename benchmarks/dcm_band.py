"""The DCM error a robot's unpushed walks show: what its step adjuster's dead bands must leave
alone (``robot.toml`` ``[balance.stepping] band_x / band_y``; :mod:`wbc.balance.stepping`).

The push benchmark's ``step`` loop (wqp-daqp, the feed-forward at the robot's best, the
closed loop's gains sized to its servos; on a bus that reads no positions, step adjustment on
the commanded joints, ``closed_loop(step_on_commands=True)``) with dead bands of 1 m, so it
never re-plans; per tick of single support, the estimated DCM against the reference's in the
stance sole's heading frame: max / 95th percentile / median of |error|, mm, along × sideways,
per walk, beside the run's fall and torso deviation (as benchmarks/op3.md section 1 measured
the OP3's).

    python benchmarks/dcm_band.py --robot kokone --trajectories walk10 walk10_wb turn turn_wb \
        lateral lateral_wb
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from pushes import loop_spec

from wbc import load_robot
from wbc.balance import best_compensate
from wbc.balance import stepping as step_mod
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import simulate
from wbc.bench.physics import physics_entry, plan

#: dead bands no unpushed walk reaches: the adjuster runs (its error read) but never re-plans
WIDE = {"band_x": 1.0, "band_y": 1.0}


def errors(robot, walk: str, solver: str = "wqp-daqp") -> tuple[dict, np.ndarray]:
    """(the run's summary, the single-support DCM errors along × sideways, m, one row a
    tick) of ``walk``'s unpushed step loop with :data:`WIDE` bands."""
    entry = physics_entry(solver, robot)
    ref = traj.build(walk, robot)
    rec = plan(solver, walk, robot)
    spec, comp = loop_spec("step", entry, ref, WIDE, {}, {}, best_compensate(robot), None,
                           robot, on_commands=True)  # fmt: skip
    rows: list[np.ndarray] = []
    original = step_mod.StepAdjuster.update

    def observed(self, ref, i, dcm):
        if self.phases[self.phase_of[i]].kind == "single":
            e = np.asarray(dcm[:2], float) - self._dcm_ref(ref, i)
            c, s = self._heading(ref, i)
            rows.append(np.array([c * e[0] + s * e[1], -s * e[0] + c * e[1]]))
        return original(self, ref, i, dcm)

    step_mod.StepAdjuster.update = observed
    try:
        r = simulate(rec, robot, compensate=comp, closed=spec)
    finally:
        step_mod.StepAdjuster.update = original
    summary = {"walk": walk, "fell": r["fell"], "fall_time_s": r.get("fall_time_s"),
               "dev_deg": round(r["orientation_dev_max_deg"], 2),
               "dist": round(r["distance_ratio"], 3), "replans": r.get("replans")}  # fmt: skip
    return summary, np.array(rows).reshape(-1, 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="bioloid")
    ap.add_argument("--trajectories", nargs="+", default=["walk10_wb"])
    ap.add_argument("--solver", default="wqp-daqp")
    args = ap.parse_args()
    from wbc.drive.sim import wait_for_compiled_ticks

    wait_for_compiled_ticks()
    robot = load_robot(args.robot)
    for walk in args.trajectories:
        summary, e = errors(robot, walk, args.solver)
        a = np.abs(e) * 1e3
        for name, f in (("max", np.max), ("p95", lambda x, axis: np.percentile(x, 95, axis)),
                        ("median", np.median)):  # fmt: skip
            summary[f"{name}_mm"] = np.round(f(a, axis=0), 1).tolist() if len(a) else None
        print(json.dumps(summary), flush=True)


if __name__ == "__main__":
    main()
