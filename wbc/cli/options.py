"""The command line's shared options, each declared once: the numeric type :func:`number`, the
servo bus, the motion and safety options of a deployment, the torso IMU, the simulated robot
and the compliance feed-forward (``wbc deploy``, ``wbc drive``, ``wbc sim``, ``wbc bench``).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

from ..balance import BEST_COMPENSATE, best_compensate
from ..exceptions import ConfigurationError
from ..servos.config import MAX_RATE_HZ, MAX_SOFT_SPEED, ON_FAULT_CHOICES
from ..servos.connect import BusOptions


def number(
    lo: float | None = None,
    hi: float | None = None,
    *,
    integer: bool = False,
    lo_open: bool = False,
    hi_open: bool = False,
) -> Callable[[str], float]:
    """The argparse ``type`` of every numeric command-line option: a finite number (an integer
    with ``integer``) in ``[lo, hi]`` (``(lo`` / ``hi)`` when open; None: unbounded), else one
    line saying what is allowed: ``argument --limit-tol: must be a finite number in [0, 0.5],
    got 'nan'``."""
    if integer:
        kind = "an integer"
    else:
        kind = "a finite number"
    if lo is not None and hi is not None:
        what = f"{kind} in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
    elif lo is not None:
        what = f"{kind} {'>' if lo_open else '>='} {lo:g}"
    elif hi is not None:
        what = f"{kind} {'<' if hi_open else '<='} {hi:g}"
    else:
        what = kind

    def parse(text: str) -> float:
        try:
            value: float = int(text) if integer else float(text)
        except (TypeError, ValueError):
            value = math.nan
        ok = math.isfinite(value)
        if ok and lo is not None:
            ok = value > lo if lo_open else value >= lo
        if ok and hi is not None:
            ok = value < hi if hi_open else value <= hi
        if not ok:
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        return value

    parse.__name__ = "integer" if integer else "number"  # argparse names the type in errors
    return parse


# ---------------------------------------------------------------------- the robot
def add_robot_argument(parser: argparse.ArgumentParser) -> None:
    """``--robot``: every command's robot."""
    parser.add_argument("--robot", default="bioloid", help="robot name, robot folder or URDF path")


# ---------------------------------------------------------------------- servo bus
def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """The servo bus of a real robot (``wbc deploy``, ``wbc drive``): map, backend, port,
    baud rate, USB latency timer, AX torque limit."""
    parser.add_argument("--servo-map", help="servo map TOML (default: the robot's servos.toml)")
    parser.add_argument(
        "--backend",
        "--bus",
        choices=("dynamixel", "ssc32"),
        default="dynamixel",
        help="servo bus (ssc32: the robot folder's ssc32.toml, or wbc deploy --ssc32-map)",
    )
    parser.add_argument("--port", help="serial port of the servo bus, e.g. /dev/ttyUSB0")
    parser.add_argument(
        "--baud",
        type=number(1, integer=True),
        help="baud rate (default: servo map's, 115200 for ssc32)",
    )
    parser.add_argument(
        "--latency-ms", type=number(0, 255), default=1.0, help="USB latency timer, ms"
    )
    parser.add_argument(
        "--torque-limit",
        type=number(0, 1023, integer=True),
        help="AX torque limit 0..1023 for every servo (overrides the servo map's [settings])",
    )


def bus_options(args: argparse.Namespace) -> BusOptions:
    """The :class:`~wbc.servos.connect.BusOptions` of the parsed bus options (a command
    without ``--reply-timeout-ms``, ``--attempts`` or ``--ssc32-map`` takes their defaults)."""
    default = BusOptions()
    return BusOptions(
        backend=args.backend,
        baud=args.baud,
        rate=args.rate,
        latency_ms=args.latency_ms,
        torque_limit=args.torque_limit,
        reply_timeout_ms=getattr(args, "reply_timeout_ms", default.reply_timeout_ms),
        attempts=getattr(args, "attempts", default.attempts),
        ssc32_map=getattr(args, "ssc32_map", default.ssc32_map),
    )


# ---------------------------------------------------------------------- the deployment
def add_motion_arguments(parser: argparse.ArgumentParser, rate: float) -> None:
    """A deployment's rate and safety options (``wbc deploy``, ``wbc drive``): ``rate`` is the
    command's default control rate (Hz)."""
    parser.add_argument(
        "--rate",
        type=number(0, MAX_RATE_HZ, lo_open=True),
        default=rate,
        help=f"control rate, Hz (<= {MAX_RATE_HZ:g})",
    )
    parser.add_argument(
        "--on-fault",
        choices=ON_FAULT_CHOICES,
        default="auto",
        help="safe stop; auto: overheating/overload -> crouch then torque off, else hold",
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
    parser.add_argument("--log", help="save per-tick goals / present positions (.npz)")


# ---------------------------------------------------------------------- the torso IMU
def add_encoders_only_argument(parser: argparse.ArgumentParser) -> None:
    """``--encoders-only``: the closed loop's estimate without the IMU."""
    parser.add_argument(
        "--encoders-only",
        action="store_true",
        help="closed loop: no IMU, estimate from the servos' positions alone",
    )


def add_stepping_arguments(parser: argparse.ArgumentParser, legacy: bool = True) -> None:
    """``--no-stepping`` (and, with ``legacy``, the old no-op ``--stepping``): the closed loop's
    step adjustment from the measured DCM (``wbc.balance.stepping``), on by default."""
    if legacy:
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


def add_imu_arguments(parser: argparse.ArgumentParser) -> None:
    """The closed loop's torso IMU on a real robot (``wbc deploy``, ``wbc drive``)."""
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
    add_encoders_only_argument(parser)


# ---------------------------------------------------------------------- the simulated robot
def add_sim_arguments(parser: argparse.ArgumentParser) -> None:
    """The simulated robot in place of the servo bus (``wbc deploy``, ``wbc drive``; mujoco
    is imported only when used)."""
    parser.add_argument(
        "--sim", action="store_true", help="no port: the MuJoCo-simulated robot (wbc[physics])"
    )
    parser.add_argument(
        "--realtime",
        action="store_true",
        help="--sim: wall-clock pace (default: lockstep; wbc drive steered from the keyboard "
        "or a gamepad: always)",
    )
    parser.add_argument(
        "--view", action="store_true", help="--sim: show it live in meshcat (at real speed)"
    )


# ---------------------------------------------------------------------- compliance feed-forward
def add_compensate_arguments(parser: argparse.ArgumentParser, purpose: str) -> None:
    """The ``--compensate [GAIN]`` option of every command that can add the servo compliance
    feed-forward (:mod:`wbc.balance.compliance`): the measured best by default
    (:func:`wbc.balance.best_compensate`, resolved by :func:`resolve_compensate`), gain 1 when
    given bare, ``--compensate 0`` turns it off; and ``--compensate-encoders``."""
    parser.add_argument(
        "--compensate",
        type=number(0, 10),
        nargs="?",
        const=1.0,
        default=None,
        metavar="GAIN",
        help=f"{purpose} (gain; default: the measured best, x{BEST_COMPENSATE:g} on AX-12A "
        "servos, x1 on hobby PWM servos; 0 turns it off; wbc.balance.compliance)",
    )
    parser.add_argument(
        "--compensate-encoders",
        action="store_true",
        help="--compensate: rescale each servo's feed-forward online from the encoders' present "
        "positions (wbc.balance.compliance.EncoderCorrection; needs the positions read)",
    )


def resolve_compensate(args: argparse.Namespace, robot, best: bool = True) -> float:
    """``args.compensate`` with its default resolved for ``robot``:
    :func:`wbc.balance.best_compensate` (``best``), else 0 (a recording played as recorded)."""
    if getattr(args, "compensate", None) is None:
        args.compensate = best_compensate(robot) if best else 0.0
    return args.compensate


def check_compensate_encoders(args: argparse.Namespace) -> None:
    """``--compensate-encoders`` corrects the feed-forward: refused without ``--compensate``."""
    if getattr(args, "compensate_encoders", False) and not args.compensate > 0:
        raise ConfigurationError(
            "--compensate-encoders corrects the feed-forward: give --compensate too"
        )
