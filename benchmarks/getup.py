"""Getting-up benchmark: the simulated robot dropped on its front or back, left to settle with
its torque off (the state a safe fall leaves), then :func:`wbc.balance.getup_play.get_up`,
closed loop, on ``--models`` randomised models (:func:`wbc.bench.variation.models`, seeded;
model 0 is the first randomised one, ``--nominal`` adds the nominal model) and a random
heading on the floor. Success: the torso upright within 10°, both soles flat, the CoM above
the feet, still so 2 s later (:func:`wbc.drive.sim.judge`). Prints the success rate
and the duration (from the first goal to the end of the rise) per side.

    nice -n 5 python benchmarks/getup.py --models 20 --sides prone supine --nominal
    nice -n 5 python benchmarks/getup.py --models 20 --sides prone --nominal --open-loop
    nice -n 5 python benchmarks/getup.py --models 0 --sides supine --nominal --trace
    nice -n 5 python benchmarks/getup.py --models 20 --sides prone supine --nominal --fall

``--fall``: a real fall instead of the drop: the walker standing on its velocity commands, a
shove of 14-24 N for 0.2 s (forward for the front, backward for the back) fells it, the fall
detection stops the walk, and ``wbc drive``'s ``after_fall`` gets it up (the side it landed
on is printed: a shove backward may land it on its front).

``--no-support-hull``: the planner without its hull rows (``GetupParams.support_margin``
None: the plan before them, for a side-by-side run); ``--only K ...``: only those randomised
models (the same shoves and headings as in the full run).

``--trace`` watches each run (with ``--fall`` too: the walk, the fall and the get-up): every
0.1 s the torso's elevation, the CoM and the hands ahead of the rear edge of the soles (along
the left sole's heading: meaningful once the feet are flat), the soles' tilt, the base's
height, the largest servo torque over its cap (the AX-12A's stall torque 1.5 N·m at the default
torque limit) and the bodies touching the floor with their normal force (N); then per phase the
share of ticks with a servo at its cap, and which.

Figures and the exact commands they came from: benchmarks/getup.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")

from wbc import load_robot
from wbc.balance.getup import GetupParams
from wbc.bench.variation import models
from wbc.drive.getup_sim import getup_sim

#: the shove's range (N, for 0.2 s at the base) of ``--fall``: the Bioloid standing falls over
#: from about 13 N
FALL_FORCE_N = (14.0, 24.0)


def fall_and_get_up(
    robot, side: str, variation, force: float, watcher=None, params: GetupParams | None = None
) -> dict:
    """``--fall``: the walker standing on its velocity commands (``wbc drive``'s path, the
    hqp-daqp controller, closed loop), shoved at 1 s for 0.2 s (forward to fall on its front,
    backward on its back) until the fall detection stops it; then what ``wbc drive`` does
    (:func:`wbc.drive.sim.after_fall`), judged as the drop (:func:`wbc.drive.sim.judge`).
    ``watcher``: ``--trace`` (:class:`Watcher`) watches the walk, the fall and the get-up;
    ``params``: the get-up planner's."""
    from wbc.bench.solvers import registry
    from wbc.drive.commands import Command
    from wbc.drive.sim import drive_sim

    controller = registry("physics")["hqp-daqp"].make(robot)
    push = force if side == "prone" else -force
    rec = drive_sim(robot, controller, [Command(3.0, 0.0, 0.0, 0.0)], variation=variation,
                    walker_options={"compensate": 0.5, "calibrate_s": 0.3},
                    push=(1.0, (push, 0.0, 0.0), 0.2), get_up=True, getup_params=params,
                    view=watcher,
                    out=watcher.phase if watcher else (lambda _line: None))  # fmt: skip
    landed = rec.get("getup_side") or ("on a side" if rec["fell"] else "not")
    return {"side": side, "force_n": force, "landed": landed, "fell": rec["fell"],
            "success": bool(rec.get("got_up")), "reason": rec.get("getup_reason", ""),
            "phases": rec.get("getup_phases", []), "duration_s": None, "trunk_deg": {}}  # fmt: skip


class Watcher:
    """``--trace``: what the simulated robot does, every 0.1 s and per phase."""

    def __init__(self, robot) -> None:
        self.robot = robot
        self.name = "start"
        self.printed = -1  # the last 0.1 s printed
        self.stats: dict[str, list] = {}  # phase -> [ticks, ticks at the cap, {joint: n}]

    def phase(self, line: str) -> None:
        print(f"    {line}", flush=True)
        if line.startswith("get-up: ") and not line.startswith("get-up: lying"):
            self.name = line[len("get-up: ") :]

    def __call__(self, sim) -> None:
        tau = np.abs(sim.joint_torques())
        cap = getattr(getattr(sim.servos, "params", None), "torque_cap", None)
        cap = np.full_like(tau, 1.5) if cap is None else np.asarray(cap, dtype=float)
        at_cap = tau >= 0.98 * cap
        st = self.stats.setdefault(self.name, [0, 0, {}])
        st[0] += 1
        st[1] += bool(at_cap.any())
        for j in np.flatnonzero(at_cap):
            name = self.robot.joint_names[j]
            st[2][name] = st[2].get(name, 0) + 1
        tenth = math.floor(sim.time * 10 + 1e-6)
        if tenth == self.printed:  # every 0.1 s
            return
        self.printed = tenth
        R = sim.site_pose("torso").rotation
        elevation = math.degrees(math.asin(float(np.clip(R[2, 2], -1.0, 1.0))))
        soles = [sim.site_pose(s) for s in ("l_sole", "r_sole")]
        x = soles[0].rotation[:, 0]
        half = 0.5 * self.robot.foot_size[0]
        rear = min(float((M.translation - half * x) @ x) for M in soles)
        tilt = [math.degrees(math.acos(float(np.clip(M.rotation[2, 2], -1, 1)))) for M in soles]
        _pts, fz, body = sim.contacts()
        touching: dict[str, float] = {}
        for b, f in zip(body, fz, strict=True):
            n = sim.model.body(int(b)).name
            touching[n] = touching.get(n, 0.0) + float(f)
        hands = [f"{1e3 * (sim.site_pose(h).translation @ x - rear):4.0f}"
                 for h in ("l_hand", "r_hand") if h in sim.site]  # fmt: skip
        k = int(np.argmax(tau / cap))
        print(f"    t {sim.time:5.1f} {self.name:11s} trunk {elevation:4.0f} deg, CoM "
              f"{1e3 * (sim.com() @ x - rear):5.0f} mm ahead of the heels (hands "
              f"{'/'.join(hands)}), soles "
              f"{tilt[0]:3.0f}/{tilt[1]:3.0f} deg, base z {1e3 * sim.q()[2]:3.0f} mm, "
              f"torque {tau[k] / cap[k]:4.0%} of cap ({self.robot.joint_names[k]}); "
              + " ".join(f"{n} {f:.1f}" for n, f in sorted(touching.items(),
                                                          key=lambda kv: -kv[1])),
              flush=True)  # fmt: skip

    def summary(self) -> None:
        for name, (n, capped, joints) in self.stats.items():
            worst = ", ".join(f"{j} {c / n:.0%}" for j, c in
                              sorted(joints.items(), key=lambda kv: -kv[1])[:4])  # fmt: skip
            print(
                f"    {name:11s}: a servo at its torque cap {capped / n:4.0%} of {n} ticks"
                + (f" ({worst})" if worst else "")
            )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="bioloid")
    ap.add_argument("--models", type=int, default=20)
    ap.add_argument("--seed", type=int, default=33)
    ap.add_argument("--sides", nargs="+", default=["prone", "supine"])
    ap.add_argument("--nominal", action="store_true", help="also the nominal model")
    ap.add_argument(
        "--open-loop", action="store_true", help="each phase planned from the plan's own end"
    )
    ap.add_argument(
        "--compensate", type=float, default=1.0, help="compliance feed-forward gain (0: off)"
    )
    ap.add_argument(
        "--no-stiffen", action="store_true", help="every phase at the configured servo stiffness"
    )
    ap.add_argument(
        "--no-support-hull",
        action="store_true",
        help="no rows keeping the CoM inside the contacts' hull (GetupParams.support_margin)",
    )
    ap.add_argument(
        "--sliding-margin",
        type=float,
        default=GetupParams().sliding_margin,
        help="m: the hull margin of the phases with sliding contacts (GetupParams)",
    )
    ap.add_argument("--trace", action="store_true", help="watch each run (module docstring)")
    ap.add_argument(
        "--fall",
        action="store_true",
        help="a real fall instead of the drop: the walker standing, shoved (module docstring)",
    )
    ap.add_argument(
        "--only", type=int, nargs="+", help="run only these randomised models (their index)"
    )
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    robot = load_robot(args.robot)
    params = GetupParams(sliding_margin=args.sliding_margin)
    if args.no_support_hull:
        params = replace(params, support_margin=None)
    variations = ([None] if args.nominal else []) + models(robot, args.models, args.seed)
    rng = np.random.default_rng(args.seed)
    yaws = rng.uniform(-math.pi, math.pi, len(variations))
    force = rng.uniform(FALL_FORCE_N[0], FALL_FORCE_N[1], len(variations))
    records = []
    start = time.perf_counter()
    for side in args.sides:
        ok, durations = 0, []
        for k, (v, yaw) in enumerate(zip(variations, yaws, strict=True)):
            if args.only is not None and (v is None or k - int(args.nominal) not in args.only):
                continue
            watcher = Watcher(robot) if args.trace else None
            if args.fall:
                rec = fall_and_get_up(robot, side, v, float(force[k]), watcher, params)
                if watcher:
                    watcher.summary()
                rec.update(model="nominal" if v is None else k - int(args.nominal))
                records.append(rec)
                ok += rec["success"]
                print(f"{side} model {rec['model']}: shoved {rec['force_n']:.1f} N, fell "
                      f"{rec['landed']}: {'UP' if rec['success'] else 'FAILED'} "
                      f"({rec['reason']})", flush=True)  # fmt: skip
                continue
            rec = getup_sim(
                robot,
                side,
                v,
                yaw=float(yaw),
                params=params,
                replan=not args.open_loop,
                compensate=args.compensate,
                stiffen=not args.no_stiffen,
                watch=watcher,
                out=watcher.phase if watcher else (lambda _line: None),
            )
            if watcher:
                watcher.summary()
            rec.update(model="nominal" if v is None else k - int(args.nominal), yaw=float(yaw))
            records.append(rec)
            ok += rec["success"]
            if rec["success"]:
                durations.append(rec["duration_s"])
            print(f"{side} model {rec['model']}: {'UP' if rec['success'] else 'FAILED'} "
                  f"({rec['reason']}), {rec['duration_s'] or 0:.1f} s", flush=True)  # fmt: skip
        d = f", {np.median(durations):.1f} s median" if durations else ""
        n_runs = sum(r["side"] == side for r in records)
        print(f"{side}: {ok}/{n_runs} up{d}", flush=True)
        if args.fall:
            landed = [r["landed"] for r in records if r["side"] == side]
            print("  landed: " + ", ".join(f"{n} {landed.count(n)}" for n in sorted(set(landed))))
        # the torso's elevation at the start of each phase (deg above the horizontal; 90 up)
        side_recs = [r for r in records if r["side"] == side]
        for name in side_recs[0]["phases"] if side_recs else []:
            deg = [r["trunk_deg"][name] for r in side_recs if name in r.get("trunk_deg", {})]
            if not deg:
                continue
            print(f"  trunk at '{name}': median {np.median(deg):.0f} deg, "
                  f"{min(deg):.0f}..{max(deg):.0f} ({len(deg)} runs)")  # fmt: skip
    print(f"{len(records)} runs in {time.perf_counter() - start:.0f} s")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(records, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
