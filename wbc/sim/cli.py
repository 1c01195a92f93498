"""``wbc sim`` and ``wbc deploy --sim``: the simulated robot on the command line.

``wbc deploy REC.npz --sim [--realtime] [--view]`` runs the deployment (soft start, clamping,
rate limit, watchdog) on :class:`~wbc.sim.bus.SimServoBus` instead of a serial port.
``wbc sim`` plays a recording, or a solver on a benchmark trajectory, through the same path
and prints what the physics did (fell, deviations, slip, torques, CoP margin)::

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
from typing import TYPE_CHECKING

import numpy as np

from ..cli import number
from ..exceptions import ConfigurationError, TrajectoryError

if TYPE_CHECKING:
    from .simulator import Simulation


def add_deploy_arguments(parser: argparse.ArgumentParser) -> None:
    """``wbc deploy`` options for the simulated robot (mujoco is imported only when used)."""
    parser.add_argument(
        "--sim", action="store_true", help="no port: the MuJoCo-simulated robot (wbc[physics])"
    )
    parser.add_argument(
        "--realtime", action="store_true", help="--sim: wall-clock pace (default: lockstep)"
    )
    parser.add_argument(
        "--view", action="store_true", help="--sim: show it live in meshcat (at real speed)"
    )


def make_sim_bus(args: argparse.Namespace, robot):
    """The simulated bus for ``wbc deploy --sim`` (robot standing in its standing pose):
    the AX-12A bus, or with ``--bus ssc32`` the SSC-32 backend on a simulated board (hobby
    servos: the robot's ``robot.toml`` ``[servo]``)."""
    from .bus import sim_bus
    from .simulator import Simulation

    sim = Simulation(robot)
    backend = getattr(args, "backend", "dynamixel")
    want = "ssc32" if sim.hobby else "dynamixel"
    if backend != want:
        servo = sim.servo_params.name if sim.hobby else "AX-12A"
        raise ConfigurationError(
            f"--sim: robot {robot.name}'s servos are {servo} ({want} bus): use --bus {want}"
        )
    watch = UprightWatch(sim)
    view = _live_view(robot, sim) if getattr(args, "view", False) else None

    def on_tick(bus) -> None:
        watch()
        if view is not None:
            view(bus)

    torque_limit = getattr(args, "torque_limit", None)
    torque_limit = None if torque_limit == 1023 else torque_limit
    return sim_bus(
        sim, args.rate, realtime=args.realtime, torque_limit=torque_limit, on_tick=on_tick,
        on_close=lambda: print(watch.line(), flush=True),
    )  # fmt: skip


class UprightWatch:
    """What the physics did during ``wbc deploy --sim`` (no plan to compare with): the
    largest torso tilt from its start, and a fall (tilt > 45° or the torso below 60 % of its
    start height, as the physics benchmark's thresholds), checked every control tick."""

    def __init__(self, sim: Simulation) -> None:
        from ..bench.physics import FALL_HEIGHT, FALL_TILT_DEG

        self.sim = sim
        self.limits = (FALL_TILT_DEG, FALL_HEIGHT)
        self.R0 = sim.base_rotation()
        self.z0 = float(sim.q()[2])
        self.xy0 = sim.q()[:2].copy()
        self.t0 = sim.time
        self.tilt_max = 0.0
        self.fell_at: float | None = None

    def __call__(self) -> None:
        R = self.sim.base_rotation()
        tilt = math.degrees(math.acos(np.clip((np.trace(self.R0.T @ R) - 1.0) / 2.0, -1, 1)))
        if self.fell_at is None:
            self.tilt_max = max(self.tilt_max, tilt)
            if tilt > self.limits[0] or self.sim.q()[2] < self.limits[1] * self.z0:
                self.fell_at = self.sim.time - self.t0

    def line(self) -> str:
        """One line: fell (when) or stayed up, the largest torso tilt, the base's travel."""
        moved = 1e3 * np.linalg.norm(self.sim.q()[:2] - self.xy0)
        if self.fell_at is not None:
            return f"sim: FELL at {self.fell_at:.2f} s (torso tilt {self.tilt_max:.1f}° then)"
        return (
            f"sim: stayed up; torso tilt at most {self.tilt_max:.1f}° from the start, "
            f"the base moved {moved:.0f} mm"
        )


def _live_view(robot, sim, planned=None):
    """A meshcat viewer following the simulation (one update per control tick)."""
    from ..viewer import Viewer

    viewer = Viewer(robot)
    print(f"meshcat: {viewer.url}", flush=True)

    pace = _Pacer()

    def update(_bus=None) -> None:
        viewer.update(sim.q())  # the deployment plays joints only: no planned CoM here
        pace(sim.time)

    return update


class _Pacer:
    """Sleep so that simulated time does not run ahead of the wall clock (lockstep physics,
    shown at real speed: a slow draw never changes what the physics does)."""

    def __init__(self) -> None:
        self.start: tuple[float, float] | None = None

    def __call__(self, sim_time: float) -> None:
        import time

        now = time.perf_counter()
        if self.start is None:
            self.start = (now, sim_time)
        ahead = (sim_time - self.start[1]) - (now - self.start[0])
        if ahead > 0:
            time.sleep(ahead)


# ---------------------------------------------------------------------- wbc sim
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", nargs="?", help="recording .npz to play (else --solver)")
    parser.add_argument("--robot", default="bioloid", help="robot name or URDF path")
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
        "--encoders-only", action="store_true", help="closed loop: no IMU, the encoders alone"
    )
    parser.add_argument(
        "--no-stepping", action="store_true", help="closed loop: no step adjustment"
    )
    from ..balance import add_compensate_argument

    add_compensate_argument(parser, "servo compliance feed-forward on the goals")
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
    from ..bench.physics import (
        PHYSICS_KEYS,
        mid_single_support,
        physics_record,
        plan,
        simulated_recording,
    )
    from ..model import load_robot
    from ..recording import Recording
    from .play import play

    if not (math.isfinite(args.settle) and args.settle >= 0):
        raise ConfigurationError(f"--settle must be a time >= 0 s, got {args.settle}")
    from ..balance import resolve_compensate
    from .actuator import servo_kind

    robot = load_robot(args.robot)
    closed = best = not args.open_loop and not args.recording
    if closed and servo_kind(robot) == "hobby_pwm":
        print(f"open loop: {robot.name}'s hobby servos report no positions (the closed loop "
              "reads them)")  # fmt: skip
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
        rec = plan(args.solver, args.trajectory, robot)
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

        viewer = Viewer(robot)
        print(f"meshcat: {viewer.url} (planned CoM and swing sole beside the real ones)")
        rec_t = rec.t - rec.t[0]
        planned = {k: rec[k] for k in ("com", "swing") if k in rec.channels}
        start: list[float] = []
        pace = _Pacer()

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
        from ..bench.physics import ClosedLoopSpec, closed_loop_figures, play_closed_loop
        from ..bench.solvers import registry
        from ..bench.trajectories import build

        if args.realtime:
            raise ConfigurationError("--realtime plays a plan: give --open-loop with it")
        ref = build(args.trajectory, robot)
        step = None if args.no_stepping else SteppingParams()
        spec = ClosedLoopSpec(registry()[args.solver].make, ref, None, True,
                              not args.encoders_only, step)  # fmt: skip
        result, loop = play_closed_loop(spec, robot, push=push, settle=args.settle,
                                        compensate=args.compensate, on_tick=on_tick)  # fmt: skip
        record = physics_record(rec, result, robot, ref)
        record.update(closed_loop_figures(loop))
        print(f"closed loop: IMU {'off (encoders only)' if args.encoders_only else 'on'}, "
              f"feed-forward x{args.compensate:g} on {loop.servo_model}, step adjustment "
              f"{'off' if loop.stepping is None else 'on'}, fall detection on")  # fmt: skip
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
