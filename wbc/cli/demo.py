"""``wbc demo``: load a robot and print its mass, CoM and sole poses at a named pose."""

from __future__ import annotations

import argparse

import numpy as np
import pinocchio as pin

from ..model import STANDARD_FRAMES, load_robot, print_notes
from .options import add_robot_argument


def _fmt(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:8.2f}" for x in v) + ")"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_argument(parser)
    parser.add_argument("--pose", default="stand", help="named configuration")


def run(args: argparse.Namespace) -> int:
    robot = load_robot(args.robot)
    print_notes(robot, "demo")
    q = robot.configuration(args.pose)
    print(f"robot {robot.name}: {robot.n_joints} actuated joints, mass {robot.total_mass:.4f} kg")
    com = robot.com(q)
    print(f"pose {args.pose}: CoM (mm) = {_fmt(com * 1e3)}")
    for frame in (f for f in STANDARD_FRAMES if robot.has_frame(f)):
        M = robot.frame_placement(q, frame)
        rpy = np.degrees(pin.rpy.matrixToRpy(M.rotation))
        print(f"  {frame:7s} xyz (mm) = {_fmt(M.translation * 1e3)}  rpy (deg) = {_fmt(rpy)}")
    return 0
