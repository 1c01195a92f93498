"""Pushes at mid single support: open loop vs closed loop vs closed loop + stepping.

The largest 10 ms torso impulse survived (N·s, bisection over 0–3 N·s as ``wbc bench
--physics --push``: :func:`wbc.bench.physics.largest_push`), on ``walk10``, per solver, for
the plan played open loop (``open``), the closed loop (the feed-forward at the robot's best,
the closed loop's default gains sized to its servos — the Bioloid's and the OP3's ``Gains()``,
Kokone's torso terms ×0.025, :func:`wbc.balance.margin.default_sized_gains` —: with the hip
strategy, :mod:`wbc.balance.stabilizer`; ``closed``), the closed loop with step
placement from the measured DCM (``step``, :mod:`wbc.balance.stepping`), and both without the
hip strategy (``nohip``, ``nohipstep``: ``k_hip`` 0, the closed loop before it), the
plan open loop with the feed-forward ×0.5 (``openff``: the default loop's comparison); plus
the nominal run's figures, the LIPM capturability bounds
(:func:`wbc.balance.capture.capture_bounds`) and the angular-momentum (hip strategy) bound
(:func:`wbc.balance.angular.hip_strategy_bound`); the bounds include step timing
(``*_timed_ns``) and a second timed step (:func:`second_step`).

    python benchmarks/pushes.py --solvers wqp-daqp hqp-daqp placo pink --json pushes.json
    python benchmarks/pushes.py --solvers wqp-daqp --loops nohip closed --directions lateral
    python benchmarks/pushes.py --solvers wqp-daqp --trajectory walk10_wb --loops openff step \
        --directions forward backward toward away          # four directions (issue 30)
    python benchmarks/pushes.py --solvers wqp-daqp --trajectory walk10_wb --loops step steps \
        --directions forward backward toward away   # planned recovery steps (issue 30)
    python benchmarks/pushes.py --solvers wqp-daqp --trajectory walk10_wb --loops step \
        --directions forward backward toward away --stepping '{"until_inside": 3}' \
        --gains '{"anchor_band": 0.01}'   # multi-step recovery, the landed-sole anchor
    python benchmarks/pushes.py --solvers wqp-daqp --trajectory walk10_wb --loops step \
        --directions forward backward toward away --offsets -0.04 -0.02 0 0.02 0.04 \
        --gains '{"contact_band": 0.004}'   # five push times, the mean; the contact state
    python benchmarks/pushes.py --solvers wqp-daqp --trajectory walk10_wb --loops step \
        --directions forward backward --offsets -0.03 0 0.03 --stepping \
        '{"trigger_jump": 0.018, "landing": 1, "landing_catch": 0.02, "lift": 0.015}'
        # the push caught in its own step: the trigger and the lift (issue 30)
    python benchmarks/pushes.py --robot kokone --solvers hqp-daqp --trajectory lateral_wb \
        --loops step --directions forward  # the closed loops' gains sized to its servos
    python benchmarks/pushes.py --robot kokone --solvers wqp-daqp --trajectory walk10_wb \
        --loops step --step-on-commands --stepping '{"band_x": 0.04, "band_y": 0.026}' \
        --directions forward backward toward away  # step adjustment on its commanded joints
    python benchmarks/pushes.py --solvers wqp-daqp --safety 0.83   # goals at one push
    python benchmarks/pushes.py --solvers wqp-daqp --grid 0.7 0.95 0.025  # survival per impulse
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

from wbc.balance import best_compensate
from wbc.balance.angular import hip_strategy_bound, point_push_bound
from wbc.balance.capture import capture_bounds
from wbc.balance.fall import FallParams
from wbc.balance.live import loop_rate
from wbc.balance.margin import default_sized_gains
from wbc.balance.retime import HoldParams
from wbc.balance.stabilizer import Gains
from wbc.balance.stepping import SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, simulate
from wbc.bench.physics import physics_entry, plan
from wbc.bench.pushes import largest_push
from wbc.bench.solvers import select
from wbc.exceptions import ModelError
from wbc.model import load_robot
from wbc.walking.legs import LegGeometry

LOOPS = ("open", "closed", "step", "nohip", "nohipstep", "before", "openff", "steps")
#: the planned recovery steps (issue 30, third pass; ``steps``): three steps placed per
#: re-plan, the next landing re-planned in double support during a catch, the dead band
#: centred on the error's running mean (1 s); ``--stepping`` JSON overrides any keyword
RECOVERY_STEPS = {"steps_ahead": 3, "double_support": True, "baseline_tau": 1.0}


def loop_spec(
    loop: str,
    entry,
    ref,
    stepping: dict | None = None,
    gains: dict | str | None = None,
    hold: dict | None = None,
    compensate: float = 0.5,
    fall: dict | str | None = None,
    robot=None,
    on_commands: bool = False,
) -> tuple[ClosedLoopSpec | None, float]:
    """(closed-loop spec or None for the open loop, compliance gain) of one loop name
    (``stepping``: SteppingParams keywords of the ``step`` loop, and of the ``steps`` loop
    over RECOVERY_STEPS;
    ``gains``: Gains keywords of the ``closed``, ``step`` and ``steps`` loops over the closed
    loop's default on ``robot`` (:func:`~wbc.balance.margin.default_sized_gains`: sized to
    its servos — Kokone's torso gains ×0.025; the Bioloid's and the OP3's ``Gains()`` as
    they are; without ``robot``, ``Gains()``), or "sized" (no gains given: the closed loop
    sizes its default itself); ``hold``:
    HoldParams keywords of those loops' lift-off hold; ``compensate``: the feed-forward gain
    of the loops with it, the robot's measured best; ``fall``: FallParams keywords of their
    fall detector, ``"off"`` none; ``on_commands``: the stepping loops step on a bus that reads
    no positions too, ``closed_loop(step_on_commands=True)``)."""
    if loop == "open":
        return None, 0.0
    if loop == "openff":  # the plan played open loop with the feed-forward (x0.5 here)
        return None, compensate
    base = Gains()  # the closed loop's default (sized to the robot's servos)
    if robot is not None:
        base = default_sized_gains(robot, compensate, 1.0 / loop_rate(ref))[0]
    g: Gains | None = None  # ("sized": closed_loop sizes its default itself)
    if loop in ("nohip", "nohipstep"):
        g = replace(base, k_hip=0.0)
    elif not isinstance(gains, str):
        g = replace(base, **(gains or {}))
    step = SteppingParams(**(stepping or {})) if loop in ("step", "nohipstep") else None
    if loop == "steps":
        step = SteppingParams(**{**RECOVERY_STEPS, **(stepping or {})})
    if loop == "before":  # the closed loop before the narrower sway and the lift-off hold
        spec = ClosedLoopSpec(entry.make, ref, replace(base, transfer=0.0), True, True, None,
                              None)  # fmt: skip
        return spec, compensate
    spec = ClosedLoopSpec(entry.make, ref, g, True, True, step,
                          HoldParams(**(hold or {})))  # fmt: skip
    if on_commands and step is not None:
        spec = replace(spec, step_on_commands=True)
    if fall == "off":  # no fall detector: a run ends only by falling (45°)
        spec = replace(spec, fall=None)
    elif fall:
        spec = replace(spec, fall=FallParams(**fall))
    return spec, compensate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solvers", nargs="+", default=["wqp-daqp", "hqp-daqp", "placo", "pink"])
    ap.add_argument("--loops", nargs="+", default=list(LOOPS[:3]), choices=LOOPS)
    ap.add_argument("--directions", nargs="+", default=["lateral", "forward"])
    ap.add_argument("--trajectory", default="walk10")
    ap.add_argument(
        "--robot",
        default="bioloid",
        help="robot name or folder (its stack.toml and feed-forward gain: the loops with the "
        "feed-forward run at its measured best, the Bioloid's x0.5)",
    )
    ap.add_argument("--json", default=None)
    ap.add_argument(
        "--stepping", default="{}", help="JSON of SteppingParams keywords (step, steps)"
    )
    ap.add_argument(
        "--gains",
        default="{}",
        help="JSON of Gains keywords (closed, step, steps) over the closed loop's default, "
        "sized to the robot's servos (Kokone's x0.025), or \"sized\": none given",
    )
    ap.add_argument(
        "--step-on-commands",
        action="store_true",
        help="the stepping loops step on a bus that reads no positions too (Kokone's SSC-32: "
        "the DCM from the IMU and the commanded joints; closed_loop's step_on_commands)",
    )
    ap.add_argument(
        "--hold", default="{}", help="JSON of HoldParams keywords (the lift-off hold's)"
    )
    ap.add_argument(
        "--fall",
        default="{}",
        help='JSON of FallParams keywords (the closed loops\' fall detector), or "off"',
    )
    ap.add_argument(
        "--offsets",
        type=float,
        nargs="+",
        default=[0.0],
        metavar="S",
        help="push times, s after mid single support: one bisection each, their mean "
        "reported (push_DIR_ns) beside each (push_DIR_each)",
    )
    ap.add_argument(
        "--safety",
        type=float,
        default=None,
        metavar="NS",
        help="instead: one lateral push of NS N·s per closed loop; the goals' excursions "
        "beyond the joint limits, clamped and rate-limited ticks",
    )
    ap.add_argument(
        "--safety-direction",
        default="lateral",
        help="--safety's push direction (lateral, forward, backward, toward, away)",
    )
    ap.add_argument(
        "--screen",
        nargs="+",
        metavar="DIR:NS:S",
        help="instead: one push each (direction, impulse N·s, s after mid single support) "
        "per loop: up, or the fall's time",
    )
    ap.add_argument(
        "--grid",
        type=float,
        nargs=3,
        metavar=("FROM", "TO", "STEP"),
        help="instead: survive or fall at every lateral impulse of the grid (N·s), per loop",
    )
    args = ap.parse_args()
    from wbc.drive.sim import wait_for_compiled_ticks

    wait_for_compiled_ticks()  # (every run on the compiled tick: a bisection is repeatable)
    if args.grid is not None:
        grid(args)
        return
    if args.safety is not None:
        safety(args)
        return
    if args.screen:
        screen(args)
        return
    robot = load_robot(args.robot)
    ff = best_compensate(robot)
    ref = traj.build(args.trajectory, robot)
    legs = LegGeometry.from_robot(robot, robot.configuration("stand"))
    bounds = capture_bounds(ref, robot.total_mass, legs)
    bounds["second_step"] = second_step(bounds, ref)
    print(json.dumps(bounds, indent=1))
    out = {"bounds": bounds, "runs": []}
    for solver in args.solvers:
        entry = physics_entry(solver, robot)  # (the robot folder's stack.toml, if any)
        rec = plan(solver, args.trajectory, robot)
        if "hip_bound" not in out:  # at the push, on the first solver's plan
            try:
                out["hip_bound"] = hip_bound(rec, robot, ref, bounds)
            except ModelError as e:  # (a hip whose joints are not plain RX/RY/RZ: the OP3)
                out["hip_bound"] = {"skipped": str(e)}
            print(json.dumps(out["hip_bound"], indent=1))
        for loop in args.loops:
            spec, comp = loop_spec(
                loop, entry, ref, json.loads(args.stepping), gains_arg(args.gains),
                json.loads(args.hold), ff, "off" if args.fall == "off" else json.loads(args.fall),
                robot, args.step_on_commands,
            )  # fmt: skip
            started = time.perf_counter()
            nominal = simulate(rec, robot, compensate=comp, closed=spec)
            row = {"solver": solver, "loop": loop, "compensate": comp,
                   "fell": nominal["fell"], "dev_deg": nominal["orientation_dev_max_deg"],
                   "dist": nominal["distance_ratio"], "replans": nominal.get("replans"),
                   "goal_limit_excess_deg": nominal.get("goal_limit_excess_deg"),
                   "share": nominal.get("feedback_share"), "holds": nominal.get("holds"),
                   "hold_worst_mm": nominal.get("hold_worst_mm")}  # fmt: skip
            for d in args.directions:
                each = [largest_push(rec, robot, d, compensate=comp, closed=spec, offset=o)
                        for o in args.offsets]  # fmt: skip
                found = [b for b in each if b is not None]
                row[f"push_{d}_ns"] = sum(found) / len(found) if found else None
                if len(args.offsets) > 1:
                    row[f"push_{d}_each"] = each
            row["wall_s"] = time.perf_counter() - started
            print(json.dumps(row), flush=True)
            out["runs"].append(row)
            if args.json:
                with open(args.json, "w") as f:
                    json.dump(out, f, indent=1)


def gains_arg(text: str) -> dict | str:
    """``--gains``: its JSON, or ``"sized"`` as it is."""
    return text if text == "sized" else json.loads(text)


def second_step(bounds: dict, ref) -> dict:
    """What a second, timed step adds to the timed one-step bound forward and backward (LIPM,
    N·s; toward the swing foot the other foot cannot widen the support without crossing):
    after the first landing at ``t1`` (``*_timed_s``), the other sole swings for ``t2`` s
    from where it stands past the landed sole by ``a2 = v t2 − travel`` (forward the stride
    ``L`` plus the first step's added reach ``a1``; backward ``a1 − L``) (``v`` a whole
    min-jerk swing's mean speed at ``max_foot_speed`` peak: ``v_max / 1.875``; no double
    support: optimistic), which buys ``a2 e^{−ω (t1 + t2)}`` of DCM margin; the best ``t2``."""
    import numpy as np

    w, to_ns = bounds["omega"], bounds["mass"] * bounds["omega"]
    v1 = bounds["in_time_reach_mm"] / 1e3 / bounds["t_swing_left_s"]
    v2 = SteppingParams().max_foot_speed / 1.875
    stride = abs(float(ref.plan.steps[0].x - ref.plan.start_left.x))
    out = {}
    for d in ("forward", "backward"):
        t1 = bounds[f"{d}_timed_s"]
        a1 = min(v1 * t1, bounds[f"{d}_reach_mm"] / 1e3)
        # forward: the other sole starts the stride + a1 behind the landed one; backward it
        # starts stride − a1 behind it already (past its back edge when a1 < stride)
        travel = stride + a1 if d == "forward" else a1 - stride
        t2 = np.linspace(0.05, 0.6, 111)
        gain = np.maximum(v2 * t2 - travel, 0.0) * np.exp(-w * (t1 + t2))
        j = int(np.argmax(gain))
        out[f"{d}_gain_ns"] = to_ns * float(gain[j])
        out[f"{d}_two_step_ns"] = bounds[f"{d}_timed_ns"] + to_ns * float(gain[j])
        out[f"{d}_t2_s"] = float(t2[j])
    out["mean_swing_speed"] = v2
    return out


def hip_bound(rec, robot, ref, bounds: dict) -> dict:
    """The angular-momentum bound at the lateral push (:mod:`wbc.balance.angular`), at once
    and 30 ms late (the estimated DCM's lag), added to the CoP bound (``away_ns``); and the
    same bound for the push where the benchmark applies it (``at_push_point``:
    :func:`wbc.balance.angular.point_push_bound`, the torso's CoM above the robot's)."""
    import numpy as np

    from wbc.bench.pushes import push_direction
    from wbc.bench.sim_record import mid_single_support

    t = mid_single_support(rec)
    k = int(np.clip(np.searchsorted(rec.t - rec.t[0], t), 0, len(rec) - 1))
    i = int(np.clip(np.searchsorted(ref.t - ref.t[0], t), 0, ref.n - 1))
    stance = ref.stance_side(i)
    u = push_direction(rec, "lateral")
    out = {}
    cop = bounds["away_ns"] / (bounds["mass"] * bounds["omega"])  # the CoP's margin, m
    for delay in (0.0, 0.03):
        b = hip_strategy_bound(robot, rec.q[k], stance, u, ref.com_height, delay=delay)
        b["cop_plus_hip_ns"] = bounds["away_ns"] + b["ns"]
        b["cop_plus_stance_hip_ns"] = bounds["away_ns"] + b["stance_hip_ns"]
        # the push where the benchmark applies it (the root body's CoM), not at the CoM
        b["at_push_point"] = point_push_bound(robot, rec.q[k], stance, u, ref.com_height,
                                              cop, delay=delay)  # fmt: skip
        out[f"delay_{round(1e3 * delay)}ms"] = b
    return out


def screen(args) -> None:
    """One push per ``--screen`` item (``DIR:NS:S``), per solver and loop: ``UP`` or the
    fall's time (s) — a screen beside the bisections, at the points just above them; then
    ``/Nf`` (N walking ticks whose solve failed: the last configuration held), ``/Nr`` (N
    ticks relaxed), ``/Nl`` (N ticks of the stack's ``landing_fallback``) and ``/Nb`` (N ticks
    braced, its ``brace``), if any; ``replans``: the step adjuster's re-plans per push (None:
    no step adjustment ran — a robot with no dead bands of its own, or a bus that reads no
    positions: :func:`wbc.balance.live.closed_loop`)."""
    from wbc.bench.pushes import PUSH_DURATION, push_direction
    from wbc.bench.sim_record import mid_single_support

    robot = load_robot(args.robot)
    ff = best_compensate(robot)
    ref = traj.build(args.trajectory, robot)
    fall = "off" if args.fall == "off" else json.loads(args.fall)
    for solver in args.solvers:
        entry = physics_entry(solver, robot)
        rec = plan(solver, args.trajectory, robot)
        t = mid_single_support(rec)
        for loop in args.loops:
            spec, comp = loop_spec(loop, entry, ref, json.loads(args.stepping),
                                   gains_arg(args.gains), json.loads(args.hold), ff,
                                   fall, robot, args.step_on_commands)  # fmt: skip
            out, replans = [], []
            for item in args.screen:
                d, ns, off = item.split(":")
                push = (t + float(off), push_direction(rec, d) * float(ns) / PUSH_DURATION,
                        PUSH_DURATION)  # fmt: skip
                r = simulate(rec, robot, push=push, compensate=comp, closed=spec)
                held = "".join(f"/{r[k]}{k[0]}" for k in ("failed_solves", "relaxed_solves",
                               "landing_fallbacks", "braced_ticks") if r.get(k))  # fmt: skip
                out.append(f"{item}={'UP' if not r['fell'] else round(r['fall_time_s'], 2)}{held}")
                replans.append(r.get("replans"))  # (None: no step adjustment ran)
            print(json.dumps({"solver": solver, "loop": loop, "stepping": args.stepping,
                              "gains": args.gains, "screen": out, "replans": replans}),
                  flush=True)  # fmt: skip


def grid(args) -> None:
    """Up (1) or fallen (0) at each lateral impulse of the grid, per solver and loop: the
    bisection of ``--push`` assumes one threshold; stepping makes survival non-monotonic."""
    import numpy as np

    from wbc.bench.pushes import PUSH_DURATION, push_direction
    from wbc.bench.sim_record import mid_single_support

    robot = load_robot("bioloid")
    ref = traj.build(args.trajectory, robot)
    lo, hi, step = args.grid
    impulses = np.round(np.arange(lo, hi + 1e-9, step), 4)
    for solver in args.solvers:
        entry = next(e for e in select([solver], None, "tick")[0] if e.name == solver)
        rec = plan(solver, args.trajectory, robot)
        u, t = push_direction(rec, "lateral"), mid_single_support(rec)
        for loop in args.loops:
            spec, comp = loop_spec(loop, entry, ref, robot=robot)
            up = []
            for j in impulses:
                push = (t, u * j / PUSH_DURATION, PUSH_DURATION)
                up.append(int(not simulate(rec, robot, push=push, compensate=comp,
                                           closed=spec)["fell"]))  # fmt: skip
            row = {"solver": solver, "loop": loop, "impulses": impulses.tolist(), "up": up}
            print(json.dumps(row), flush=True)


def safety(args) -> None:
    """The deployment's view of the goals of one pushed run per closed loop."""
    import numpy as np

    from wbc.bench.closed_loop import play_closed_loop
    from wbc.bench.pushes import PUSH_DURATION, push_direction
    from wbc.bench.sim_record import mid_single_support, physics_record

    robot = load_robot("bioloid")
    ref = traj.build(args.trajectory, robot)
    for solver in args.solvers:
        entry = next(e for e in select([solver], None, "tick")[0] if e.name == solver)
        rec = plan(solver, args.trajectory, robot)
        u = push_direction(rec, args.safety_direction)
        push = (mid_single_support(rec), u * args.safety / PUSH_DURATION, PUSH_DURATION)
        for loop in [lp for lp in args.loops if lp != "open"] or ["closed", "step"]:
            spec, _ = loop_spec(loop, entry, ref, json.loads(args.stepping), robot=robot)
            result, cl = play_closed_loop(spec, robot, push=push, compensate=0.5)
            rec_fig = physics_record(rec, result, robot, ref)
            lim = result.deploy.limits
            row = {
                "solver": solver,
                "loop": loop,
                "impulse_ns": args.safety,
                "direction": args.safety_direction,
                "fell": rec_fig["fell"],
                "replans": len(cl.stepping.events) if cl.stepping else None,
                "goal_limit_excess_deg": float(np.degrees(max(cl.source.limit_excess, 0.0))),
                "clamped_ticks": int(lim.clamped.sum()),
                "rate_limited_ticks": int(lim.rate_limited.sum()),
                "rate_limited_max_joint": int(lim.rate_limited.max()),
                "completed": bool(result.deploy.completed),
            }
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
