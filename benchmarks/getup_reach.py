"""Can the hands hold the robot while its CoM crosses onto the feet? (the get-up from the back,
issue 33). The get-up from the back ends on feet and hands with the hands behind the CoM; it
can lift them quasi-statically only through a pose with the CoM over the soles and the hands
still on the floor behind it. This plans that pose with the get-up's own QP
(:class:`wbc.balance.getup.PhasePlanner`): from the standing pose, a squat on both soles with
the CoM ``--ahead`` m in front of the soles' rear edge, as low as the QP gets it (goal
``--com-z``), the torso pitched forward by each ``--pitch`` (a negative pitch leans it back,
from a crouch: the knees at their limit, the shins forward); then both hands sent to the floor
beside the feet, ``--behind`` m behind the CoM. Prints, per pitch, the CoM's height and its
margin over the heels, the shoulders' height, the hands' lowest height (0: on the floor) and
the joints within 2° of a limit.

    python benchmarks/getup_reach.py

Figures: benchmarks/getup.md.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np
import pinocchio as pin

os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")

from wbc import load_robot
from wbc.balance.getup import HEEL_FRAMES, BodySizes, Phase, PhasePlanner
from wbc.model import Kinematics
from wbc.roles import HAND_FRAMES


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="bioloid")
    ap.add_argument(
        "--pitch", type=float, nargs="+", default=[40, 60, 75, 90, 105, 125, -60, -70, -80]
    )
    ap.add_argument("--ahead", type=float, default=0.005)
    ap.add_argument("--behind", type=float, default=0.01)
    ap.add_argument("--com-z", type=float, default=0.05)
    args = ap.parse_args(argv)
    robot = load_robot(args.robot)
    sizes = BodySizes.of(robot)
    soles = ("l_sole", "r_sole")
    stand = robot.place_on_ground(robot.configuration(robot.stand_pose))
    # leaning back: from a crouch, the knees at their limit and the shins forward
    crouch = robot.configuration(robot.stand_pose)
    for side in ("left", "right"):
        for role, value in (("hip_pitch", -40.0), ("knee", None), ("ankle_pitch", -80.0)):
            j = robot.joint_names.index(robot.roles.joint(side, role))
            crouch[7 + j] = robot.q_max[j] - 0.01 if value is None else math.radians(value)
    crouch[7:] = np.clip(crouch[7:], robot.q_min, robot.q_max)
    crouch = robot.place_on_ground(crouch)
    ground = pin.SE3.Identity()
    print(f"{robot.name}: joint limits ankle pitch / hip pitch / knee (deg): "
          + " / ".join(f"{math.degrees(robot.q_min[robot.joint_names.index(j)]):.0f}.."
                       f"{math.degrees(robot.q_max[robot.joint_names.index(j)]):.0f}"
                       for j in (robot.roles.joint("left", r)
                                 for r in ("ankle_pitch", "hip_pitch", "knee"))))  # fmt: skip
    for pitch in args.pitch:
        planner = PhasePlanner(robot)
        rb = planner.robot
        planner.floor = {f: 0.0 for f in planner.body_points}  # standing: no floor rows
        start = stand if pitch >= 0 else crouch
        kin = Kinematics(rb, start)
        heel_x = kin.translation(rb.frame_id(HEEL_FRAMES["left"]))[0]
        centre_x = np.mean([kin.translation(rb.frame_id(s))[0] for s in soles])
        shift = heel_x + args.ahead - centre_x
        squat = Phase("squat", soles, 2.0, com_over=soles, com_shift=shift, com_z=args.com_z,
                      torso_pitch=math.radians(pitch))  # fmt: skip
        q = planner.plan(squat, start, ground).q[-1]
        com_x = Kinematics(rb, q).com[0]
        y = sizes.hip_y + 0.5 * float(robot.foot_size[1]) + 0.02
        goal = {HAND_FRAMES["left"]: (com_x - args.behind, y, 0.0),
                HAND_FRAMES["right"]: (com_x - args.behind, -y, 0.0)}  # fmt: skip
        hands = Phase("hands", soles, 2.0, com_over=soles, com_shift=shift, moves=goal,
                      torso_pitch=math.radians(pitch), posture_weight=0.001)  # fmt: skip
        plan = planner.plan(hands, q, ground)
        q = plan.q[-1]
        kin = Kinematics(rb, q)
        shoulders = kin.data.oMi[rb.model.getJointId(robot.roles.joint("left", "shoulder_pitch"))]
        hand_z = min(kin.translation(rb.frame_id(f))[2] for f in HAND_FRAMES.values())
        near = [n for n, v, lo, hi in zip(robot.joint_names, q[7:], robot.q_min, robot.q_max,
                                          strict=True)
                if min(v - lo, hi - v) < math.radians(2) and n.startswith("l_")]  # fmt: skip
        up = math.degrees(math.asin(float(np.clip(kin.rotation(rb.frame_id("torso"))[2, 2],
                                                  -1, 1))))  # fmt: skip
        print(
            f"torso pitch goal {pitch:4.0f} deg (elevation {up:3.0f}): CoM z "
            f"{1e3 * kin.com[2]:4.0f} mm, {1e3 * (kin.com[0] - heel_x):3.0f} mm ahead of the "
            f"heels; shoulders z {1e3 * shoulders.translation[2]:4.0f} mm; hands "
            f"{1e3 * hand_z:3.0f} mm above the floor; at a limit: {', '.join(near) or '-'}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
