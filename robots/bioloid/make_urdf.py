"""Generate ``bioloid.urdf`` (Robotis Bioloid Premium, Type A) from sourced numbers.

Run ``python robots/bioloid/make_urdf.py`` to rewrite the URDF; ``tests/test_robot_files.py``
checks that the committed file equals this script's output. Every number below carries its
source; ``robots/bioloid/README.md`` explains the choices.

Conventions of *our* model (not of any servo or source URDF):

* Every link frame is parallel to the torso frame at q = 0 (x forward, y left, z up), so a
  joint origin is a pure translation and every axis is +x (roll), +y (pitch) or +z (yaw) on
  both sides. A mirror-symmetric pose therefore has equal pitch angles and opposite roll/yaw
  angles on the two sides.
* q = 0: legs straight and facing forward, arms stretched sideways (T-pose) with the shoulder
  roll axis pointing forward, so roll lowers the arm in the frontal plane and pitch swings
  the (lowered) arm forward/back. Knee flexion is positive.
* Joint limits are the CoM-control thesis's Annex A limits (servo degrees from tick 512),
  mapped through ``servos.toml`` into these frames.
"""

from __future__ import annotations

import math
import sys
import tomllib
from pathlib import Path
from xml.sax.saxutils import quoteattr

from wbc.urdf_writer import Link, fmt, link_xml

HERE = Path(__file__).resolve().parent
MM = 1e-3
G = 1e-3  # grams -> kg
DEG_PER_TICK = 300.0 / 1023.0  # AX-12A: 1023 ticks over 300 degrees (bioloid-facts §4.1)

# --- Actuator (bioloid-facts §4.1, EMAN-AX) -------------------------------------------------
STALL_TORQUE = 1.5  # N·m at 12 V
NO_LOAD_SPEED = 59.0 * 2.0 * math.pi / 60.0  # 59 rpm at 12 V -> rad/s
SERVO_BOX = (40 * MM, 32 * MM, 50 * MM)  # AX-12A 32 W x 50 H x 40 D mm

# --- Annex A of the thesis: limits in servo degrees from tick 512, keyed by Robotis ID ----
# (bioloid-facts §8 maps thesis joints j1..j18 to IDs.)
ANNEX_A = {
    1: ("j10", -150.0, 150.0),
    3: ("j11", -80.26, 84.67),
    5: ("j12", -36.65, 84.35),
    2: ("j7", -150.0, 150.0),
    4: ("j8", -84.67, 80.6),
    6: ("j9", -84.35, 36.6),
    7: ("j13", -67.09, 24.02),
    9: ("j15", -40.46, 5.57),
    11: ("j14", -130.1, 25.9),
    13: ("j16", -129.69, 0.0),
    15: ("j17", -25.0, 100.0),
    17: ("j18", -50.0, 50.0),
    8: ("j6", -24.8, 67.09),
    10: ("j4", -5.57, 40.17),
    12: ("j5", -25.2, 130.6),
    14: ("j3", 0.0, 129.44),
    16: ("j2", -100.84, 25.2),
    18: ("j1", -50.68, 50.1),
}


def mm_link(name: str, mass_g: float, com_mm, inertia_box_mm, boxes) -> Link:
    """A link from grams and mm: CoM, the solid box of its inertia, its (centre, size, material)
    boxes, all in the link frame."""
    return Link.scaled(name, mass_g * G, com_mm, inertia_box_mm, boxes, MM)


def side_links(s: int, p: str) -> list[Link]:
    """Links of one side; s = +1 left, -1 right; p = 'l' or 'r'.

    Masses: MR-old / PEPE CAD set (bioloid-facts §2.2), total 1914.4 g.
    CoMs: estimates at the centre of each part's servo bodies / brackets (README.md).
    """
    ax = SERVO_BOX
    return [
        # leg -----------------------------------------------------------------------------
        mm_link(
            f"{p}_hip_bracket",
            15.1,
            (0, 0, -25),
            (32, 40, 50),
            [((0, 0, -25), (30, 36, 10), "frame")],
        ),
        # the roll servo turns about its horn axis, so it reaches half its 32 mm width
        # (16 mm) above the roll/pitch axes: below the yaw bracket (20 mm above) and clear
        # of the torso plate (29 mm above) at any roll (self-collision, README section 3)
        mm_link(
            f"{p}_hip_block",
            137.0,
            (0, 0, 0),
            (40, 32, 100),
            [
                ((0, 0, 3), (ax[0] * 1e3, ax[1] * 1e3, 26), "servo"),
                ((0, 0, -8), (ax[1] * 1e3, ax[0] * 1e3, 36), "servo"),
            ],
        ),
        mm_link(
            f"{p}_thigh",
            31.2,
            (-7.25, 0, -37.5),
            (20, 30, 75),
            [((-7.25, 0, -37.5), (22, 32, 60), "frame")],
        ),
        mm_link(
            f"{p}_shin",
            86.7,
            (-7.0, 0, -22.0),
            (40, 32, 71),
            [
                ((-9.0, 0, -20.0), (ax[0] * 1e3, ax[1] * 1e3, 40), "servo"),
                ((4.0, 0, -52.0), (22, 32, 30), "frame"),
            ],
        ),
        mm_link(
            f"{p}_ankle_block",
            137.0,
            (0, 0, 0),
            (40, 32, 100),
            [
                ((0, 0, 8), (ax[0] * 1e3, ax[1] * 1e3, 36), "servo"),
                ((0, 0, -8), (ax[0] * 1e3, ax[1] * 1e3, 36), "servo"),
            ],
        ),
        # foot plate 101 x 61 x 9 mm, centred under the ankle, bottom face 32.2 mm below the
        # ankle axes (bioloid-facts §1.3, MR collision box)
        mm_link(
            f"{p}_foot",
            37.4,
            (0, 0, -24.0),
            (101, 61, 16),
            [((0, 0, -27.7), (101, 61, 9), "foot"), ((0, 0, -14.0), (24, 34, 18), "frame")],
        ),
        # arm -----------------------------------------------------------------------------
        mm_link(
            f"{p}_shoulder_bracket",
            11.9,
            (0, 22 * s, -7),
            (20, 44, 20),
            [((0, 22 * s, -7), (20, 44, 14), "frame")],
        ),
        mm_link(
            f"{p}_upper_arm",
            76.5,
            (0, 30 * s, 0),
            (32, 67.5, 40),
            [
                ((0, 26 * s, 0), (ax[1] * 1e3, 50, ax[0] * 1e3), "servo"),
                ((0, 58 * s, 0), (22, 20, 26), "frame"),
            ],
        ),
        mm_link(
            f"{p}_forearm",
            76.7,
            (0, 32 * s, 0),
            (32, 74.5, 40),
            [
                ((0, 22 * s, 0), (ax[1] * 1e3, 50, ax[0] * 1e3), "servo"),
                ((0, 62 * s, 0), (18, 30, 28), "hand"),
            ],
        ),
    ]


def torso_link() -> Link:
    # Mass: MR-old / PEPE m0 = 695.4 g (incl. servos 1, 2, 7, 8 and the controller).
    # CoM: RK-URDF torso CoM (-14.1, 0, -19.9) mm, same torso frame origin.
    # Boxes: MR collision boxes (bioloid-facts §1.3): top 90.5x103x63.5 at (-19, 0, -15),
    # bottom 65x99x43 at (-6.25, 0, -64.8), head 54x33x44 at (-12.2, 0, 35).
    return mm_link(
        "torso",
        695.4,
        (-14.1, 0, -19.9),
        (70, 103, 130),
        [
            ((-19, 0, -15), (90.5, 103, 63.5), "body"),
            ((-6.25, 0, -64.8), (65, 99, 43), "body"),
            ((-12.2, 0, 35), (54, 33, 44), "head"),
        ],
    )


def side_joints(s: int, p: str) -> list[tuple[str, str, str, tuple[float, ...], str, int]]:
    """(joint, parent, child, origin mm, axis, Robotis ID) for one side.

    Offsets: MR-URDF joint positions at its q = 0 (bioloid-facts §1.2), re-zeroed: the arm
    is rotated 90 degrees about the shoulder-pitch axis so that the roll axis points forward,
    which turns the 14 mm forward offset of the roll joint into 14 mm downward.
    """
    r = s < 0
    return [
        (f"{p}_hip_yaw", "torso", f"{p}_hip_bracket", (0, 38.5 * s, -65.5), "z", 7 if r else 8),
        (f"{p}_hip_roll", f"{p}_hip_bracket", f"{p}_hip_block", (0, 0, -50), "x", 9 if r else 10),
        (f"{p}_hip_pitch", f"{p}_hip_block", f"{p}_thigh", (0, 0, 0), "y", 11 if r else 12),
        (f"{p}_knee", f"{p}_thigh", f"{p}_shin", (-14.5, 0, -75), "y", 13 if r else 14),
        (f"{p}_ankle_pitch", f"{p}_shin", f"{p}_ankle_block", (14.5, 0, -71), "y", 15 if r else 16),
        (f"{p}_ankle_roll", f"{p}_ankle_block", f"{p}_foot", (0, 0, 0), "x", 17 if r else 18),
        (
            f"{p}_shoulder_pitch",
            "torso",
            f"{p}_shoulder_bracket",
            (0, 32 * s, 0),
            "y",
            1 if r else 2,
        ),
        (
            f"{p}_shoulder_roll",
            f"{p}_shoulder_bracket",
            f"{p}_upper_arm",
            (0, 44 * s, -14),
            "x",
            3 if r else 4,
        ),
        (f"{p}_elbow", f"{p}_upper_arm", f"{p}_forearm", (0, 67.5 * s, 0), "x", 5 if r else 6),
    ]


def side_frames(s: int, p: str) -> list[tuple[str, str, tuple[float, ...]]]:
    """Fixed operational frames: soles 32.2 mm under the ankle axes; hands 74.5 mm past the
    elbow (PEPE L5 = 74.5 mm, the forearm length of its CoM model)."""
    return [
        (f"{p}_sole", f"{p}_foot", (0, 0, -32.2)),
        (f"{p}_hand", f"{p}_forearm", (0, 74.5 * s, 0)),
    ]


def load_servo_map() -> dict[str, dict]:
    with open(HERE / "servos.toml", "rb") as f:
        return tomllib.load(f)["joints"]


def joint_limits_rad(servo: dict) -> tuple[float, float]:
    """Annex A servo-degree limits mapped into our joint frame: q = sign * (servo - zero)."""
    _, lo_deg, hi_deg = ANNEX_A[servo["id"]]
    zero_deg = (servo["zero_tick"] - 512.0) * DEG_PER_TICK
    a = servo["sign"] * (lo_deg - zero_deg)
    b = servo["sign"] * (hi_deg - zero_deg)
    return math.radians(min(a, b)), math.radians(max(a, b))


MATERIALS = {
    "body": (0.20, 0.22, 0.26, 1.0),
    "head": (0.85, 0.45, 0.10, 1.0),
    "servo": (0.12, 0.12, 0.14, 1.0),
    "frame": (0.75, 0.76, 0.78, 1.0),
    "foot": (0.85, 0.45, 0.10, 1.0),
    "hand": (0.75, 0.76, 0.78, 1.0),
}


AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def build_urdf() -> str:
    servos = load_servo_map()
    links = [torso_link()]
    joints = []
    frames = []
    # Pinocchio orders sibling subtrees by joint name, so the model's joint order is
    # left leg, left arm, right leg, right arm; the file follows the same order.
    for s, p in ((1, "l"), (-1, "r")):
        links += side_links(s, p)
        joints += side_joints(s, p)
        frames += side_frames(s, p)

    lines = [
        '<?xml version="1.0"?>',
        "<!-- Robotis Bioloid Premium (Type A), written by the wbc project.",
        "     Generated by robots/bioloid/make_urdf.py; sources in robots/bioloid/README.md.",
        "     All link frames are parallel to the torso frame at q = 0 (x fwd, y left, z up). -->",
        '<robot name="bioloid">',
    ]
    for name, rgba in MATERIALS.items():
        lines.append(f'  <material name="{name}"><color rgba="{fmt(rgba)}"/></material>')
    for link in links:
        lines.append(link_xml(link))
    for name, parent, child, origin, axis, servo_id in joints:
        servo = servos[name]
        if servo["id"] != servo_id:
            raise ValueError(f"servos.toml: {name} has id {servo['id']}, expected {servo_id}")
        lo, hi = joint_limits_rad(servo)
        lines.append(f'  <joint name="{name}" type="revolute">')
        lines.append(f'    <parent link="{parent}"/>')
        lines.append(f'    <child link="{child}"/>')
        lines.append(f'    <origin xyz="{fmt(o * MM for o in origin)}" rpy="0 0 0"/>')
        lines.append(f'    <axis xyz="{fmt(AXES[axis])}"/>')
        lines.append(
            f'    <limit lower="{lo:.9f}" upper="{hi:.9f}" effort="{STALL_TORQUE}" '
            f'velocity="{NO_LOAD_SPEED:.6f}"/>'
        )
        lines.append("  </joint>")
    for name, parent, origin in frames:
        lines.append(f"  <link name={quoteattr(name)}/>")
        lines.append(f'  <joint name="{name}_fixed" type="fixed">')
        lines.append(f'    <parent link="{parent}"/>')
        lines.append(f'    <child link="{name}"/>')
        lines.append(f'    <origin xyz="{fmt(o * MM for o in origin)}" rpy="0 0 0"/>')
        lines.append("  </joint>")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def main() -> int:
    text = build_urdf()
    out = HERE / "bioloid.urdf"
    if "--check" in sys.argv:
        return 0 if out.read_text() == text else 1
    out.write_text(text)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
