"""The controller's side of a pushed landing, tick by tick (issue 30, eighteenth session): per
solve of the closed loop (``StackController.track``) the reference tick, its phase, whether the
contacts move (``contacts_move``), each sole's target and where the solve puts it, the CoM
target and the solve's, the tasks' errors — or the solve's failure (``InfeasibleError``: the
controller then holds its last configuration). The push as ``push_trace.py`` (walk10_wb,
wqp-daqp, feed-forward ×0.5, the fall detector off).

    nice -n 5 python benchmarks/landing_probe.py '{}' --impulse 0.70 --offset 0.03 --ticks 178 200
    nice -n 5 python benchmarks/landing_probe.py '{"accept": 1.0, "accept_skip": 2, \\
        "accept_share": 0.99, "accept_steps": 0, "accept_settle": 0.003}'
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import _args
import numpy as np
import push_trace

from wbc import load_robot
from wbc.balance.stepping import SteppingParams
from wbc.walking import loop as loop_mod


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stepping", type=_args.json_setting(SteppingParams),
                    help="JSON SteppingParams keywords")  # fmt: skip
    _args.push(ap, impulse=0.70, direction="backward", offset=0.03)
    ap.add_argument("--ticks", type=int, nargs=2, default=(178, 200), help="reference ticks")
    a = ap.parse_args()
    robot = load_robot("bioloid")
    rows: list[dict[str, Any]] = []
    original = loop_mod.StackController.track

    def mm(v: Any) -> list[float]:
        return (1e3 * np.asarray(v, dtype=float)).round(1).tolist()

    def track(self, q, targets, dt, phase_changed):  # (observed: the solve or its failure)
        row: dict[str, Any] = {"i": int(targets.i), "phase": targets.phase,
                               "moves": bool(targets.contacts_move)}  # fmt: skip
        rows.append(row)
        try:
            out = original(self, q, targets, dt, phase_changed)
        except Exception as exc:
            row["failed"] = repr(exc)[:160]
            raise
        for f in ("l_sole", "r_sole"):
            row[f] = {"target": mm(targets.sole(f).translation),
                      "solved": mm(robot.frame_placement(out, f).translation)}  # fmt: skip
        row["com"] = {"target": mm(targets.com), "solved": mm(robot.com(out))}
        errors = {k: float(np.linalg.norm(v)) for k, v in self.task_errors().items()}
        row["errors"] = {k: round(v, 4) for k, v in errors.items() if v > 1e-3}
        return out

    loop_mod.StackController.track = track  # type: ignore[method-assign]
    try:
        summary, _ = push_trace.trace(a.impulse, a.direction, a.stepping, {},
                                      "walk10_wb", a.offset, False)  # fmt: skip
    finally:
        loop_mod.StackController.track = original  # type: ignore[method-assign]
    print(json.dumps({"fall_time_s": summary["fall_time_s"], "accepted": summary["accepted"]}))
    start = next(
        (
            k
            for k, r in enumerate(rows)
            if r["i"] < a.ticks[0] and k > 0 and rows[k - 1]["i"] > r["i"]
        ),
        0,
    )  # (the closed loop's, after the plan's)
    for r in rows[start:]:
        if a.ticks[0] <= r["i"] <= a.ticks[1]:
            print(json.dumps(r))


if __name__ == "__main__":
    main()
