"""The ``wbc`` command line: one sub-command per capability.

Each sub-command lives in its own module of this package (``wbc.cli.<command>``) exposing
``add_arguments(parser)`` and ``run(args) -> int``; the options several commands share are
declared once in :mod:`wbc.cli.options` (with :func:`number`, the type of every numeric
option), the pieces several commands wire the same way in :mod:`wbc.cli.wiring`. This package
is the only place that parses arguments and wires the library's packages together.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import NoReturn

from .options import number

__all__ = ["COMMANDS", "OPTIONAL", "build_parser", "main", "number"]

# command -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("wbc.cli.demo", "load the robot and print mass, CoM and sole poses at Walk Ready"),
    "bench": ("wbc.cli.bench", "compare solver families on the same trajectories"),
    "walk": ("wbc.cli.walk", "run a task stack along a walking reference and record it"),
    "deploy": ("wbc.cli.deploy", "play a trajectory on AX-12A servos (or a dry run)"),
    "drive": ("wbc.cli.drive", "walk from velocity commands: keyboard, gamepad or a file"),
    "view": ("wbc.cli.view", "show the robot or a recording in meshcat"),
    "sim": ("wbc.cli.sim", "play a plan on the MuJoCo-simulated robot: does it stay up?"),
    "robot": ("wbc.cli.robot", "scaffold (init) or check a robot folder from a URDF"),
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


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage dump): what was wrong and where to look."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

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
    from ..exceptions import WbcError

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
