"""Kokone's key-pose walk as the ``walk`` stack reaches it: one markdown row per key pose.

For each of the first 12 key poses (robots/kokone/README.md section 6): the hip (torso)
position, the CoM, both soles (cm) and both legs' angles in the thesis's DH convention (deg),
read from the recording of ``wbc walk --robot kokone --trajectory keyposes`` at the key-pose
ticks.

Run: ``python benchmarks/kokone_keyposes.py``
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from wbc import load_robot  # noqa: E402
from wbc.bench.trajectories import build  # noqa: E402
from wbc.stacks import load_stack  # noqa: E402
from wbc.walking.loop import StackController, run  # noqa: E402

spec = importlib.util.spec_from_file_location("kokone_gen", ROOT / "robots/kokone/make_urdf.py")
gen = importlib.util.module_from_spec(spec)
spec.loader.exec_module(gen)


def main() -> int:
    robot = load_robot("kokone")
    ref = build("keyposes", robot)
    rec = run(StackController(load_stack("walk", robot)), robot, ref)
    per = round(ref.meta["params"]["pose_time"] / ref.dt)

    def cm(v) -> str:
        return ", ".join(f"{x:.2f}" for x in np.round(np.asarray(v) * 100, 2) + 0.0)

    print(
        "| pose | hip (torso) x, y, z | CoM x, y | left sole x, y, z | right sole x, y, z | "
        "right leg θ1..θ6 | left leg θ1..θ6 |"
    )
    print("|---|---|---|---|---|---|---|")
    for i, kp in enumerate(ref.meta["key_poses"][:12]):
        q = rec.q[i * per]
        th = {s: gen.q_to_dh([q[robot.q_index(f"{s}_{n}")] for n in gen.LEG_JOINTS]) for s in "rl"}
        angles = {s: " ".join(f"{x:.1f}" for x in np.round(th[s], 1) + 0.0) for s in "rl"}
        print(
            f"| {i + 1} | {cm(robot.frame_placement(q, 'torso').translation)} | "
            f"{cm(rec['com'][i * per][:2])} | {cm(kp['left'])} | {cm(kp['right'])} | "
            f"{angles['r']} | {angles['l']} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
