"""``wbc sim``: the simulated robot on the command line.

``wbc deploy REC.npz --sim [--realtime] [--view]`` runs the deployment (soft start, clamping,
rate limit, watchdog) on :class:`~wbc.sim.bus.SimServoBus` instead of a serial port
(:func:`wbc.cli.wiring.make_sim_bus`). ``wbc sim`` plays a recording, or a solver on a
benchmark trajectory, through the same path and prints what the physics did (fell,
deviations, slip, torques, CoP margin)::

    wbc sim --solver hqp-daqp --trajectory walk10_wb       # closed loop (the default)
    wbc sim --solver hqp-daqp --trajectory walk10 --open-loop   # plan, then play it
    wbc sim results/runs/hqp-daqp__walk10.npz --view       # live in meshcat, planned ghost
    wbc sim --solver placo --trajectory thesis_step --export sim.html --json sim.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from ..exceptions import ConfigurationError, TrajectoryError
from .options import (
    add_compensate_arguments,
    add_encoders_only_argument,
    add_robot_argument,
    add_stepping_arguments,
    number,
    resolve_compensate,
)


# ---------------------------------------------------------------------- wbc sim
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", nargs="?", help="recording .npz to play (else --solver)")
    add_robot_argument(parser)
    parser.add_argument("--solver", default="hqp-daqp", help="plan with this benchmark solver")
    parser.add_argument(
        "--trajectory",
        default="walk10_wb",
        help="benchmark trajectory (default walk10_wb, the whole-body walk; the thesis's by name)",
    )
    parser.add_argument(
        "--open-loop",
        action="store_true",
        help="plan, then play the plan (by default the solver runs live in the tick, closed "
        "loop with the simulated IMU, feed-forward and step adjustment: wbc.balance.live)",
    )
    parser.add_argument(
        "--closed-loop",
        action="store_true",
        help="on hobby PWM servos (no position read back): close the loop through the IMU and "
        "the commanded joints (by default they play open loop: it measured better, "
        "benchmarks/kokone_sim.md); elsewhere the default",
    )
    add_encoders_only_argument(parser)
    add_stepping_arguments(parser, legacy=False)
    add_compensate_arguments(parser, "servo compliance feed-forward on the goals")
    parser.add_argument(
        "--rate", type=number(0, 1000, lo_open=True), help="control rate, Hz (default: recording's)"
    )
    parser.add_argument("--settle", type=number(0, 600), default=1.0, help="hold the end pose, s")
    parser.add_argument(
        "--push",
        nargs=2,
        type=number(),
        metavar=("FX_NS", "FY_NS"),
        help="torso impulse (N·s, world x and y) at mid single support",
    )
    parser.add_argument("--realtime", action="store_true", help="wall-clock pace")
    parser.add_argument("--view", action="store_true", help="show it live in meshcat")
    parser.add_argument("--export", type=Path, help="write a replay page (.html)")
    parser.add_argument("--json", type=Path, help="write the physics record (.json)")
    parser.add_argument("--record", type=Path, help="save the simulated run (.npz)")


def run(args: argparse.Namespace) -> int:
    from ..bench.physics import plan
    from ..bench.play import play
    from ..bench.sim_record import (
        PHYSICS_KEYS,
        mid_single_support,
        physics_record,
        simulated_recording,
    )
    from ..bench.trajectories import build
    from ..model import load_robot
    from ..recording import Recording
    from ..sim.actuator import servo_kind

    if not (math.isfinite(args.settle) and args.settle >= 0):
        raise ConfigurationError(f"--settle must be a time >= 0 s, got {args.settle}")
    robot = load_robot(args.robot)
    closed = best = not args.open_loop and not args.recording
    if args.closed_loop and args.open_loop:
        raise ConfigurationError("--closed-loop and --open-loop: give one")
    if closed and servo_kind(robot) == "hobby_pwm":
        if args.encoders_only:
            raise ConfigurationError(
                f"--encoders-only: {robot.name}'s hobby servos report no positions (its closed "
                "loop is the IMU and the commanded joints)"
            )
        if args.closed_loop:
            print(f"closed loop: {robot.name}'s hobby servos report no positions: the "
                  "estimator uses the IMU and the commanded joint positions")  # fmt: skip
        else:
            print(f"open loop: {robot.name}'s hobby servos report no positions, and the closed "
                  "loop through the IMU and the commanded joints measured worse "
                  "(benchmarks/kokone_sim.md; --closed-loop runs it)")  # fmt: skip
            closed = False
    resolve_compensate(args, robot, best=best)  # the feed-forward's best even open loop
    if not (math.isfinite(args.compensate) and args.compensate >= 0):
        raise ConfigurationError(
            f"--compensate GAIN must be a finite number >= 0, got {args.compensate}"
        )
    if args.recording:
        rec = Recording.load(args.recording)
        label = Path(args.recording).name + " (a recording: played open loop)"
    else:
        from ..bench.physics import physics_stack
        from ..bench.solvers import BENCH_STACKS

        stack = physics_stack(robot)
        if args.solver.startswith(("wqp-", "hqp-")):
            which = "the robot folder's" if stack is not None else "the default"
            stack = stack or BENCH_STACKS["physics"]
            print(f"wbc sim: {args.solver} loads {which} stack {stack}", flush=True)
        walk = build(args.trajectory, robot, on_servos=True)  # (once: the fit takes seconds)
        rec = plan(args.solver, args.trajectory, robot, walk)
        label = f"{args.solver} on {args.trajectory}"
        label += " (closed loop)" if closed else " (open loop)"
    push = None
    if args.push:
        t_push = mid_single_support(rec)
        if t_push is None:
            raise TrajectoryError(f"{label}: no single-support phase to push in")
        duration = 0.01
        push = (t_push, [args.push[0] / duration, args.push[1] / duration, 0.0], duration)
    on_tick = None
    viewer = None
    if args.view:
        from ..viewer import Viewer
        from .wiring import Pacer

        viewer = Viewer(robot)
        print(f"meshcat: {viewer.url} (planned CoM and swing sole beside the real ones)")
        rec_t = rec.t - rec.t[0]
        planned = {k: rec[k] for k in ("com", "swing") if k in rec.channels}
        start: list[float] = []
        pace = Pacer()

        def on_tick(sim) -> None:
            start[:] = start or [sim.time]
            t = sim.time - start[0]
            ref = {
                f"{k}_ref": np.array([np.interp(t, rec_t, v[:, j]) for j in range(3)])
                for k, v in planned.items()
            }
            viewer.update(sim.q(), **ref)
            pace(sim.time)

    if closed:
        from ..balance.stepping import SteppingParams
        from ..bench.closed_loop import ClosedLoopSpec, closed_loop_figures, play_closed_loop
        from ..bench.physics import physics_entry

        if args.realtime:
            raise ConfigurationError("--realtime plays a plan: give --open-loop with it")
        ref = walk
        step = None if args.no_stepping else SteppingParams()
        spec = ClosedLoopSpec(physics_entry(args.solver, robot).make, ref, None, True,
                              not args.encoders_only, step)  # fmt: skip
        result, loop = play_closed_loop(spec, robot, push=push, settle=args.settle,
                                        compensate=args.compensate, on_tick=on_tick)  # fmt: skip
        record = physics_record(rec, result, robot, ref)
        record.update(closed_loop_figures(loop))
        record.update(loop.source.solve_counts())
        print(f"closed loop: IMU {'off (encoders only)' if args.encoders_only else 'on'}, "
              f"feed-forward x{args.compensate:g} on {loop.servo_model}, step adjustment "
              f"{'off' if loop.stepping is None else 'on'}, fall detection on")  # fmt: skip
        print(loop.source.solve_line())
    else:
        result = play(
            rec, robot, rate=args.rate, settle=args.settle, realtime=args.realtime,
            push=push, on_tick=on_tick, compensate=args.compensate,
        )  # fmt: skip
        record = physics_record(rec, result, robot)
    record.pop("_series")
    print(f"simulated {label}: {result.deploy.timing.ticks} ticks")
    for key, (text, unit) in PHYSICS_KEYS.items():
        v = record.get(key)
        if isinstance(v, float) and not math.isnan(v):
            print(f"  {text}: {v:.3g} {unit}".rstrip())
        elif v is not None:
            print(f"  {text}: {v} {unit}".rstrip())
    if not result.deploy.completed:
        print(f"  deploy: SAFE STOP: {result.deploy.trip}", file=sys.stderr)
    sim_rec = simulated_recording(rec, result, robot)
    if args.record:
        sim_rec.save(args.record)
        print(f"simulated run in {args.record}")
    if args.export:
        from ..viewer.scene import export_html

        export_html(robot, sim_rec, args.export)
        print(f"replay page {args.export}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(record, indent=1))
    if viewer is not None:
        viewer.close()
    return 0 if result.deploy.completed else 3
