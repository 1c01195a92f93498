"""``wbc deploy``: play joint targets on the servos at a fixed rate, safely (command line).

The work is split by concern: :mod:`.sources` (what to play), :mod:`.playback` (the
deployment: start-up, ticks, health checks, safe stop), :mod:`.plan` (bus budget, health
schedule, fault bound) and this module (arguments, building the bus, the command). The names
below are re-exported for callers of ``wbc.servos.deploy``.

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
import os
import signal
import sys
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..balance import add_compensate_argument, check_compensate_encoders, resolve_compensate
from ..cli import number
from ..exceptions import ConfigurationError, ServoMapError, TrajectoryError, WbcError
from ..model import Robot, load_robot
from ..recording import Recording, RecordingReader
from .bus import DryRunBus, ServoBus
from .plan import budget_line, plan_lines
from .playback import (
    AT_END_CHOICES,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_REFUSED,
    EXIT_SAFE_STOP,
    MAX_RATE_HZ,
    MAX_SOFT_SPEED,
    ON_FAULT_CHOICES,
    STOP_SIGNALS,
    DeployConfig,
    Deployment,
    DeployResult,
    Interrupted,
    TimingStats,
    deploy,
    report_lines,
    signal_exit_code,
)
from .sources import CallableSource, RecordingSource, StreamedRecordingSource, TargetSource

__all__ = [
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_REFUSED",
    "EXIT_SAFE_STOP",
    "MAX_RATE_HZ",
    "CallableSource",
    "DeployConfig",
    "DeployResult",
    "Deployment",
    "RecordingSource",
    "TargetSource",
    "TimingStats",
    "add_arguments",
    "check_servo_map",
    "deploy",
    "make_bus",
    "report_lines",
    "run",
]


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
    parser.add_argument("--robot", default="bioloid", help="robot name or URDF path")
    parser.add_argument("--servo-map", help="servo map TOML (default: the robot's servos.toml)")
    parser.add_argument(
        "--backend",
        "--bus",
        choices=("dynamixel", "ssc32"),
        default="dynamixel",
        help="servo bus (ssc32: the robot folder's ssc32.toml unless --ssc32-map)",
    )
    parser.add_argument("--port", help="serial port, e.g. /dev/ttyUSB0")
    parser.add_argument(
        "--baud",
        type=number(1, integer=True),
        help="baud rate (default: servo map's, 115200 for ssc32)",
    )
    parser.add_argument("--dry-run", action="store_true", help="no port: simulated ideal servos")
    parser.add_argument(
        "--plan", action="store_true", help="print the bus budget (then play RECORDING if given)"
    )
    parser.add_argument(
        "--rate", type=number(0, MAX_RATE_HZ, lo_open=True), default=50.0, help="Hz (<= 100)"
    )
    parser.add_argument("--read", action="store_true", help="read present positions every tick")
    parser.add_argument(
        "--on-fault",
        choices=ON_FAULT_CHOICES,
        default="auto",
        help="safe stop; auto: overheating/overload -> crouch then torque off, else hold",
    )
    parser.add_argument(
        "--at-end", choices=AT_END_CHOICES, default="hold", help="after the last target"
    )
    parser.add_argument(
        "--max-speed", type=number(0, lo_open=True), help="rad/s (default: the servo speed)"
    )
    parser.add_argument(
        "--soft-speed",
        type=number(0, MAX_SOFT_SPEED, lo_open=True),
        default=0.5,
        help=f"soft start and crouch, rad/s (<= {MAX_SOFT_SPEED:g})",
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
        "--latency-ms", type=number(0, 255), default=1.0, help="USB latency timer, ms"
    )
    parser.add_argument(
        "--turnaround-ms", type=number(0, 255), default=1.0, help="--plan: per reply, ms"
    )
    parser.add_argument(
        "--torque-limit",
        type=number(0, 1023, integer=True),
        help="AX torque limit 0..1023 for every servo (overrides the servo map's [settings])",
    )
    parser.add_argument(
        "--reply-timeout-ms",
        type=number(0, 1000, lo_open=True),
        help="reply deadline per exchange, ms (default: 2 x latency + 2 ms + wire time)",
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
    parser.add_argument("--ssc32-map", help="SSC-32 joint/channel TOML")
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
    parser.add_argument("--log", help="save per-tick goals / present positions (.npz)")
    add_compensate_argument(
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
    parser.add_argument(
        "--imu",
        metavar="PORT",
        help="closed loop: the torso IMU's serial port (WitMotion WT901/HWT901B family); "
        "with --sim the simulated torso IMU is used; without either: encoders only",
    )
    parser.add_argument(
        "--imu-baud",
        type=number(1, integer=True),
        default=115200,
        help="--imu: the IMU's baud rate (115200)",
    )
    parser.add_argument(
        "--encoders-only",
        action="store_true",
        help="closed loop: no IMU, estimate from the servos' positions alone",
    )
    parser.add_argument(
        "--stepping",
        action="store_true",
        help="closed loop: step adjustment (the default; kept for old command lines)",
    )
    parser.add_argument(
        "--no-stepping",
        action="store_true",
        help="closed loop: no step adjustment from the measured DCM (wbc.balance.stepping)",
    )
    from ..sim.cli import add_deploy_arguments  # --sim, --view, --realtime (no mujoco needed)

    add_deploy_arguments(parser)


def make_bus(args: argparse.Namespace, robot: Robot, port: str | None) -> ServoBus:
    """The backend named by ``--backend`` (not opened)."""
    sm = robot.servo_map
    if getattr(args, "sim", False):
        from ..sim.cli import make_sim_bus

        return make_sim_bus(args, robot)
    if args.backend == "ssc32":
        from .ssc32 import Ssc32Bus, Ssc32Map

        own = robot.urdf_path.parent / "ssc32.toml"  # the robot folder's map (Kokone)
        if args.ssc32_map or own.is_file():
            ssc_map = Ssc32Map.from_file(args.ssc32_map or own, robot.joint_names)
        elif sm is not None:
            ssc_map = Ssc32Map.default(robot.joint_names, sm.signs.astype(int))
        else:
            raise ServoMapError(f"robot {robot.name} has no ssc32.toml; give --ssc32-map")
        for warning in ssc_map.range_warnings(robot.q_min, robot.q_max):
            print(f"warning: {warning}", file=sys.stderr)
        move_ms = max(1, round(1000.0 / args.rate))
        return Ssc32Bus(port or "", ssc_map, args.baud or ssc_map.baudrate, move_time_ms=move_ms)
    if sm is not None and sm.protocol == 2.0:  # servos.toml [bus] protocol = 2.0
        from .protocol2 import Dynamixel2Bus

        if args.torque_limit is not None:
            raise ConfigurationError(
                "--torque-limit is the AX-12A's register; X-series servos take "
                "[settings] current_limit in servos.toml"
            )
        return Dynamixel2Bus(
            port or "",
            sm,
            args.baud or sm.baudrate,
            latency_timer_ms=args.latency_ms,
            reply_timeout_ms=args.reply_timeout_ms,
            attempts=args.attempts,
            watchdog_ms=max(100.0, 3000.0 / args.rate),  # 3 ticks, at least 100 ms
        )
    from .dynamixel import DynamixelBus

    return DynamixelBus(
        port or "",
        sm,
        args.baud or sm.baudrate,
        latency_timer_ms=args.latency_ms,
        torque_limit=args.torque_limit,
        reply_timeout_ms=args.reply_timeout_ms,
        attempts=args.attempts,
    )


def check_servo_map(robot: Robot, tol: float = 1e-3) -> list[str]:
    """Refuse a servo map whose named poses (e.g. Walk Ready) fall outside the URDF limits
    (a wrong sign or zero tick); return warnings for joints whose URDF range the servo's
    0..1023 ticks cut by more than 5 %."""
    sm = robot.servo_map
    if sm is None:
        raise ServoMapError(f"robot {robot.name} has no servo map (servos.toml); use --servo-map")
    for name in sorted(sm.poses):
        q = sm.ticks_to_angles(sm.pose_ticks(name))
        bad = np.flatnonzero((q < robot.q_min - tol) | (q > robot.q_max + tol))
        if bad.size:
            parts = [
                f"{robot.joint_names[i]} (id {sm.ids[i]}) at {q[i]:.4f} rad, limits "
                f"[{robot.q_min[i]:.4f}, {robot.q_max[i]:.4f}]"
                for i in bad
            ]
            raise ServoMapError(
                f"servo map {sm.source} is inconsistent with the URDF {robot.urdf_path.name}: "
                f"pose {name!r} puts " + "; ".join(parts) + " (wrong sign or zero tick?)"
            )
    a = sm.angles_to_ticks_float(robot.q_min)
    b = sm.angles_to_ticks_float(robot.q_max)
    span = np.abs(b - a)
    reachable = np.minimum(np.maximum(a, b), sm.tick_max) - np.maximum(
        np.minimum(a, b), sm.tick_min
    )
    return [
        f"servo map: only {100 * reachable[i] / span[i]:.0f} % of {robot.joint_names[i]}'s URDF "
        f"range lies inside the servo's {sm.tick_min}..{sm.tick_max} ticks"
        for i in np.flatnonzero(reachable < 0.95 * span)
    ]


def _dry_bus(bus: ServoBus, robot: Robot) -> DryRunBus:
    """Ideal servos at the robot's standing pose, reading back only what ``bus`` could, with
    its figures: health checks per servo or per board, top speed, bus budget (the dry run of
    an SSC-32 shows the SSC-32's)."""
    if robot.stand_pose != "zero":
        start = bus.codec.encode_float(robot.configuration("stand")[7:])
    else:
        start = bus.codec.encode_float(np.clip(0.0, robot.q_min, robot.q_max))
    start = np.clip(np.rint(start), bus.codec.cmd_min, bus.codec.cmd_max)
    dry = DryRunBus(bus.codec, bus.labels, start)
    dry.can_read = bus.can_read
    dry.name = "dry-run" if bus.can_read else f"dry-run {bus.name}"
    dry.unchecked = getattr(bus, "unchecked", ())
    dry.health_per_servo = bus.health_per_servo
    dry.servo_speed = bus.servo_speed
    dry.turnaround_s = bus.turnaround_s
    dry.budget = bus.budget  # type: ignore[method-assign]
    dry.tick_budget = bus.tick_budget  # type: ignore[method-assign]
    return dry


def _imu(args: argparse.Namespace, bus: ServoBus, robot: Robot | None = None, out=print):
    """The torso IMU of the closed loop: the simulated one (--sim), a WitMotion on --imu
    PORT (mounted as ``robot``'s ``robot.toml`` ``[imu]`` says), or None: --encoders-only,
    or no IMU given (said through ``out``)."""
    if args.encoders_only:
        if args.imu:
            raise ConfigurationError("give either --imu PORT or --encoders-only, not both")
        return None
    if args.imu:
        from ..imu_witmotion import WitImu

        mount = None
        if robot is not None:
            from ..sim.model import imu_mount

            mount = imu_mount(robot)
        return WitImu(args.imu, args.imu_baud, mount=mount)
    if getattr(bus, "sim", None) is not None:
        from ..sim.bus import SimImu

        return SimImu(bus.sim)
    out(
        "closed loop: no IMU given (--imu PORT): estimating from the servos' encoders alone "
        "(the stance sole assumed flat; --encoders-only says so without this note)"
    )
    return None


def _loaded(stack: str | Path, note: str, robot: Robot):
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
    ref = build(args.trajectory, robot)
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
    torque is on, at once; once it may be on, in the safe stop (:mod:`.playback`)."""
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


def real_time_priority(priority: int):
    """Run this process at ``SCHED_FIFO`` ``priority`` (fewer late ticks on a busy host);
    returns ``(restore, line)``: ``restore()`` puts the previous policy back (None if
    nothing changed) and ``line`` says what happened, or why it was not permitted."""
    if not hasattr(os, "sched_setscheduler"):
        return None, "--rt-priority: this platform has no sched_setscheduler; normal priority"
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as exc:  # EPERM: no CAP_SYS_NICE / rtprio limit
        return None, (
            f"--rt-priority: not permitted ({exc.strerror}); running at normal priority "
            "(needs root, CAP_SYS_NICE or an rtprio limit in /etc/security/limits.conf)"
        )

    def restore() -> None:
        try:
            os.sched_setscheduler(0, policy, param)
        except OSError:
            pass

    return restore, f"real-time priority: SCHED_FIFO {priority}"


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
                bus = _dry_bus(bus, robot)
            elif not args.port and bus.name != "sim":
                raise ConfigurationError("give --port (or --dry-run)")
            if args.closed_loop and not bus.can_read and not explicit:
                print(f"open loop: the {bus.name} bus cannot read the servos' positions, which "
                      "the closed loop needs")  # fmt: skip
                args.closed_loop = False
                config = replace(config, read=args.read or args.compensate_encoders)
            if args.closed_loop:  # the IMU first: a wrong port fails before the solver builds
                imu = _imu(args, bus, robot)
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
                bus = _dry_bus(bus, robot)
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
