"""``wbc robot``: scaffold (``init``) or check (``check``) a robot folder from a URDF
(:mod:`wbc.robot_folder`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..robot_folder import check_folder, init_folder


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    init = sub.add_parser("init", help="scaffold a robot folder from a URDF")
    init.add_argument("urdf", type=Path, help="the robot's URDF")
    init.add_argument("--out", type=Path, required=True, help="the folder to create")
    init.add_argument("--force", action="store_true", help="write into a non-empty folder")
    check = sub.add_parser("check", help="check a robot folder (or URDF); one line per finding")
    check.add_argument("folder", help="robot folder, URDF path or robot name")


def run(args: argparse.Namespace) -> int:
    if args.action == "init":
        for line in init_folder(args.urdf, args.out, args.force):
            print(line)
        return 0
    findings = check_folder(args.folder)
    for f in findings:
        print(f, file=sys.stdout)
    errors = sum(f.level == "error" for f in findings)
    print(f"{errors} error(s), {sum(f.level == 'warning' for f in findings)} warning(s)")
    return 1 if errors else 0
