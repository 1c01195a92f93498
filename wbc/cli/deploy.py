"""``wbc deploy``: play joint targets on the servos at a fixed rate, safely (command line).

The work is split by concern: :mod:`wbc.servos.sources` (what to play),
:mod:`wbc.servos.playback` (the deployment: start-up, ticks, health checks, safe stop),
:mod:`wbc.servos.plan` (bus budget, health schedule, fault bound),
:mod:`wbc.servos.connect` (the bus, the servo map's check) and this module (the options and
the command).

Examples::

    wbc deploy --plan                                   # bus budget, fault bound, rates
    wbc deploy walk.npz --dry-run                       # whole pipeline, no port
    wbc deploy walk.npz --port /dev/ttyUSB0 --rate 50 --read --on-fault torque-off
    wbc deploy walk.npz --backend ssc32 --port /dev/ttyUSB0 --ssc32-map kokone.toml

Exit codes: 0 played to the end, 2 refused (nothing moved), 3 safe stop after a fault,
130 safe stop after Ctrl-C.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
from dataclasses import replace
from pathlib import Path

from ..exceptions import ConfigurationError, TrajectoryError, WbcError
from ..model import load_robot
from ..recording import Recording, RecordingReader
from ..servos.bus import ServoBus
from ..servos.config import AT_END_CHOICES, DeployConfig
from ..servos.connect import check_servo_map, dry_run_bus, real_time_priority
from ..servos.plan import budget_line, plan_lines
from ..servos.playback import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_REFUSED,
    EXIT_SAFE_STOP,
    STOP_SIGNALS,
    Deployment,
    Interrupted,
    report_lines,
    signal_exit_code,
)
from ..servos.sources import RecordingSource, StreamedRecordingSource, TargetSource
from .options import (
    add_bus_arguments,
    add_compensate_arguments,
    add_imu_arguments,
    add_motion_arguments,
    add_robot_argument,
    add_sim_arguments,
    add_stepping_arguments,
    check_compensate_encoders,
    number,
    resolve_compensate,
)
from .wiring import make_bus, make_imu

__all__ = ["EXIT_INTERRUPTED", "EXIT_OK", "EXIT_REFUSED", "EXIT_SAFE_STOP", "add_arguments", "run"]


# ---------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", nargs="?", help="recording .npz to play (t, q columns)")
    parser.add_argument(
        "--live",
        metavar="STACK",
        nargs="?",
        const="",
        help="run a task stack live instead of a recording: STACK, or without it the robot "
        "folder's stack.toml (else walk)",
    )
    parser.add_argument(
        "--trajectory",
        default="walk10_wb",
        help="--live: the walking reference to follow (default walk10_wb, the whole-body walk; "
        "the thesis's walks by name, e.g. walk10; see wbc bench --list)",
    )
    add_robot_argument(parser)
    add_bus_arguments(parser)  # --servo-map, --backend, --port, --baud, --latency-ms, ...
    parser.add_argument("--dry-run", action="store_true", help="no port: simulated ideal servos")
    parser.add_argument(
        "--plan", action="store_true", help="print the bus budget (then play RECORDING if given)"
    )
    add_motion_arguments(parser, rate=50.0)  # --rate, --on-fault, --max-speed, --soft-speed, --log
    parser.add_argument("--read", action="store_true", help="read present positions every tick")
    parser.add_argument(
        "--at-end", choices=AT_END_CHOICES, default="hold", help="after the last target"
    )
    parser.add_argument(
        "--max-failures",
        type=number(1, 20, integer=True),
        default=3,
        help="consecutive failed replies",
    )
    parser.add_argument(
        "--limit-tol", type=number(0, 0.1), default=1e-3, help="rad beyond limits refused"
    )
    parser.add_argument(
        "--start-tol",
        type=number(0, 0.5, lo_open=True),
        default=0.05,
        help="rad outside limits at start",
    )
    parser.add_argument(
        "--turnaround-ms", type=number(0, 255), default=1.0, help="--plan: per reply, ms"
    )
    parser.add_argument(
        "--reply-timeout-ms",
        type=number(0, 1000, lo_open=True),
        help="reply deadline per exchange, ms (default: 2 x latency + 2 ms + wire; SSC-32 50)",
    )
    parser.add_argument(
        "--attempts",
        type=number(1, 10, integer=True),
        default=3,
        help="tries per start-up exchange (PING, settings)",
    )
    parser.add_argument(
        "--fault-bound-ms",
        type=number(0, 1000, lo_open=True),
        default=100.0,
        help="health checks are scheduled so a servo fault stops motion within this time",
    )
    parser.add_argument(
        "--crouch-pose", default="stand", help="named pose of the crouch (safe stop)"
    )
    parser.add_argument(
        "--ssc32-map", help="SSC-32 joint/channel TOML (default: the robot folder's ssc32.toml)"
    )
    parser.add_argument(
        "--rt-priority",
        type=number(1, 99, integer=True),
        nargs="?",
        const=50,
        metavar="PRIO",
        help="run the control loop at real-time priority (SCHED_FIFO, default 50) where "
        "permitted (root, CAP_SYS_NICE or an rtprio limit); says so when not",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="play a recording of a failed run (failed ticks, limit violations): refused without",
    )
    add_compensate_arguments(
        parser,
        "add the servos' expected compliance deflection to the goals (a recording's: "
        "only when given)",
    )
    parser.add_argument(
        "--closed-loop",
        action="store_true",
        help="--live: the closed loop (the default with --live; kept for old command lines)",
    )
    parser.add_argument(
        "--open-loop",
        action="store_true",
        help="--live: no feedback (by default --live closes the loop: state estimate from the "
        "servos' present positions and the torso IMU, feedback on the walking targets, step "
        "adjustment, fall detection; wbc.balance.live)",
    )
    add_imu_arguments(parser)  # --imu, --imu-baud, --encoders-only
    add_stepping_arguments(parser)
    add_sim_arguments(parser)  # --sim, --realtime, --view (no mujoco needed)


def _loaded(stack: str | Path, note: str, robot):
    """Load the live stack, then say which one it is (stdout: errors stay one line)."""
    from ..stacks import load_stack

    control = load_stack(stack, robot)
    print(f"wbc deploy: {note}")
    return control


def _live(args: argparse.Namespace, robot, bus: ServoBus, config: DeployConfig, imu):
    """A task stack solved live along a walking reference, one solve per deploy tick, open
    or closed loop (:func:`wbc.balance.live.closed_loop`); returns (loop, imu, what, s)."""
    from ..balance.live import closed_loop
    from ..bench.trajectories import build
    from ..stacks import robot_stack
    from ..walking.loop import StackController

    stack, note = robot_stack(robot, args.live or None)
    ref = build(args.trajectory, robot, on_servos=True)
    stepping = None
    if not args.no_stepping:
        from ..balance.stepping import SteppingParams

        stepping = SteppingParams()
    loop = closed_loop(
        bus, robot, StackController(_loaded(stack, note, robot)), ref, imu,
        enabled=args.closed_loop, compensate=args.compensate,
        correct=args.compensate_encoders, config=config, stepping=stepping,
    )  # fmt: skip
    state = "closed loop" + (f", IMU {imu.name}" if imu else ", encoders only")
    mode = state if args.closed_loop else "open loop"
    what = f"live {Path(stack).stem} on {args.trajectory} ({mode})"
    return loop, what, ref.duration


def run(args: argparse.Namespace) -> int:
    """``wbc deploy``; every stop signal (:data:`STOP_SIGNALS`) ends like Ctrl-C: before
    torque is on, at once; once it may be on, in the safe stop (:mod:`wbc.servos.playback`)."""
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for signum in STOP_SIGNALS:
            previous[signum] = signal.signal(signum, _raise_interrupted)
    restore = None
    try:
        if getattr(args, "rt_priority", None) is not None:
            restore, text = real_time_priority(args.rt_priority)
            print(f"note: {text}")
        return _run(args)
    finally:
        if restore is not None:
            restore()
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _raise_interrupted(signum, frame) -> None:
    raise Interrupted(signum)


def _run(args: argparse.Namespace) -> int:
    err = sys.stderr
    imu = None
    try:
        robot = load_robot(args.robot, servo_map=args.servo_map)
        if args.open_loop and args.closed_loop:
            raise ConfigurationError("give either --open-loop or --closed-loop, not both")
        if args.no_stepping and args.stepping:
            raise ConfigurationError("give either --stepping or --no-stepping, not both")
        resolve_compensate(args, robot, best=args.live is not None and not args.open_loop)
        if args.closed_loop and args.live is None:
            raise ConfigurationError("--closed-loop runs a controller live: give --live STACK")
        explicit = args.closed_loop
        args.closed_loop = args.live is not None and not args.open_loop  # the default
        if args.backend == "dynamixel" or robot.servo_map is not None:
            for warning in check_servo_map(robot):
                print(f"warning: {warning}", file=err)
        config = DeployConfig(
            rate=args.rate,
            read=args.read or args.closed_loop or args.compensate_encoders,  # (encoders)
            on_fault=args.on_fault,
            at_end=args.at_end,
            max_speed=args.max_speed,
            soft_speed=args.soft_speed,
            max_failures=args.max_failures,
            fault_bound_s=args.fault_bound_ms * 1e-3,
            crouch_pose=args.crouch_pose,
            start_tol=args.start_tol,
            log_path=args.log,
        )
        config.validate()
        bus = make_bus(args, robot, args.port)
        if args.plan:
            for line in plan_lines(bus, config, args.turnaround_ms * 1e-3):
                print(line)
            if args.recording is None:
                return EXIT_OK
        if args.recording is None and args.live is None:
            raise TrajectoryError("give a RECORDING.npz to play, --live STACK (or --plan)")
        if not (math.isfinite(args.compensate) and args.compensate >= 0):
            raise ConfigurationError(
                f"--compensate GAIN must be a finite number >= 0, not {args.compensate}"
            )
        check_compensate_encoders(args)
        loop = imu = None
        holder: list[Deployment] = []  # the deployment, for the encoder correction
        if (args.imu or args.encoders_only or args.stepping) and not args.closed_loop:
            raise ConfigurationError(
                "--imu / --encoders-only / --stepping belong to the closed loop (--live STACK, "
                "without --open-loop)"
            )
        if args.live is not None:
            if args.dry_run:
                bus = dry_run_bus(bus, robot)
            elif not args.port and bus.name != "sim":
                raise ConfigurationError("give --port (or --dry-run)")
            if args.closed_loop and not bus.can_read and not explicit:
                print(f"open loop: the {bus.name} bus cannot read the servos' positions (the "
                      "closed loop through the IMU and the commanded joints measured worse: "
                      "benchmarks/kokone_sim.md; --closed-loop runs it)")  # fmt: skip
                args.closed_loop = False
                config = replace(config, read=args.read or args.compensate_encoders)
            elif args.closed_loop and not bus.can_read:  # the IMU and the commanded joints
                config = replace(config, read=False)
            if args.closed_loop:  # the IMU first: a wrong port fails before the solver builds
                imu = make_imu(args, bus, robot)
                if imu is not None:
                    imu.open()
                    if hasattr(imu, "wait_ready"):
                        imu.wait_ready()
            loop, what, duration = _live(args, robot, bus, config, imu)
        else:
            # streamed from the file (memory independent of its length), unless --compensate
            # needs the recording's channels (its support phases) in memory
            reader = RecordingReader(args.recording)
            problems = reader.problems()
            if problems and not args.force:
                raise TrajectoryError(
                    f"recording {args.recording} is from a failed run ({'; '.join(problems)}); "
                    "give --force to play it anyway"
                )
            for problem in problems:
                print(f"warning: --force: playing a failed run: {problem}", file=err)
            source: TargetSource
            if args.compensate:
                recording = Recording.load(args.recording)
                source = RecordingSource(recording, robot, tol=args.limit_tol)
            else:
                source = StreamedRecordingSource(reader, robot, tol=args.limit_tol)
            what, duration = Path(args.recording).name, source.duration
            if args.compensate:
                from ..balance.compliance import compensated

                source = compensated(source, recording, robot, args.compensate,
                                     args.compensate_encoders, lambda: holder[0])  # fmt: skip
        if loop is None:
            if args.dry_run:
                bus = dry_run_bus(bus, robot)
            elif not args.port and bus.name != "sim":
                raise ConfigurationError("give --port (or --dry-run)")
        print(
            f"deploy {what}: {duration:.2f} s at {args.rate:g} Hz on "
            f"{bus.name}{' ' + args.port if args.port and not args.dry_run else ''}"
        )
        if args.dry_run:
            print(budget_line(bus, config, args.turnaround_ms * 1e-3))
        if loop is None:
            holder.append(Deployment(bus, source, robot, config))
            result = holder[0].run()
        else:
            try:
                result = loop.deployment.run()
            finally:
                if imu is not None:
                    imu.close()
            share = loop.source.cost_share()
            if args.closed_loop and share is not None:
                print(f"closed loop: estimator + feedback {100 * share:.0f} % of the tick "
                      f"(median), largest estimated torso tilt error "
                      f"{math.degrees(loop.stabilizer.max_tilt_error):.1f}°")  # fmt: skip
            print(loop.source.solve_line())
    except WbcError as exc:
        print(f"wbc deploy: refused before any torque was enabled: {exc}", file=err)
        return EXIT_REFUSED
    except KeyboardInterrupt as exc:
        what = f" ({exc})" if isinstance(exc, Interrupted) else ""
        print(f"wbc deploy: interrupted{what} before any torque was enabled", file=err)
        return signal_exit_code(getattr(exc, "signum", None))
    for line in report_lines(result, robot):
        print(line, file=sys.stdout if result.completed else err)
    return result.exit_code
