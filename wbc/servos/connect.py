"""Setting up a deployment on real servos: the bus of a robot (:func:`make_bus`, from
:class:`BusOptions`), the servo map checked against the URDF (:func:`check_servo_map`), the
dry-run stand-in of a bus (:func:`dry_run_bus`) and the control loop's real-time priority
(:func:`real_time_priority`). The ``wbc deploy`` / ``wbc drive`` options map onto these in
:mod:`wbc.cli.options`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import ConfigurationError, ServoMapError
from ..model import Robot
from .bus import DryRunBus, ServoBus


@dataclass(frozen=True)
class BusOptions:
    """How to talk to a robot's servos: ``backend`` (``dynamixel``: the servo map's protocol,
    AX-12A or X-series; ``ssc32``: hobby servos on a Lynxmotion SSC-32), ``baud`` (None: the
    servo map's, 115200 for the SSC-32), the control ``rate`` (Hz: the SSC-32's move time, the
    X-series watchdog), the USB ``latency_ms`` timer, the AX ``torque_limit`` (0..1023; None:
    the servo map's), the ``reply_timeout_ms`` per exchange (None: from the latency and the
    wire time), the ``attempts`` per start-up exchange and the SSC-32 joint/channel map
    ``ssc32_map`` (None: the robot folder's ``ssc32.toml``, else the default map)."""

    backend: str = "dynamixel"
    baud: int | None = None
    rate: float = 50.0
    latency_ms: float = 1.0
    torque_limit: int | None = None
    reply_timeout_ms: float | None = None
    attempts: int = 3
    ssc32_map: str | Path | None = None


def make_bus(robot: Robot, port: str | None, options: BusOptions) -> ServoBus:
    """The bus named by ``options.backend`` on ``port`` (not opened)."""
    sm = robot.servo_map
    if options.backend == "ssc32":
        from .ssc32 import Ssc32Bus, Ssc32Map

        own = robot.urdf_path.parent / "ssc32.toml"  # the robot folder's map (Kokone)
        if options.ssc32_map or own.is_file():
            ssc_map = Ssc32Map.from_file(options.ssc32_map or own, robot.joint_names)
        elif sm is not None:
            ssc_map = Ssc32Map.default(robot.joint_names, sm.signs.astype(int))
        else:
            raise ServoMapError(f"robot {robot.name} has no ssc32.toml; give --ssc32-map")
        for warning in ssc_map.range_warnings(robot.q_min, robot.q_max):
            print(f"warning: {warning}", file=sys.stderr)
        move_ms = max(1, round(1000.0 / options.rate))
        baud = options.baud or ssc_map.baudrate
        timeout_s = 0.05 if options.reply_timeout_ms is None else options.reply_timeout_ms / 1e3
        return Ssc32Bus(port or "", ssc_map, baud, move_time_ms=move_ms, reply_timeout_s=timeout_s)
    if sm is not None and sm.protocol == 2.0:  # servos.toml [bus] protocol = 2.0
        from .protocol2 import Dynamixel2Bus

        if options.torque_limit is not None:
            raise ConfigurationError(
                "--torque-limit is the AX-12A's register; X-series servos take "
                "[settings] current_limit in servos.toml"
            )
        return Dynamixel2Bus(
            port or "",
            sm,
            options.baud or sm.baudrate,
            latency_timer_ms=options.latency_ms,
            reply_timeout_ms=options.reply_timeout_ms,
            attempts=options.attempts,
            watchdog_ms=max(100.0, 3000.0 / options.rate),  # 3 ticks, at least 100 ms
        )
    from .dynamixel import DynamixelBus

    return DynamixelBus(
        port or "",
        sm,
        options.baud or sm.baudrate,
        latency_timer_ms=options.latency_ms,
        torque_limit=options.torque_limit,
        reply_timeout_ms=options.reply_timeout_ms,
        attempts=options.attempts,
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


def dry_run_bus(bus: ServoBus, robot: Robot) -> DryRunBus:
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


def real_time_priority(priority: int) -> tuple[Callable[[], None] | None, str]:
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
