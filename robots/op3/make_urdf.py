"""Generate ``op3.urdf``, ``servos.toml`` and ``poses.toml`` (ROBOTIS OP3) from ROBOTIS's files.

Run ``python robots/op3/make_urdf.py`` to rewrite them; ``--check`` writes nothing and exits 1
if a committed file differs from this script's output (``tests/test_op3.py`` checks it too).

Inputs, all beside this script (``robots/op3/README.md`` gives every number's source):

* ``op3_description/urdf/*.xacro``: ROBOTIS's official description (ROBOTIS-OP3-Common
  0780e54, Apache-2.0, ``LICENSE``), copied unchanged. This script reads it as XML (no ROS,
  no ``xacro`` package): joint names, parents, origins and axes from the ``structure`` files,
  masses, CoMs and full inertia tensors from ``robotis_op3.inertia.xacro``, the mesh of each
  link from ``robotis_op3.visuals.xacro``.
* ``mesh_bounds.md``: the bounding box of every mesh, measured from ROBOTIS's STL files; each
  becomes the link's visual and collision box. Six meshes are missing there: their links'
  boxes are ESTIMATES below.
* The joint limits are ROBOTIS's ``op3_kinematics_dynamics.cpp`` (``JOINT_LIMITS``): the
  xacro files give every joint ±0.9π, a placeholder.

Servo IDs, directions and zero ticks are ROBOTIS-OP3 ``op3_manager/config/OP3.robot`` and
the framework's ``XM-430.device`` (``value_of_0_radian_position = 2048``): the framework
writes a joint angle to its servo unchanged, so every sign is +1 and every zero tick 2048 in
ROBOTIS's (kept) joint axes.
"""

from __future__ import annotations

import math
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from wbc.urdf_writer import Link, fmt, link_xml

HERE = Path(__file__).resolve().parent
XACRO = HERE / "op3_description" / "urdf"
NS = "{http://ros.org/wiki/xacro}"
MM = 1e-3

# --- Actuator: 20 x XM430-W350-R (ROBOTIS e-Manual, XM430-W350 specifications) ---------------
STALL_TORQUE = 4.1  # N·m at 12.0 V (2.3 A)
NO_LOAD_SPEED = 46.0 * 2.0 * math.pi / 60.0  # 46 rev/min at 12.0 V -> rad/s

# --- Joint limits: ROBOTIS-OP3 op3_kinematics_dynamics.cpp, (axis, min, max) in units of pi,
# about the axis given there (equal to the xacro's axis for every joint: checked below).
JOINT_LIMITS = {
    "head_pan": ((0, 0, 1), -0.5, 0.5),
    "head_tilt": ((0, -1, 0), -0.5, 0.5),
    "r_sho_pitch": ((0, -1, 0), -0.5, 0.5),
    "r_sho_roll": ((-1, 0, 0), -0.5, 0.3),
    "r_el": ((1, 0, 0), -0.5, 0.5),
    "l_sho_pitch": ((0, 1, 0), -0.5, 0.5),
    "l_sho_roll": ((-1, 0, 0), -0.3, 0.5),
    "l_el": ((1, 0, 0), -0.5, 0.5),
    "r_hip_yaw": ((0, 0, -1), -0.45, 0.45),
    "r_hip_roll": ((-1, 0, 0), -0.3, 0.3),
    "r_hip_pitch": ((0, -1, 0), -0.4, 0.4),
    "r_knee": ((0, -1, 0), -0.7, 0.1),
    "r_ank_pitch": ((0, 1, 0), -0.45, 0.45),
    "r_ank_roll": ((1, 0, 0), -0.45, 0.45),
    "l_hip_yaw": ((0, 0, -1), -0.45, 0.45),
    "l_hip_roll": ((-1, 0, 0), -0.3, 0.3),
    "l_hip_pitch": ((0, 1, 0), -0.4, 0.4),
    "l_knee": ((0, 1, 0), -0.1, 0.7),
    "l_ank_pitch": ((0, -1, 0), -0.45, 0.45),
    "l_ank_roll": ((1, 0, 0), -0.45, 0.45),
}

# --- Servo IDs: ROBOTIS-OP3 op3_manager/config/OP3.robot (all XM-430, Protocol 2.0, one bus
# /dev/ttyUSB0 at 2000000 baud).
SERVO_IDS = {
    "r_sho_pitch": 1, "l_sho_pitch": 2, "r_sho_roll": 3, "l_sho_roll": 4, "r_el": 5, "l_el": 6,
    "r_hip_yaw": 7, "l_hip_yaw": 8, "r_hip_roll": 9, "l_hip_roll": 10, "r_hip_pitch": 11,
    "l_hip_pitch": 12, "r_knee": 13, "l_knee": 14, "r_ank_pitch": 15, "l_ank_pitch": 16,
    "r_ank_roll": 17, "l_ank_roll": 18, "head_pan": 19, "head_tilt": 20,
}  # fmt: skip
BAUDRATE = 2_000_000  # OP3.robot [port info]
ZERO_TICK = 2048  # XM-430.device value_of_0_radian_position

# --- Position gains: ROBOTIS-OP3 op3_manager/config/dxl_init_OP3.yaml (the rest: the XM430's
# factory values P 800, I 0, D 0, e-Manual control table).
GAINS = {
    "hip_yaw": (1000, 1000, 250), "hip_roll": (1000, 1000, 250),
    "hip_pitch": (1000, 1000, 250), "knee": (1000, 500, 150),
    "ank_pitch": (1000, 250, 50), "ank_roll": (1000, 250, 50),
}  # fmt: skip
# The project's leg P gain, written in place of dxl_init's 1000 (its I and D kept): measured in
# the simulator's XM430 law (benchmarks/op3.md section 8), ROBOTIS's P 1000 (23.6 N·m/rad) let
# the softest randomised plants (x0.5) fall or rock at rest and fast_wb travel 1.25 of its
# plan; P 2000 (47.1 N·m/rad): 50/50 randomised models up, every walk within 0.95-1.07.
LEG_P_GAIN = 2000

# --- Boxes of the six links whose meshes mesh_bounds.md lacks: ESTIMATES (mm, link frame,
# left side; the right side mirrors y). README section 3 explains each.
ESTIMATED_BOXES = {
    # torso: between the hips (z = 0) and the head pan servo (z = 136.5), inside the
    # shoulder servos (y = ±60): 80 deep around its CoM x (-15), 100 wide, z 10..130
    "body_link": ((-15.0, 0.0, 70.0), (80.0, 100.0, 120.0)),
    # the two-servo hip block (roll + pitch XM430s, each 28.5 x 46.5 x 34 mm) between the roll
    # axis (origin) and the pitch axis (24.1, 19, 0): same part as the ankle block, flipped
    "l_hip_roll_link": ((12.0, 0.0, -12.0), (60.0, 40.0, 46.0)),
    "l_ank_pitch_link": ((-12.0, -19.0, 12.0), (60.0, 40.0, 46.0)),
}
# Collision boxes that differ from the mesh boxes (mm, link frame, left side; README section
# 3): the mesh boxes of the hip yaw bracket and the foot reach past the next joint's axis and
# overlap the thigh / shin at every pose, though the parts themselves interleave. Collision
# keeps the bracket's top plate (12 mm under its top) and the sole plate (10 mm thick).
COLLISION_TRIM_Z = {"l_hip_yaw_link": (-12.0, 0.0), "l_ank_roll_link": (-30.5, -20.5)}
COLLISION_INSET = 0.001  # m, collision boxes 1 mm inside the visual ones (as Kokone's)
MATERIALS = {"grey": (0.6, 0.6, 0.6, 1.0), "dark": (0.25, 0.25, 0.28, 1.0)}

# --- Operational frames (ROBOTIS op3_kinematics_dynamics.cpp "leg end" / "arm end").
# The sole frames sit on the sole surface (30.5 mm under the ankle roll axis, as ROBOTIS's
# leg end) at the centre of the foot's mesh box (ll6/rl6: x -39.5..87.5, y -27.5..52.5 mm on
# the left), so the foot rectangle of robot.toml is centred on them.
FOOT_BOX_MM = ((-39.5, -27.5), (87.5, 52.5))  # ll6 min x,y / max x,y (mesh_bounds.md)


def _number(text: str) -> float:
    """A xacro attribute value: a number or ``${expr}`` of ``pi``."""
    text = text.strip()
    m = re.fullmatch(r"\$\{(.*)\}", text)
    if m:
        return float(eval(m.group(1), {"__builtins__": {}}, {"pi": math.pi}))
    return float(text)


def _vec(text: str) -> tuple[float, float, float]:
    x, y, z = (_number(v) for v in text.split())
    return (x, y, z)


def read_joints() -> list[dict]:
    """Every joint of the structure files: name, type, parent, child, origin, axis."""
    joints = []
    for part in ("rleg", "lleg", "rarm", "larm", "head"):
        root = ET.parse(XACRO / f"robotis_op3.structure.{part}.xacro").getroot()
        for macro in root.iter(f"{NS}macro"):
            for j in macro.iter("joint"):
                origin = j.find("origin")
                axis = j.find("axis")
                parent = j.find("parent").get("link").replace("${parent}", "body_link")
                joints.append(
                    {
                        "name": j.get("name"),
                        "type": j.get("type"),
                        "parent": parent,
                        "child": j.find("child").get("link"),
                        "xyz": _vec(origin.get("xyz")),
                        "rpy": _vec(origin.get("rpy", "0 0 0")),
                        "axis": _vec(axis.get("xyz")) if axis is not None else None,
                    }
                )
    return joints


def read_inertias() -> dict[str, tuple]:
    """``insert_inertia_<link>`` macros: link -> (mass, com, (ixx, iyy, izz), (ixy, ixz, iyz))."""
    root = ET.parse(XACRO / "robotis_op3.inertia.xacro").getroot()
    out = {}
    for macro in root.iter(f"{NS}macro"):
        link = macro.get("name").removeprefix("insert_inertia_")
        i = macro.find("inertia")
        out[link] = (
            _number(macro.find("mass").get("value")),
            _vec(macro.find("origin").get("xyz")),
            tuple(_number(i.get(k)) for k in ("ixx", "iyy", "izz")),
            tuple(_number(i.get(k)) for k in ("ixy", "ixz", "iyz")),
        )
    return out


def read_meshes() -> dict[str, str]:
    """``insert_mesh_<link>`` macros: link -> mesh file name (e.g. ``ll6.stl``)."""
    root = ET.parse(XACRO / "robotis_op3.visuals.xacro").getroot()
    out = {}
    for macro in root.iter(f"{NS}macro"):
        mesh = macro.find("geometry/mesh")
        out[macro.get("name").removeprefix("insert_mesh_")] = Path(mesh.get("filename")).name
    return out


def read_mesh_bounds() -> dict[str, tuple[tuple[float, ...], tuple[float, ...]]]:
    """``mesh_bounds.md``'s table: mesh -> (min xyz, max xyz) in mm."""
    out = {}
    for line in (HERE / "mesh_bounds.md").read_text().splitlines():
        m = re.fullmatch(r"\| (\w+\.stl) \| ([-\d., ]+) \| ([-\d., ]+) \|", line.strip())
        if m:
            lo = tuple(float(v) for v in m.group(2).split(","))
            hi = tuple(float(v) for v in m.group(3).split(","))
            out[m.group(1)] = (lo, hi)
    return out


def link_box(link: str, meshes: dict, bounds: dict) -> tuple[tuple, tuple]:
    """(centre, size) in mm of a link's box: its mesh's bounds, else the estimate."""
    mesh = meshes[link]
    if mesh in bounds:
        lo, hi = bounds[mesh]
        pairs = list(zip(lo, hi, strict=True))
        return tuple((a + b) / 2 for a, b in pairs), tuple(b - a for a, b in pairs)
    key = link.replace("r_", "l_", 1) if link.startswith("r_") else link
    centre, size = ESTIMATED_BOXES[key]
    if link.startswith("r_"):
        centre = (centre[0], -centre[1], centre[2])
    return centre, size


def all_links() -> list[Link]:
    inertias, meshes, bounds = read_inertias(), read_meshes(), read_mesh_bounds()
    links = []
    for name, (mass, com, diag, products) in inertias.items():
        centre, size = link_box(name, meshes, bounds)
        material = "dark" if name == "body_link" else "grey"
        box = (tuple(v * MM for v in centre), tuple(v * MM for v in size), material)
        collision = None
        key = name.replace("r_", "l_", 1) if name.startswith("r_") else name
        if key in COLLISION_TRIM_Z:
            z0, z1 = COLLISION_TRIM_Z[key]
            c = (centre[0], centre[1], (z0 + z1) / 2)
            collision = [(tuple(v * MM for v in c), (size[0] * MM, size[1] * MM, (z1 - z0) * MM))]
        links.append(Link(name, mass, com, diag, [box], products, collision))
    return links


def revolute_joints() -> list[dict]:
    """The 20 revolute joints with ROBOTIS's limits, checked against the kinematics' axes."""
    out = []
    for j in read_joints():
        if j["type"] != "revolute":
            continue
        axis, lo, hi = JOINT_LIMITS[j["name"]]
        if tuple(axis) != tuple(round(v) for v in j["axis"]):
            raise SystemExit(f"{j['name']}: kinematics axis {axis} != xacro axis {j['axis']}")
        out.append({**j, "lower": lo * math.pi, "upper": hi * math.pi})
    return out


def fixed_frames() -> list[tuple[str, str, tuple[float, float, float]]]:
    """(frame, parent link, position m): soles and hands (ROBOTIS's leg/arm ends)."""
    (x0, y0), (x1, y1) = FOOT_BOX_MM
    cx, cy = (x0 + x1) / 2 * MM, (y0 + y1) / 2 * MM
    return [
        ("l_sole", "l_ank_roll_link", (cx, cy, -0.0305)),
        ("r_sole", "r_ank_roll_link", (cx, -cy, -0.0305)),
        ("l_hand", "l_el_link", (0.0, 0.15, 0.0)),
        ("r_hand", "r_el_link", (0.0, -0.15, 0.0)),
    ]


def build_urdf() -> str:
    out = [
        '<?xml version="1.0"?>',
        "<!-- ROBOTIS OP3, written by robots/op3/make_urdf.py from ROBOTIS's op3_description",
        "     (ROBOTIS-OP3-Common 0780e54, Apache License 2.0: LICENSE). Joint and link names,",
        "     origins, axes, masses and inertias are ROBOTIS's; joint limits are those of",
        "     op3_kinematics_dynamics.cpp; meshes are replaced by their bounding boxes.",
        "     Sources of every number: robots/op3/README.md. -->",
        '<robot name="op3">',
    ]
    for name, rgba in MATERIALS.items():
        out.append(f'  <material name="{name}"><color rgba="{fmt(rgba)}"/></material>')
    out += [link_xml(link, COLLISION_INSET) for link in all_links()]
    for j in revolute_joints():
        out += [
            f'  <joint name="{j["name"]}" type="revolute">',
            f'    <parent link="{j["parent"]}"/>',
            f'    <child link="{j["child"]}"/>',
            f'    <origin xyz="{fmt(j["xyz"])}" rpy="{fmt(j["rpy"])}"/>',
            f'    <axis xyz="{fmt(j["axis"])}"/>',
            f'    <limit lower="{j["lower"]:.12g}" upper="{j["upper"]:.12g}" '
            f'effort="{STALL_TORQUE:.6g}" velocity="{NO_LOAD_SPEED:.6g}"/>',
            "  </joint>",
        ]
    for frame, parent, xyz in fixed_frames():
        out += [
            f'  <link name="{frame}"/>',
            f'  <joint name="{frame}_fixed" type="fixed">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{frame}"/>',
            f'    <origin xyz="{fmt(xyz)}" rpy="0 0 0"/>',
            "  </joint>",
        ]
    out.append("</robot>")
    return "\n".join(out) + "\n"


# --- Poses -------------------------------------------------------------------------------
# ROBOTIS-OP3 op3_base_module/data/ini_pose.yaml "tar_pose" (degrees, by servo ID): the arms
# and head of the pose the base module moves to. Its legs (hip 70°, knee 140°) sit the robot
# down, past the kinematics' knee limit (126°): not used.
INI_POSE_ARMS_DEG = {
    "r_sho_pitch": 15, "l_sho_pitch": -15, "r_sho_roll": -45, "l_sho_roll": 45,
    "r_el": 45, "l_el": -45, "head_pan": 0, "head_tilt": -10,
}  # fmt: skip
# ROBOTIS-OP3 op3_walking_module/config/param.yaml: z_offset 0.035 m, the hip lowered from
# the straight leg to walk. Thigh 110.15 mm, shin 110 mm (the xacro's knee / ankle origins).
WALK_Z_OFFSET = 0.035
# The project's walking stance (robot.toml stand): the hip 20 mm lower than straight. In the
# simulator the 35 mm crouch leaves the knees and hips at stall torque in single support
# (benchmarks/op3.md); 20 mm asks less of them. Not a ROBOTIS figure.
WALK_HIGH_Z_OFFSET = 0.020
THIGH, SHIN = 0.11015, 0.110


def walk_ready(z_offset: float = WALK_Z_OFFSET) -> dict[str, float]:
    """The standing pose (rad): feet flat under the hips, hip ``z_offset`` lower than
    straight (law of cosines in the sagittal plane), torso upright; ROBOTIS's arm and head
    angles.

    With α the thigh's and β the shin's angle to the vertical, hip pitch = −α, knee = α + β,
    ankle pitch = β about +y; ROBOTIS's axes flip the right leg's signs (and the left ankle's).
    """
    d = THIGH + SHIN - z_offset
    a = math.acos((THIGH**2 + d * d - SHIN**2) / (2 * THIGH * d))
    b = math.acos((SHIN**2 + d * d - THIGH**2) / (2 * SHIN * d))
    pose = {}
    for s, axis_sign in (("l", 1.0), ("r", -1.0)):  # hip/knee axes: l +y, r -y
        pose[f"{s}_hip_pitch"] = -a * axis_sign
        pose[f"{s}_knee"] = (a + b) * axis_sign
        pose[f"{s}_ank_pitch"] = b * axis_sign  # ankle axes: l -y, r +y
    pose.update({j: math.radians(v) for j, v in INI_POSE_ARMS_DEG.items()})
    return pose


def build_poses() -> str:
    lines = [
        "# Named poses of op3.urdf in radians, by joint name (joints not listed are 0).",
        "# Generated by make_urdf.py (README.md section 5): do not edit.",
        "",
        "[poses.walk_ready]",
    ]
    lines += [f"{j} = {v!r}" for j, v in walk_ready().items()]
    lines += ["", "[poses.walk_high]"]
    lines += [f"{j} = {v!r}" for j, v in walk_ready(WALK_HIGH_Z_OFFSET).items()]
    return "\n".join(lines) + "\n"


def build_servo_map() -> str:
    lines = [
        "# Servo map of the ROBOTIS OP3: 20 x XM430-W350-R on Dynamixel Protocol 2.0.",
        "# Generated by make_urdf.py from ROBOTIS-OP3 op3_manager/config/OP3.robot (IDs, baud)",
        "# and dxl_init_OP3.yaml (the legs' I and D gains); README.md section 4. Do not edit.",
        "#",
        "#   q (rad) = sign * (ticks - zero_tick) * 2 pi / 4096     (4096 ticks over 360 deg)",
        "#",
        "# ROBOTIS's framework writes joint angles to the servos unchanged (zero at 2048), in",
        "# the URDF's own axes, which op3.urdf keeps: every sign is 1, every zero tick 2048.",
        "",
        "[bus]",
        "protocol = 2.0",
        f"baudrate = {BAUDRATE}",
        "",
        "[joints]",
    ]
    width = max(map(len, SERVO_IDS))
    for joint, sid in sorted(SERVO_IDS.items(), key=lambda kv: kv[1]):
        lines.append(f"{joint:<{width}} = {{ id = {sid}, sign = 1, zero_tick = {ZERO_TICK} }}")
    lines += [
        "",
        "# Register values written at start-up (wbc.xseries.XSettings): the legs' I and D gains",
        f"# of dxl_init_OP3.yaml with the project's P {LEG_P_GAIN} (dxl_init: 1000; README.md",
        "# section 4), the factory P 800 / I 0 / D 0 elsewhere.",
        "[settings]",
        "position_p_gain = 800",
        "position_i_gain = 0",
        "position_d_gain = 0",
        "",
    ]
    for joint in sorted(SERVO_IDS, key=SERVO_IDS.get):
        kind = joint[2:] if joint[:2] in ("l_", "r_") else joint
        if kind in GAINS:
            _, i, d = GAINS[kind]
            p = LEG_P_GAIN
            lines.append(
                f"[settings.joints.{joint}]\n"
                f"position_p_gain = {p}\nposition_i_gain = {i}\nposition_d_gain = {d}\n"
            )
    return "\n".join(lines).rstrip() + "\n"


def outputs() -> dict[Path, str]:
    return {
        HERE / "op3.urdf": build_urdf(),
        HERE / "servos.toml": build_servo_map(),
        HERE / "poses.toml": build_poses(),
    }


def main() -> int:
    if "--check" in sys.argv[1:]:
        ok = True
        for path, text in outputs().items():
            same = path.is_file() and path.read_text() == text
            ok &= same
            print(f"{path}: {'up to date' if same else 'DIFFERS from make_urdf.py output'}")
        return 0 if ok else 1
    for path, text in outputs().items():
        path.write_text(text)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
