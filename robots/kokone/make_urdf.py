"""Generate ``kokone.urdf`` (Kokone, 2009, 22 DOF, hobby PWM servos) from the thesis's numbers.

Run ``python robots/kokone/make_urdf.py`` to rewrite the URDF (``--check``: write nothing, exit 1
if the committed file differs); ``tests/test_kokone.py`` checks that the committed file equals
this script's output. Sources: "the thesis" is V. E. González Hernández, *Diseño y control de
Kokone, un pequeño robot humanoide*, CINVESTAV 2009 (the project's notes:
``../shared/reference/kokone-thesis.md``). ``robots/kokone/README.md`` explains every number.

* **Legs: exact.** Each leg is the thesis's DH chain (Table 4.1, eqs. 4.16-4.27, lengths in cm)
  with its base at ±2.25 cm from the hip frame O_c (eqs. 4.33/4.34). The generator evaluates the
  DH chain at the straight-leg pose θ0 = (90°, 90°, 90°, 0, 0, 0) and writes every joint as a
  pure translation with its axis along ±x, ±y or ±z of the torso (it checks that the DH axes
  are so aligned there). Our joint angle is ``q = sign · (θ - θ0)`` (:data:`DH_SIGN`,
  :data:`DH_ZERO_DEG`), so the URDF reproduces the DH forward kinematics exactly.
* **Arms, torso, head: ESTIMATES** (the thesis never models them). Sizes from its totals (37 cm,
  ~1.2 kg, 22 × 16.4 g servos, aluminium profiles) and its figures; each number below says why.

Conventions (as the Bioloid model): root link ``torso`` at O_c, the hip centre (intersection
of the hip roll/yaw axes, midway between the legs), x forward, y left, z up; every link frame
parallel to the torso at q = 0; axes +x (roll), +y (pitch), +z (yaw) on both sides; knee
flexion positive. q = 0: legs straight (the thesis's θ0), arms hanging, head forward.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from wbc.urdf_writer import Link, fmt, link_xml

HERE = Path(__file__).resolve().parent
CM = 1e-2
G = 1e-3  # grams -> kg

# --- Servo: Blue-Bird BMS-380MAX, thesis Table 3.1 --------------------------------------
SERVO_MASS_G = 16.4  # Table 3.1 "Peso 16.4 gr."
SERVO_TORQUE = 4.2 * 9.80665 / 100.0  # 4.2 kg·cm at 4.8 V -> 0.412 N·m
SERVO_SPEED = math.radians(60.0) / 0.16  # 0.16 s/60° at 4.8 V -> 6.545 rad/s
# ESTIMATE: a micro servo of this class measures about 2.9 x 1.3 x 3.0 cm (not in the thesis;
# used only for the visual/collision boxes and the inertia of the servo-holder assemblies).
SERVO_BOX_CM = (2.9, 1.3, 3.0)

# --- Legs: thesis Table 4.1 (both legs; lengths cm): (d, a, alpha deg) ------------------
DH_TABLE = (
    (0.0, 0.0, 90.0),  # 1 hip roll  (θ1 + 90°)
    (-4.3, 0.0, 90.0),  # 2 hip yaw   (θ2 + 90°)
    (0.0, -6.1, 0.0),  # 3 hip pitch (θ3 + 90°)
    (0.0, -6.1, 0.0),  # 4 knee
    (0.0, -3.3, 90.0),  # 5 ankle pitch
    (0.0, -2.0, 0.0),  # 6 ankle roll
)
LEG_BASE_Y = 2.25  # eqs. 4.33/4.34: leg bases at ±2.25 cm along the hip frame's y_c
HIP_HEIGHT = 21.8  # A_mc of the straight stance; = 4.3 + 6.1 + 6.1 + 3.3 + 2.0
#: the straight-leg pose in the thesis's DH angles (deg; the +90° offsets included)
DH_ZERO_DEG = (90.0, 90.0, 90.0, 0.0, 0.0, 0.0)
#: Table 4.3 ranges of the DH angles (deg), both legs
DH_RANGE_DEG = ((45, 135), (45, 135), (45, 135), (-90, 0), (-45, 45), (-45, 45))
LEG_JOINTS = ("hip_roll", "hip_yaw", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
# O_c in world: x_c up, y_c = -y, z_c forward (A_mc of the thesis, without the height)
R_MC = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])


def dh(theta_deg: float, d: float, a: float, alpha_deg: float) -> np.ndarray:
    """Standard DH transform (thesis eq. 4.15)."""
    t, al = math.radians(theta_deg), math.radians(alpha_deg)
    c, s, ca, sa = math.cos(t), math.sin(t), math.cos(al), math.sin(al)
    return np.array(
        [[c, -ca * s, sa * s, a * c], [s, ca * c, -sa * c, a * s], [0, sa, ca, d], [0, 0, 0, 1.0]]
    )


def leg_frames(side: int, theta_deg=DH_ZERO_DEG) -> list[np.ndarray]:
    """Frames 0..6 of one leg in the torso frame (cm); side +1 left, -1 right.

    The thesis's right leg has its base at y_c = +2.25 (world y = -2.25)."""
    T = np.eye(4)
    T[:3, :3] = R_MC
    base = np.eye(4)
    base[1, 3] = -side * LEG_BASE_Y  # along y_c = -y
    T = T @ base
    frames = [T]
    for th, (d, a, al) in zip(theta_deg, DH_TABLE, strict=True):
        T = T @ dh(th, d, a, al)
        frames.append(T)
    return frames


def _aligned_axis(z: np.ndarray) -> tuple[str, int]:
    """('x'|'y'|'z', ±1) for a DH joint axis that must lie along a torso axis."""
    k = int(np.argmax(np.abs(z)))
    if abs(abs(z[k]) - 1.0) > 1e-12:
        raise AssertionError(f"DH axis {z} is not aligned with a torso axis at θ0")
    return "xyz"[k], int(np.sign(z[k]))


def _leg_axes() -> tuple[tuple[str, ...], tuple[int, ...]]:
    frames = leg_frames(1)
    axes, signs = zip(*(_aligned_axis(frames[i][:3, 2]) for i in range(6)), strict=True)
    return axes, signs


#: URDF axis letter of each leg joint and the sign s_i with URDF axis = s_i · z_{i-1}
LEG_AXES, DH_SIGN = _leg_axes()


def dh_to_q(theta_deg) -> np.ndarray:
    """Our leg joint angles (rad, thesis joint order 1..6) from the thesis's DH angles (deg)."""
    th = np.asarray(theta_deg, dtype=float)
    return np.radians(np.asarray(DH_SIGN) * (th - np.asarray(DH_ZERO_DEG)))


def q_to_dh(q) -> np.ndarray:
    """The thesis's DH angles (deg) from our leg joint angles (rad, joint order 1..6)."""
    return np.asarray(DH_ZERO_DEG) + np.asarray(DH_SIGN) * np.degrees(np.asarray(q, dtype=float))


def leg_limits_rad() -> list[tuple[float, float]]:
    """Table 4.3 ranges converted to our joint angles."""
    out = []
    for i, (lo, hi) in enumerate(DH_RANGE_DEG):
        a, b = (DH_SIGN[i] * math.radians(v - DH_ZERO_DEG[i]) for v in (lo, hi))
        out.append((min(a, b) + 0.0, max(a, b) + 0.0))  # + 0.0: no "-0" in the file
    return out


# --- Masses (ESTIMATES; total 1.2 kg, thesis §3.5) --------------------------------------
# Each leg link carries the servo of the next joint plus its aluminium holder ("sujeta-servo",
# E1) or U piece. ESTIMATE: an E1 holder or U piece of 1.5 mm aluminium profile ~ 14-20 g.
# The first servo of each limb (hip roll, shoulder pitch, head pan) sits in the torso.
# Totals: leg 215 g, arm 92 g, head 52 g, torso 534 g -> 2·215 + 2·92 + 52 + 534 = 1200 g.
TOTAL_MASS_G = 1200.0  # thesis: "aproximadamente 1.2 kg"
HEIGHT_CM = 37.0  # thesis: 37 cm


def cm_link(name: str, mass_g: float, com_cm, inertia_box_cm, boxes) -> Link:
    """A link from grams and cm: CoM, the solid box of its inertia, its (centre, size, material)
    boxes, all in the link frame."""
    return Link.scaled(name, mass_g * G, com_cm, inertia_box_cm, boxes, CM)


def leg_links(p: str) -> list[Link]:
    """Links of one leg, each in its joint's frame (origin on the joint axis, torso-parallel)."""
    sx, sy, sz = SERVO_BOX_CM
    return [
        # after hip roll (axes 1 and 2 intersect): the yaw servo + holder, ESTIMATE 30 g
        cm_link(
            f"{p}_hip_roll_link",
            30.0,
            (0, 0, -1.0),
            (3, 3, 3),
            [((0, 0, -1.0), (3, 3, 2.5), "servo")],
        ),
        # after hip yaw: the hip-pitch servo + U piece down to the pitch axis 4.3 cm below, 35 g
        cm_link(
            f"{p}_hip_yaw_link",
            35.0,
            (0, 0, -3.3),
            (sx, 3, 4.3),
            [((0, 0, -3.3), (sx, sz, sy + 1.0), "servo"), ((0, 0, -1.6), (2.0, 2.6, 0.3), "frame")],
        ),
        # thigh: knee servo + holder + profile (6.1 cm), 40 g
        cm_link(
            f"{p}_thigh",
            40.0,
            (0, 0, -3.8),
            (3, 3, 6.1),
            [((0, 0, -3.05), (2.0, 2.8, 6.1), "frame"), ((0, 0, -5.0), (sx, sz, sy), "servo")],
        ),
        # shank: ankle-pitch servo + holder + profile (6.1 cm), 40 g
        cm_link(
            f"{p}_shank",
            40.0,
            (0, 0, -3.8),
            (3, 3, 6.1),
            [((0, 0, -3.05), (2.0, 2.8, 6.1), "frame"), ((0, 0, -5.0), (sx, sz, sy), "servo")],
        ),
        # ankle: ankle-roll servo + U piece (3.3 cm), 35 g
        cm_link(
            f"{p}_ankle",
            35.0,
            (0, 0, -2.3),
            (3, 3, 3.3),
            [((0, 0, -2.3), (sy, sx, sz), "servo")],
        ),
        # foot: bracket + sole plate (ESTIMATE 7 x 4 cm, 0.3 cm thick), 35 g
        cm_link(
            f"{p}_foot",
            35.0,
            (0, 0, -1.5),
            (7.0, 4.0, 1.0),
            [((0, 0, -1.85), (7.0, 4.0, 0.3), "foot"), ((0, 0, -0.8), (2.0, 2.8, 1.6), "frame")],
        ),
    ]


# Arm (ESTIMATES): shoulder pitch (y) at the top of the torso, shoulder roll (x) 2.5 cm further
# out, then two elbow joints ("2 DOF at the elbow", E6): elbow yaw (z, along the upper arm)
# and elbow pitch (y), 6 cm below the roll axis; the hand 6 cm below the elbow. Arm length
# 12 cm: the hands hang a little above the hips (the robot's photos, Fig. 3.17/5.6).
SHOULDER = (0.0, 5.0, 9.0)  # ESTIMATE: torso 8 cm wide + servo; shoulders 9 cm above the hips
UPPER_ARM = 6.0
FOREARM = 6.0
NECK = (0.0, 0.0, 9.5)  # ESTIMATE: head pan on the torso's top plate, 9.5 cm above the hips
HEAD_TILT = 2.0  # ESTIMATE: tilt axis above the pan servo
# torso: hip (z=0) to the top plate (9.5 cm); head top at 37 - 21.8 = 15.2 cm above the hips
HEAD_BOX_CM = (4.0, 5.0, 4.5)  # ESTIMATE: a camera-ready head piece
HEAD_CENTRE_Z = HEIGHT_CM - HIP_HEIGHT - NECK[2] - HEAD_TILT - HEAD_BOX_CM[2] / 2  # 1.45 cm


def arm_links(p: str, s: int) -> list[Link]:
    sx, sy, sz = SERVO_BOX_CM
    return [
        cm_link(
            f"{p}_shoulder",
            25.0,
            (0, 1.2 * s, 0),
            (3, 3, 3),
            [((0, 1.2 * s, 0), (sy, sz, sx), "servo")],
        ),
        cm_link(
            f"{p}_upper_arm",
            25.0,
            (0, 0, -3.0),
            (2.5, 2.5, 6.0),
            [((0, 0, -2.5), (2.0, 2.0, 5.0), "frame")],
        ),
        cm_link(
            f"{p}_elbow_link", 25.0, (0, 0, 0), (3, 3, 3), [((0, 0, 0), (sx, sy, sz), "servo")]
        ),
        cm_link(
            f"{p}_forearm",
            17.0,
            (0, 0, -3.0),
            (2.0, 2.0, 6.0),
            [((0, 0, -3.5), (1.6, 1.6, 5.0), "hand")],
        ),
    ]


def torso_link(limb_mass_g: float) -> Link:
    """The torso: back + chest plates (E-body), the SSC-32 board on the back, cables, and the
    servos of the hip roll (2), shoulder pitch (2) and head pan (1) joints. Its mass is what
    the estimated limbs leave of the thesis's 1.2 kg."""
    return cm_link(
        "torso",
        TOTAL_MASS_G - limb_mass_g,
        (-0.5, 0, 5.0),  # ESTIMATE: the board on the back moves the CoM ~0.5 cm backward
        (5.0, 8.0, 9.5),
        [
            ((0, 0, 5.0), (4.5, 8.0, 9.0), "body"),  # chest + back
            ((-2.8, 0, 6.0), (0.6, 5.8, 7.6), "board"),  # SSC-32 (2.3 x 3.0 in) on the back
            ((0, 0, 0.5), (3.0, 7.5, 1.5), "servo"),  # hip roll servos
        ],
    )


def head_links() -> list[Link]:
    sx, sy, sz = SERVO_BOX_CM
    return [
        cm_link("neck", 22.0, (0, 0, 1.0), (3, 3, 3), [((0, 0, 1.0), (sx, sy, sz), "servo")]),
        cm_link(
            "head",
            30.0,
            (0, 0, HEAD_CENTRE_Z),
            HEAD_BOX_CM,
            [((0.3, 0, HEAD_CENTRE_Z), HEAD_BOX_CM, "head")],
        ),
    ]


def all_joints() -> list[tuple[str, str, str, tuple[float, ...], str, tuple[float, float]]]:
    """(joint, parent, child, origin cm in the parent frame, axis, (lo, hi) rad)."""
    out = []
    limits = leg_limits_rad()
    for s, p in ((1, "l"), (-1, "r")):
        frames = leg_frames(s)
        parent, prev = "torso", np.zeros(3)
        links = [link.name for link in leg_links(p)]
        for i, name in enumerate(LEG_JOINTS):
            origin = frames[i][:3, 3]
            out.append(
                (f"{p}_{name}", parent, links[i], tuple(origin - prev), LEG_AXES[i], limits[i])
            )
            parent, prev = links[i], origin
        # arm (ESTIMATE limits: the SSC-32 pulse range 500-2500 µs at 0.075°/µs = ±75°; the
        # shoulder roll stops at the torso side, the elbow bends one way)
        r75 = math.radians(75.0)
        roll = (math.radians(-5.0), r75) if s > 0 else (-r75, math.radians(5.0))
        arm = [
            (
                f"{p}_shoulder_pitch",
                "torso",
                f"{p}_shoulder",
                (SHOULDER[0], s * SHOULDER[1], SHOULDER[2]),
                "y",
                (-r75, r75),
            ),
            (f"{p}_shoulder_roll", f"{p}_shoulder", f"{p}_upper_arm", (0, 2.5 * s, 0), "x", roll),
            (
                f"{p}_elbow_yaw",
                f"{p}_upper_arm",
                f"{p}_elbow_link",
                (0, 0, -UPPER_ARM),
                "z",
                (-r75, r75),
            ),
            (f"{p}_elbow_pitch", f"{p}_elbow_link", f"{p}_forearm", (0, 0, 0), "y", (-r75, 0.0)),
        ]
        out += arm
    r75 = math.radians(75.0)
    out.append(("head_yaw", "torso", "neck", NECK, "z", (-r75, r75)))
    out.append(
        (
            "head_pitch",
            "neck",
            "head",
            (0, 0, HEAD_TILT),
            "y",
            (math.radians(-30), math.radians(45)),
        )
    )
    return out


def fixed_frames() -> list[tuple[str, str, tuple[float, ...]]]:
    """Operational frames: soles on the sole surface 2.0 cm under the ankle-roll axis
    (Table 4.1, a6), hands at the end of the forearm."""
    out = []
    for s, p in ((1, "l"), (-1, "r")):
        frames = leg_frames(s)
        out.append((f"{p}_sole", f"{p}_foot", tuple(frames[6][:3, 3] - frames[5][:3, 3])))
        out.append((f"{p}_hand", f"{p}_forearm", (0, 0, -FOREARM)))
    return out


def all_links() -> list[Link]:
    limbs = [
        *leg_links("l"),
        *arm_links("l", 1),
        *leg_links("r"),
        *arm_links("r", -1),
        *head_links(),
    ]
    return [torso_link(sum(link.mass for link in limbs) / G), *limbs]


MATERIALS = {
    "body": (0.72, 0.74, 0.78, 1.0),
    "board": (0.10, 0.35, 0.15, 1.0),
    "head": (0.72, 0.74, 0.78, 1.0),
    "servo": (0.10, 0.10, 0.12, 1.0),
    "frame": (0.80, 0.81, 0.83, 1.0),
    "foot": (0.80, 0.81, 0.83, 1.0),
    "hand": (0.80, 0.81, 0.83, 1.0),
}
AXES = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}
# collision boxes 1 mm inside the visual ones: the feet (5 mm apart) then keep the
# self-collision margin (5 mm) with 2 mm to spare
COLLISION_INSET = 0.001  # m, each side


def build_urdf() -> str:
    out = [
        '<?xml version="1.0"?>',
        "<!-- Kokone (González Hernández 2009), written by the wbc project.",
        "     Generated by robots/kokone/make_urdf.py; sources in robots/kokone/README.md.",
        "     Legs exact from the thesis's DH table (Table 4.1); arms, torso, head, masses are",
        "     estimates. Lengths in m. All link frames are parallel to the torso at q = 0. -->",
        '<robot name="kokone">',
    ]
    for name, rgba in MATERIALS.items():
        out.append(f'  <material name="{name}"><color rgba="{fmt(rgba)}"/></material>')
    out += [link_xml(link, COLLISION_INSET) for link in all_links()]
    for joint, parent, child, origin, axis, (lo, hi) in all_joints():
        out += [
            f'  <joint name="{joint}" type="revolute">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{child}"/>',
            f'    <origin xyz="{fmt(v * CM for v in origin)}" rpy="0 0 0"/>',
            f'    <axis xyz="{AXES[axis]}"/>',
            f'    <limit lower="{lo:.12g}" upper="{hi:.12g}" effort="{SERVO_TORQUE:.6g}" '
            f'velocity="{SERVO_SPEED:.6g}"/>',
            "  </joint>",
        ]
    for frame, parent, origin in fixed_frames():
        out += [
            f'  <link name="{frame}"/>',
            f'  <joint name="{frame}_fixed" type="fixed">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{frame}"/>',
            f'    <origin xyz="{fmt(v * CM for v in origin)}" rpy="0 0 0"/>',
            "  </joint>",
        ]
    out.append("</robot>")
    return "\n".join(out) + "\n"


# --- SSC-32 servo map (ESTIMATES where marked) -----------------------------------------
US_PER_DEG = 1.0 / 0.075  # thesis §4.6.2: 0.075° per µs (printed "per 1 ms") -> 13.33 µs/°
US_PER_RAD = US_PER_DEG * 180.0 / math.pi  # 763.94 µs/rad
PULSE_MIN, PULSE_MAX = 500, 2500  # SSC-32 range (thesis §3.4)
# ESTIMATE: the thesis gives no channel list. One bank (0-15) per side of the board's two
# banks: right leg 0-5, right arm 6-9, head 10-11; left leg 16-21, left arm 22-25.
CHANNEL_BASE = {"r": 0, "l": 16}
# ESTIMATE (calibrate on the robot): the left limbs are mirror copies (thesis §3.5.2) holding
# the same servo, so a pitch servo (lateral axis) turns the other way on the left side; roll
# and yaw servos (axes in the mirror plane) turn the same way.
PITCH_LIKE = ("hip_pitch", "knee", "ankle_pitch", "shoulder_pitch", "elbow_pitch")


def servo_channels() -> list[tuple[str, int, int, float]]:
    """(joint, channel, sign, pulse at q = 0) for the 22 joints.

    The pulse at q = 0 centres each joint's range in the board's pulse range,
    ``1500 - sign · US_PER_RAD · (lo + hi) / 2``: the knee (0..90°) gets 900 µs, so its range
    maps to 900..2100 µs instead of running past 2500 µs. (The thesis stored measured
    "initial positions" per motor instead: calibrate these on the real robot.)"""
    limits = {j[0]: j[5] for j in all_joints()}
    out = []
    for p in ("r", "l"):
        names = [f"{p}_{n}" for n in LEG_JOINTS]
        names += [f"{p}_{n}" for n in ("shoulder_pitch", "shoulder_roll", "elbow_yaw")]
        names += [f"{p}_elbow_pitch"]
        if p == "r":
            names += ["head_yaw", "head_pitch"]
        for k, name in enumerate(names):
            sign = -1 if p == "l" and name[2:] in PITCH_LIKE else 1
            lo, hi = limits[name]
            zero = round(1500.0 - sign * US_PER_RAD * 0.5 * (lo + hi), 3)
            out.append((name, CHANNEL_BASE[p] + k, sign, zero))
    return out


def build_ssc32_map() -> str:
    lines = [
        "# Kokone's SSC-32 servo map, generated by make_urdf.py (README.md section 5).",
        "# pulse (µs) = center_us + sign * us_per_rad * q (rad); the board takes 500..2500 µs.",
        "# us_per_rad: the thesis's 0.075 deg per µs. Channels, signs and centres are ESTIMATES",
        "# (the thesis lists none): calibrate them on the robot.",
        "",
        "[bus]",
        "baudrate = 115200  # thesis Table 3.2: 115.2 kbaud, 8N1, XON/XOFF",
        "",
        "[joints]",
    ]
    for name, ch, sign, zero in servo_channels():
        lines.append(
            f"{name:<16} = {{ channel = {ch:2d}, sign = {sign:2d}, center_us = {zero:g}, "
            f"us_per_rad = {US_PER_RAD:.4f} }}"
        )
    return "\n".join(lines) + "\n"


# --- Named poses (poses.toml, radians) ----------------------------------------------------
def named_poses() -> dict[str, dict[str, float]]:
    """``straight`` (θ0), ``crouch`` (hip lowered 1 cm to 20.8, Example 3's height, feet flat
    under the hips: hip pitch to ankle pitch 20.8 - 4.3 - 5.3 = 11.2 = 2 · 6.1 cos a) and
    ``example3`` (Table 4.2's angles), in our joint angles."""
    a = math.acos((HIP_HEIGHT - 1.0 - 4.3 - 5.3) / (2 * 6.1))
    crouch = dict(
        zip(
            LEG_JOINTS,
            dh_to_q(np.array(DH_ZERO_DEG) + np.degrees([0, 0, a, -2 * a, a, 0])),
            strict=True,
        )
    )
    ex3 = {
        "r": dh_to_q((90, 90, 134, -64, 20, 0)),
        "l": dh_to_q((90, 90, 113, -46, 23, 0)),
    }
    poses: dict[str, dict[str, float]] = {"straight": {}, "crouch": {}, "example3": {}}
    for p in ("l", "r"):
        for k, name in enumerate(LEG_JOINTS):
            if abs(crouch[name]) > 0:
                poses["crouch"][f"{p}_{name}"] = float(crouch[name])
            if abs(ex3[p][k]) > 0:
                poses["example3"][f"{p}_{name}"] = float(ex3[p][k])
    return poses


def build_poses() -> str:
    lines = [
        "# Kokone's named poses (radians of our joints; joints not listed are 0), generated by",
        "# make_urdf.py (README.md section 4). straight: theta = (90, 90, 90, 0, 0, 0) deg;",
        "# crouch: the hip 1 cm lower (20.8 cm), feet flat under the hips (robot.toml: stand);",
        "# example3: the thesis's Table 4.2 (right foot lifted 1.08 cm, 2.15 cm forward).",
    ]
    for name, pose in named_poses().items():
        lines += ["", f"[poses.{name}]"]
        lines += [f"{j} = {v!r}" for j, v in pose.items()]
    return "\n".join(lines) + "\n"


def main() -> int:
    outputs = {
        HERE / "kokone.urdf": build_urdf(),
        HERE / "ssc32.toml": build_ssc32_map(),
        HERE / "poses.toml": build_poses(),
    }
    if "--check" in sys.argv[1:]:
        ok = True
        for path, text in outputs.items():
            same = path.is_file() and path.read_text() == text
            ok &= same
            print(f"{path}: {'up to date' if same else 'DIFFERS from make_urdf.py output'}")
        return 0 if ok else 1
    for path, text in outputs.items():
        path.write_text(text)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
