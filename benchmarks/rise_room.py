"""The loaded legs' room to extend on each robot's walk (issue 30, ``Gains.rise_room``):
:func:`wbc.balance.push_rise.straight_room` of the stance leg over the single supports (the
lower sole's leg) and of both legs over the double supports, from the reference's CoM and
soles with :class:`~wbc.walking.legs.LegGeometry`'s pelvis model.

    python benchmarks/rise_room.py [--trajectory walk10_wb] [--robots bioloid op3 kokone]
"""

from __future__ import annotations

import argparse

import numpy as np

from wbc.balance.push_rise import straight_room
from wbc.bench import trajectories as traj
from wbc.model import load_robot
from wbc.walking.legs import LegGeometry


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trajectory", default="walk10_wb")
    ap.add_argument("--robots", nargs="+", default=["bioloid", "op3", "kokone"])
    args = ap.parse_args()
    for name in args.robots:
        robot = load_robot(name)
        legs = LegGeometry.from_robot(robot, robot.configuration("stand"))
        ref = traj.build(args.trajectory, robot)
        lh, rh = legs.hips(ref.com, ref.torso_yaw, ref.l_sole, ref.r_sole)
        room = np.column_stack(
            [straight_room(legs, lh, ref.l_sole), straight_room(legs, rh, ref.r_sole)]
        )
        zl, zr = ref.l_sole[:, 2], ref.r_sole[:, 2]
        single = np.abs(zl - zr) > 1e-3
        stance = np.where(zl < zr, room[:, 0], room[:, 1])[single]
        lo, mid, hi = 1e3 * np.percentile(stance, [0, 50, 100])
        print(f"{name}: CoM height {ref.com_height * 1e3:.1f} mm; the stance leg's room in "
              f"single support {lo:.1f} / {mid:.1f} / {hi:.1f} mm (min / median / max); both "
              f"legs' in double support {1e3 * room[~single].min():.1f} mm (min); median / "
              f"CoM height {np.median(stance) / ref.com_height:.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
