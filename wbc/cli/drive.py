"""``wbc drive``: walk the robot from velocity commands — a commands file, the keyboard or
a gamepad — on the simulator or on the servos, closed loop, through the deployment's safety
layer (soft start, clamping to the joint limits, rate limit, watchdog, safe stop)::

    wbc drive --sim --commands walk.toml --json run.json      # repeatable, simulated
    wbc drive --sim --view                                    # keyboard, live meshcat
    wbc drive --port /dev/ttyUSB0 --imu /dev/ttyUSB1          # the real robot, keyboard
    wbc drive --port /dev/ttyUSB0 --encoders-only --gamepad   # a gamepad (wbc[gamepad])

Exit codes as ``wbc deploy``: 0 done, 2 refused (nothing moved), 3 safe stop after a fault
(or a fall in the simulator), 130 Ctrl-C.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import ConfigurationError
from .options import (
    add_bus_arguments,
    add_imu_arguments,
    add_motion_arguments,
    add_robot_argument,
    add_sim_arguments,
    number,
)

EXIT_FELL = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_argument(parser)
    parser.add_argument(
        "--solver",
        default="hqp-daqp",
        help="the controller (a `wbc bench --list` solver: hqp-daqp, wqp-daqp, qp-vat, "
        "pinv-vat, placo, pink, ...)",
    )
    src = parser.add_argument_group("commands (one of; default: the keyboard)")
    src.add_argument("--commands", type=Path, metavar="FILE", help="TOML [[command]] tables")
    src.add_argument("--keyboard", action="store_true", help="steer from this terminal")
    src.add_argument(
        "--gamepad", nargs="?", const="", metavar="DEVICE",
        help="steer with a gamepad (evdev; DEVICE: /dev/input/eventN, default the first)",
    )  # fmt: skip
    add_sim_arguments(parser)  # --sim, --realtime, --view
    add_bus_arguments(parser)  # --servo-map, --backend, --port, --baud, --latency-ms, ...
    add_imu_arguments(parser)  # --imu, --imu-baud, --encoders-only
    parser.add_argument("--open-loop", action="store_true", help="no feedback on the targets")
    parser.add_argument(
        "--compensate", type=number(0, 10), default=None,
        help="servo compliance feed-forward gain (0: off; default on AX-12A servos 0.75, "
             "with --no-correct 0.5; on other servos the measured best of their law)",
    )  # fmt: skip
    parser.add_argument(
        "--no-correct", dest="correct", action="store_false",
        help="no per-servo correction of the feed-forward from the encoders",
    )  # fmt: skip
    parser.add_argument(
        "--no-track", dest="track", action="store_false",
        help="no outer loop on the IMU-aided pose (the steps aim from the legs' odometry alone)",
    )  # fmt: skip
    parser.add_argument(
        "--stride-gain", type=number(1, 5), default=None, metavar="G",
        help="plan the steps up to G times longer where the odometry measures them short "
             "(default 1.5; 1: as commanded)",
    )  # fmt: skip
    parser.add_argument(
        "--lift-gain", type=number(1, 5), default=None, metavar="G",
        help="plan the swing up to G times higher where the encoders measure the swing sole "
             "below 0.7 of its apex (default 2; 1: as planned)",
    )  # fmt: skip
    parser.add_argument(
        "--swing-settle", type=number(0, 0.5), default=None, metavar="F",
        help="the share of each swing at its end in which the sole only comes down, its "
             "horizontal move done (default 0.2; 0: moving to the end)",
    )  # fmt: skip
    add_motion_arguments(parser, rate=100.0)  # --rate, --on-fault, --max-speed, --soft-speed, --log
    parser.add_argument(
        "--settle", type=number(0, 600), default=1.0, help="s standing after the stop"
    )
    parser.add_argument(
        "--no-get-up", action="store_true", help="after a fall, stay down (default: get up)"
    )
    parser.add_argument("--json", type=Path, metavar="OUT", help="write the run's record")


def _controller(name: str, robot: Any):
    from ..bench.solvers import registry

    entries = registry("physics")
    if name not in entries:
        raise ConfigurationError(f"--solver {name!r}: unknown; choose from {list(entries)}")
    entry = entries[name]
    if not entry.real_time:
        raise ConfigurationError(f"--solver {name}: not a real-time controller")
    return entry.make(robot)


def _teleop(args: argparse.Namespace):
    if args.commands is not None:
        if args.keyboard or args.gamepad is not None:
            raise ConfigurationError("give --commands FILE, --keyboard or --gamepad, not several")
        return None
    if args.gamepad is not None:
        from ..drive.teleop import Gamepad

        missing = Gamepad.available()
        if missing is None:
            return Gamepad(args.gamepad or None)
        print(f"wbc drive: {missing}; using the keyboard", file=sys.stderr)
    from ..drive.teleop import Keyboard

    return Keyboard()


def run(args: argparse.Namespace) -> int:
    from ..drive.commands import CommandScript, integrate, load_commands
    from ..drive.walker import Walker, default_compensate, failure_lines
    from ..model import load_robot
    from ..servos.config import DeployConfig

    for name in ("rate", "compensate", "settle", "soft_speed"):
        v = getattr(args, name)
        if v is None:  # (--compensate: resolved for the robot below)
            continue
        if not (math.isfinite(v) and v >= 0):
            raise ConfigurationError(f"--{name.replace('_', '-')} must be a number >= 0, got {v}")
    if args.view and not args.sim:
        raise ConfigurationError("--view shows the simulator: add --sim")
    if not args.sim and not args.port:
        raise ConfigurationError("give --sim or --port PORT (the servo bus)")
    if args.imu and args.encoders_only:
        raise ConfigurationError("give either --imu PORT or --encoders-only, not both")
    teleop = _teleop(args)
    commands = load_commands(args.commands) if args.commands is not None else None
    robot = load_robot(args.robot, servo_map=args.servo_map)
    if args.compensate is None:
        args.compensate = default_compensate(robot, args.correct)
    controller = _controller(args.solver, robot)
    config = DeployConfig(
        rate=args.rate, read=True, on_fault=args.on_fault, soft_speed=args.soft_speed,
        max_speed=args.max_speed, log_path=args.log,
    )  # fmt: skip
    config.validate()
    odo = view = sim = None
    holder: list[Any] = []
    if args.sim:
        from ..drive.sim import Odometer, make_sim, wait_for_compiled_ticks
        from .wiring import live_view

        def on_tick() -> None:
            if holder:
                holder[0]()
            if view is not None:
                view(sim)

        realtime = args.realtime or teleop is not None
        if not realtime:  # a lockstep run is repeatable: no interim ticks on a cold cache
            wait_for_compiled_ticks()
        sim, bus, imu = make_sim(robot, None, args.rate, realtime, on_tick)
        odo = Odometer(sim)
        holder.append(odo)
        if args.view:
            view = live_view(robot)
        if args.encoders_only:
            imu = None
        if args.compensate > 0 and sim.hobby:
            args.compensate = 0.0  # the feed-forward models the AX-12A only
    else:
        from ..servos.connect import check_servo_map
        from .wiring import make_bus, make_imu

        if args.backend == "dynamixel" or robot.servo_map is not None:
            for warning in check_servo_map(robot):
                print(f"warning: {warning}", file=sys.stderr)
        bus = make_bus(args, robot, args.port)
        imu = make_imu(args, bus)
    print("wbc drive: measuring the velocity limits and the balance window on the model ...")
    extra: dict[str, Any] = {} if args.stride_gain is None else {"stride_gain": args.stride_gain}
    if args.lift_gain is not None:
        extra["lift_gain"] = args.lift_gain
    if args.swing_settle is not None:
        from ..walking.engine_params import EngineParams

        extra["params"] = EngineParams(settle=args.swing_settle)
    walker = Walker(robot, controller, imu, closed=not args.open_loop,
                    compensate=args.compensate, correct=args.correct,
                    track=args.track, **extra)  # fmt: skip
    lim = walker.limits
    print(
        f"limits: forward {100 * lim.vx_forward:.1f} cm/s, backward {100 * lim.vx_backward:.1f} "
        f"cm/s, sideways {100 * lim.vy:.1f} cm/s, turning {math.degrees(lim.wz):.0f} deg/s"
    )
    state: dict[str, Any] = {"stopped_at": None, "ended": False, "offset": 0.0}
    script = CommandScript(commands) if commands is not None else None

    def before(t: float) -> None:
        if odo is not None and odo.fell_at is not None:
            walker.close()
            return
        if script is not None:
            if walker.calibrating:  # the script starts after the IMU's calibration at rest
                state["offset"] = t
                return
            c = script.at(t - state["offset"])
            if c is not None:
                walker.command(*c.velocity)
                if not walker.walking:
                    walker.start()
                return
            if state["stopped_at"] is None:
                walker.stop()
                state["stopped_at"] = t
        elif not state["ended"] and not teleop.poll(walker):
            state["ended"] = True
            state["stopped_at"] = t
        if state["stopped_at"] is not None and not walker.walking:
            if t > state["stopped_at"] + args.settle:
                walker.close()

    walker.before_tick = before
    if imu is not None:
        imu.open()
        if hasattr(imu, "wait_ready"):
            imu.wait_ready()
    try:
        if teleop is not None:
            teleop.open()
        result = walker.deployment(bus, config).run()
        fell_now = (odo is not None and odo.fell_at is not None) or (
            result.trip is not None and "fall" in result.trip.faults
        )
        if fell_now and not args.no_get_up and imu is not None:
            from ..drive.sim import after_fall

            up = after_fall(bus, imu, robot)
            print(f"get-up: {'standing' if up.completed else up.reason}")
    finally:
        if teleop is not None:
            teleop.close()
        if imu is not None:
            imu.close()
    from ..servos.playback import report_lines

    for line in report_lines(result, robot):
        print(line, file=sys.stdout if result.completed else sys.stderr)
    for line in failure_lines(walker):
        print(line, file=sys.stderr)
    fell = odo.fell_at is not None if odo is not None else None
    if odo is not None:
        print("sim: " + (f"FELL at {odo.fell_at:.2f} s" if fell else "stayed up") +
              f"; base moved {1e3 * np.linalg.norm(odo.displacement()):.0f} mm, "
              f"turned {math.degrees(odo.yaw):.0f} deg")  # fmt: skip
    if args.json:
        record = _record(walker, commands, odo, result, integrate)
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(record, indent=1))
        print(f"record in {args.json}")
    if fell:
        return EXIT_FELL
    return result.exit_code


def _record(walker, commands, odo, result, integrate) -> dict[str, Any]:
    from ..drive.commands import Command

    if commands is not None:
        clipped = [Command(c.duration, *walker.limits.clip(*c.velocity)) for c in commands]
        xy, yaw = integrate(clipped)
        cmd_xy, cmd_yaw = [float(v) for v in xy], float(yaw)
    else:
        cmd_xy, cmd_yaw = None, None  # interactive: no script to integrate
    ticks = np.asarray(walker.tick_time) * 1e3
    return {
        "fell": (odo.fell_at is not None) if odo is not None else None,
        "fall_time_s": odo.fell_at if odo is not None else None,
        "commanded_xy_m": cmd_xy,
        "travelled_xy_m": [float(v) for v in odo.displacement()] if odo is not None else None,
        "commanded_yaw_rad": cmd_yaw,
        "travelled_yaw_rad": float(odo.yaw) if odo is not None else None,
        "steps": walker.engine.steps_taken,
        "failed_solves": walker.failed_solves,
        "failed_solve_causes": dict(walker.failure_causes),
        "walk_tick_ms_p50": float(np.median(ticks)) if ticks.size else None,
        "deploy_completed": bool(result.completed),
        "deploy_trip": None if result.trip is None else str(result.trip),
        "limits": walker.limits.as_dict(),
    }
