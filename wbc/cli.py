"""The ``wbc`` command line: one sub-command per capability.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int``; modules are imported only when their command runs.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
from collections.abc import Callable, Sequence
from typing import NoReturn

# command -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("wbc.demo", "load the robot and print mass, CoM and sole poses at Walk Ready"),
    "bench": ("wbc.bench.cli", "compare solver families on the same trajectories"),
    "walk": ("wbc.walking.cli", "run a task stack along a walking reference and record it"),
    "deploy": ("wbc.servos.deploy", "play a trajectory on AX-12A servos (or a dry run)"),
    "drive": ("wbc.drive.cli", "walk from velocity commands: keyboard, gamepad or a file"),
    "view": ("wbc.viewer.cli", "show the robot or a recording in meshcat"),
    "sim": ("wbc.sim.cli", "play a plan on the MuJoCo-simulated robot: does it stay up?"),
    "robot": ("wbc.robot_folder", "scaffold (init) or check a robot folder from a URDF"),
}


# optional dependency -> the extra that installs it
OPTIONAL = {
    "meshcat": "viewer",
    "playwright": "viewer",
    "dynamixel_sdk": "servos",
    "serial": "servos",
    "placo": "peers",
    "pink": "peers",
    "matplotlib": "plots",
    "mujoco": "physics",
    "casadi": "mpc",
}


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


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage dump): what was wrong and where to look."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = _Parser(prog="wbc", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"wbc {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(_module=module)
        try:
            importlib.import_module(module).add_arguments(p)
        except ModuleNotFoundError as exc:
            if exc.name and exc.name.startswith("wbc"):
                p.set_defaults(_missing=str(exc))
            else:
                raise
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    if getattr(args, "_missing", None):
        print(f"wbc {args.command}: not available ({args._missing})", file=sys.stderr)
        return 2
    from .exceptions import WbcError

    try:
        return int(importlib.import_module(args._module).run(args) or 0)
    except WbcError as exc:
        print(f"wbc {args.command}: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        extra = OPTIONAL.get((exc.name or "").split(".")[0])
        if extra is None:
            raise
        print(
            f"wbc {args.command}: needs the optional package {exc.name!r}: "
            f"pip install 'wbc[{extra}]' (or 'wbc[all]')",
            file=sys.stderr,
        )
        return 2


if __name__ == "__main__":
    sys.exit(main())
