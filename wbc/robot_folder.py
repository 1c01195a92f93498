"""A robot is a folder; ``init_folder`` scaffolds one from a URDF, ``check_folder`` checks it
(the ``wbc robot init`` / ``wbc robot check`` commands: :mod:`wbc.cli.robot`).

A robot folder (``robots/<name>/`` or any directory passed as ``--robot DIR``)::

    <name>.urdf    required: links, 1-DOF joints with position/velocity/effort limits, masses
    servos.toml    optional: servo map (Dynamixel ID, sign, zero tick per joint; poses in ticks)
    poses.toml     optional: named poses in radians by joint name ([poses.walk_ready] ...)
    stack.toml     optional: the robot's default task stack (format: tasks/*.toml)
    robot.toml     optional: [frames] torso / l_sole / r_sole = the URDF's names for them
    README.md      written by ``init``: this format, and what to fill in

Examples::

    wbc robot init my_robot.urdf --out robots/my_robot
    wbc robot check robots/my_robot
    wbc demo --robot robots/my_robot
"""

from __future__ import annotations

import math
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .exceptions import ConfigurationError, WbcError
from .model import (
    POSES_FILE,
    ROBOT_FILE,
    SERVO_MAP_FILE,
    STACK_FILE,
    STANDARD_FRAMES,
    STANDING_POSE,
    Robot,
    load_robot,
)
from .paths import stacks_dir
from .roles import leg_segments, length_unit

#: the stack copied as a new robot's default when its URDF has the standard frames
DEFAULT_STACK = "walk"


@dataclass(frozen=True)
class Finding:
    """One line of ``wbc robot check``: ``level`` is "ok", "note", "warning" or "error"."""

    level: str
    message: str

    def __str__(self) -> str:
        return f"{self.level:7s} {self.message}"


# ---------------------------------------------------------------------------- init
def init_folder(urdf: str | Path, out: str | Path, force: bool = False) -> list[str]:
    """Scaffold a robot folder from a URDF; returns one line per file written or skipped.

    Copies the URDF (as ``<folder name>.urdf``) and the mesh files it names by relative path,
    writes a commented ``servos.toml`` template (no servo IDs are guessed: it stays inert until
    filled in), ``poses.toml`` with the zero pose as ``walk_ready`` (clipped into the joint
    limits), a default ``stack.toml`` when the URDF has the frames ``torso``, ``l_sole``,
    ``r_sole``, and a README describing the format.
    """
    urdf, out = Path(urdf), Path(out)
    robot = Robot(urdf)  # validates the URDF first: nothing is written for a broken one
    if out.exists() and any(out.iterdir()) and not force:
        raise ConfigurationError(
            f"--out {out} exists and is not empty (use --force to write into it)"
        )
    out.mkdir(parents=True, exist_ok=True)
    lines = []
    target = out / f"{out.name}.urdf"
    shutil.copyfile(urdf, target)
    lines.append(f"wrote {target} (copy of {urdf})")
    lines += _copy_meshes(urdf, out)
    (out / SERVO_MAP_FILE).write_text(servo_template(robot, urdf.name))
    lines.append(f"wrote {out / SERVO_MAP_FILE} (template: fill in IDs, signs and zero ticks)")
    poses = poses_template(robot)
    (out / POSES_FILE).write_text(poses)
    proposed = "proposed standing pose" if "Proposed by" in poses else "the zero pose"
    lines.append(f"wrote {out / POSES_FILE} ({STANDING_POSE} = {proposed})")
    missing = [f for f in STANDARD_FRAMES if not robot.has_frame(f)]
    if missing:
        lines.append(
            f"no {STACK_FILE}: frames {missing} are not in the URDF (add them as fixed links, "
            f"or map them in {ROBOT_FILE} [frames], then copy tasks/{DEFAULT_STACK}.toml)"
        )
    else:
        shutil.copyfile(stacks_dir() / f"{DEFAULT_STACK}.toml", out / STACK_FILE)
        lines.append(f"wrote {out / STACK_FILE} (copy of tasks/{DEFAULT_STACK}.toml)")
    (out / "README.md").write_text(readme_template(out.name, urdf.name))
    lines.append(f"wrote {out / 'README.md'} (the folder format)")
    lines.append(f"next: wbc robot check {out}")
    return lines


def _copy_meshes(urdf: Path, out: Path) -> list[str]:
    """Copy mesh files named by a relative path; ``package://`` and absolute ones are noted."""
    lines = []
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError:
        return lines
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if not name:
            continue
        if "://" in name or Path(name).is_absolute():
            lines.append(f"note: mesh {name} is not copied (not a path relative to the URDF)")
            continue
        src = urdf.parent / name
        if src.is_file():
            (out / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, out / name)
            lines.append(f"wrote {out / name}")
        else:
            lines.append(f"note: mesh {name} not found beside {urdf}")
    return lines


def servo_template(robot: Robot, urdf_name: str) -> str:
    """A ``servos.toml`` whose every line is a comment: loading it gives no servo map."""
    width = max(len(j) for j in robot.joint_names)
    rows = "\n".join(
        f"# {j:<{width}} = {{ id = ?, sign = 1, zero_tick = 512 }}" for j in robot.joint_names
    )
    return f"""# Servo map of {urdf_name}: a TEMPLATE. Every line is a comment, so wbc treats the
# robot as having no servo map (wbc deploy refuses to run) until you fill it in.
#
# For every joint: its Dynamixel ID, the sign between the URDF joint angle and the servo's tick
# direction, and the tick at which the URDF angle is zero (AX-12A: 0..1023 ticks over 300 deg):
#
#   q (rad) = sign * (ticks - zero_tick) * (300 / 1023) * pi / 180
#
# Uncomment the tables below and replace every `?`. Optional: [poses.<name>] in ticks by ID
# (as in robots/bioloid/servos.toml), [settings] (compliance, punch, torque limit).
#
# [bus]
# baudrate = 1000000
#
# [joints]
{rows}
"""


#: the standing pose ``wbc robot init`` proposes: the hips lowered until hip-to-ankle is this
#: fraction of the straight leg's length (thigh + shin), soles flat, torso upright, knees bent
STAND_HEIGHT_FRACTION = 0.92


def standing_pose(robot: Robot, fraction: float = STAND_HEIGHT_FRACTION) -> np.ndarray:
    """Joint angles of a standing pose: both soles flat where they are at the zero pose, the
    torso upright and lowered by ``(1 - fraction) (thigh + shin)`` (knees bent forward, the
    way their larger limit allows), solved by :class:`wbc.pose_ik.StanceIK`. Raises a
    :class:`WbcError` (one line) if the legs cannot be understood or the pose not reached."""
    import pinocchio as pin

    from .exceptions import ModelError
    from .pose_ik import StanceIK

    roles = robot.roles
    q = robot.configuration("zero")
    leg = sum(leg_segments(robot))
    frames = ("torso", "l_sole", "r_sole")
    targets = {f: robot.frame_placement(q, f) for f in frames}
    torso = targets["torso"]
    targets["torso"] = pin.SE3(torso.rotation, torso.translation - [0.0, 0.0, (1 - fraction) * leg])
    start = q.copy()
    for side in ("left", "right"):
        k = robot.joint_index(roles.joint(side, "knee"))
        sign = 1.0 if robot.q_max[k] >= -robot.q_min[k] else -1.0
        start[7 + k] = sign * 0.6
        for r in ("hip_pitch", "ankle_pitch"):
            i = robot.joint_index(roles.joint(side, r))
            start[7 + i] = float(np.clip(-sign * 0.3, robot.q_min[i], robot.q_max[i]))
    ik = StanceIK(robot, frames)
    result = ik.solve(targets, start)
    if ik.residual(result.q, targets) > 1e-6 or not robot.within_limits(result.q, 1e-9):
        raise ModelError(
            f"{robot.name}: no standing pose with the hips at {fraction:.0%} of the leg length "
            "within the joint limits"
        )
    return robot.joints(result.q).copy()


def poses_template(robot: Robot) -> str:
    """``poses.toml`` with :data:`STANDING_POSE` = :func:`standing_pose` (soles flat, knees
    bent); the zero pose clipped into the limits if the legs cannot be understood."""
    try:
        pose = standing_pose(robot)
        how = (
            f"# {STANDING_POSE!r} is the pose every tool starts from (stack targets, walking,\n"
            f"# viewer). Proposed by `wbc robot init`: soles flat, torso upright, knees bent\n"
            f"# until hip-to-ankle is {STAND_HEIGHT_FRACTION:.0%} of the leg length; adjust it."
        )
    except WbcError as exc:
        pose = np.array(
            [np.clip(0.0, lo, hi) for lo, hi in zip(robot.q_min, robot.q_max, strict=True)]
        )
        how = (
            f"# {STANDING_POSE!r} is the pose every tool starts from (stack targets, walking,\n"
            f"# viewer): replace the zeros with your robot's standing pose, knees slightly bent\n"
            f"# (none proposed: {exc})."
        )
    lines = ["# Named poses in radians, by joint name (joints not listed are 0).", how, ""]
    lines.append(f"[poses.{STANDING_POSE}]")
    width = max(len(j) for j in robot.joint_names)
    for j, value in zip(robot.joint_names, pose, strict=True):
        lines.append(f"{j:<{width}} = {round(float(value), 6) + 0.0!r}")
    return "\n".join(lines) + "\n"


def readme_template(name: str, source: str) -> str:
    return f"""# Robot folder `{name}` (made by `wbc robot init {source}`)

- `{name}.urdf` (required): links, 1-DOF joints (`revolute`/`prismatic`) with
  `<limit lower upper velocity effort>`, masses and inertias.
- `servos.toml` (optional): the servo map; per joint `id`, `sign`, `zero_tick`;
  `[poses.<name>]` in ticks by ID; `[settings]` (see `robots/bioloid/servos.toml`).
  Without it: no `wbc deploy`. A file of comments only (the template) counts as absent.
- `poses.toml` (optional): `[poses.<name>]` joint = radians (joints not listed are 0);
  `walk_ready` is where every tool starts. Without it: the zero pose.
- `stack.toml` (optional): the default task stack of `wbc walk` (format of `tasks/*.toml`).
  Without it: `tasks/walk.toml`.
- `robot.toml` (optional): `[frames]` `torso`, `l_sole`, `r_sole` = your URDF's names for
  them, if they differ; `[joints.left]`/`[joints.right]` role = joint, for roles the
  kinematic tree does not tell (`wbc robot check` prints the roles it found); `[feet]` and
  `[legs]` to state what is otherwise measured from the model; `[walking.<trajectory>]`.

The stacks and the walking code need three frames: `torso` (the body whose orientation is
held), `l_sole` and `r_sole` (on the sole surfaces, z up, x forward at the standing pose). Add
them to the URDF as fixed links if it has none.

Check the folder with `wbc robot check {name}` (limits, frames, servo map, masses), then try
`wbc demo --robot <this folder>` and `wbc walk --robot <this folder>`.
"""


# ---------------------------------------------------------------------------- check
def check_folder(path: str | Path) -> list[Finding]:
    """Every finding about a robot folder (or a URDF), one per line; errors first stop
    nothing: all checks that can run do."""
    path = Path(path)
    findings: list[Finding] = []
    try:
        robot = load_robot(path)
    except WbcError as exc:
        return [Finding("error", str(exc))]
    folder = robot.urdf_path.parent
    findings.append(
        Finding(
            "ok", f"{robot.urdf_path}: {robot.n_joints} joints, {len(robot.link_names())} links"
        )
    )
    findings += _check_limits(robot)
    findings += _check_masses(robot)
    findings += _check_frames(robot, folder)
    findings += _check_legs(robot)
    findings += _check_servo_map(robot, folder)
    findings += _check_poses(robot)
    findings += _check_stack(robot, folder)
    findings += _check_sim(robot)
    findings += _check_self_collision(robot)
    return findings


def _check_self_collision(robot: Robot) -> list[Finding]:
    """The pairs the self-collision limit checks, those it leaves out and why, boxes that
    overlap at the standing pose (:func:`wbc.limits.self_collision.pair_report`)."""
    from .limits.self_collision import pair_report

    try:
        return [Finding(level, message) for level, message in pair_report(robot)]
    except WbcError as exc:  # e.g. a URDF without collision geometry
        return [Finding("note", f"self-collision: {exc}")]


def _check_limits(robot: Robot) -> list[Finding]:
    out = []
    effort = np.array(robot.model.effortLimit[6:])
    for i, j in enumerate(robot.joint_names):
        lo, hi, v, e = robot.q_min[i], robot.q_max[i], robot.v_max[i], effort[i]
        if not (math.isfinite(lo) and math.isfinite(hi)):
            out.append(Finding("error", f"joint {j}: position limits [{lo}, {hi}] not finite"))
        elif not lo < hi:
            out.append(Finding("error", f"joint {j}: lower limit {lo:g} >= upper {hi:g} rad"))
        if not (math.isfinite(v) and v > 0):
            out.append(Finding("error", f"joint {j}: velocity limit {v:g} rad/s (needs > 0)"))
        if not (math.isfinite(e) and e > 0):
            out.append(Finding("error", f"joint {j}: effort limit {e:g} N·m (needs > 0)"))
    if not out:
        out.append(Finding("ok", "joint limits: finite, lower < upper, velocity and effort > 0"))
    return out


def _check_masses(robot: Robot) -> list[Finding]:
    out = []
    model = robot.model
    for j in range(1, model.njoints):
        inertia = model.inertias[j]
        name = model.names[j]
        if inertia.mass < 0 or not math.isfinite(inertia.mass):
            out.append(Finding("error", f"body of joint {name}: mass {inertia.mass:g} kg"))
        elif inertia.mass == 0:
            out.append(
                Finding("warning", f"body of joint {name}: massless (fine only for a virtual link)")
            )
        elif np.linalg.eigvalsh(inertia.inertia).min() <= 0:
            out.append(Finding("warning", f"body of joint {name}: inertia not positive definite"))
    total = robot.total_mass
    level = "ok" if total > 0 and not any(f.level == "error" for f in out) else "error"
    out.append(Finding(level, f"total mass {total:.4f} kg"))
    return out


def _check_frames(robot: Robot, folder: Path) -> list[Finding]:
    missing = [f for f in STANDARD_FRAMES if not robot.has_frame(f)]
    if not missing:
        mapped = {k: v for k, v in robot.frame_aliases.items()}
        via = f" (mapped in {ROBOT_FILE}: {mapped})" if mapped else ""
        return [Finding("ok", f"frames {', '.join(STANDARD_FRAMES)} present{via}")]
    return [
        Finding(
            "error",
            f"frames {missing} missing: the stacks and walking need them; add fixed links to the "
            f"URDF or map them in {folder / ROBOT_FILE} [frames]; links: "
            f"{', '.join(robot.link_names())}",
        )
    ]


def _check_legs(robot: Robot) -> list[Finding]:
    """The joint roles found (:mod:`wbc.roles`), the feet and the legs' measurements."""
    if not all(robot.has_frame(f) for f in STANDARD_FRAMES):
        return []
    try:
        roles = robot.roles
    except WbcError as exc:
        return [Finding("error", str(exc))]
    out = [Finding("ok", "joint roles from the kinematic tree (* named in robot.toml [joints]):")]
    out += [Finding("ok", f"  {line}") for line in roles.lines()]
    given = robot.robot_data.feet_given
    try:
        length, width = robot.foot_size
    except WbcError as exc:
        return [*out, Finding("error", str(exc))]
    where = f"{ROBOT_FILE} [feet]" if len(given) == 2 else "the sole link's collision box"
    out.append(Finding("ok", f"feet {1e3 * length:.1f} x {1e3 * width:.1f} mm (from {where})"))
    from .walking.legs import LegGeometry

    try:
        legs = LegGeometry.from_robot(robot)
    except WbcError as exc:
        return [*out, Finding("error", f"leg measurements: {exc}")]
    out.append(
        Finding(
            "ok",
            f"legs: thigh {1e3 * legs.thigh:.1f} mm, shin {1e3 * legs.shin:.1f} mm, hips "
            f"{2e3 * legs.hip_half_width:.1f} mm apart, ankle {1e3 * legs.ankle_height:.1f} mm "
            f"above the sole, standing CoM {1e3 * robot.com(robot.configuration('stand'))[2]:.1f}"
            f" mm high; {length_unit(robot):.3g}x the Bioloid's leg (the walking settings and"
            " the stacks' length weights are scaled by it)",
        )
    )
    return out


def _check_servo_map(robot: Robot, folder: Path) -> list[Finding]:
    path = folder / SERVO_MAP_FILE
    if robot.servo_map is None and (folder / "ssc32.toml").is_file():
        from .servos.ssc32 import Ssc32Map

        try:
            ssc = Ssc32Map.from_file(folder / "ssc32.toml", robot.joint_names)
        except WbcError as exc:
            return [Finding("error", str(exc))]
        warnings = ssc.range_warnings(robot.q_min, robot.q_max)
        if warnings:
            return [Finding("warning", w) for w in warnings]
        return [Finding("ok", f"{folder / 'ssc32.toml'}: every joint's range inside 500..2500 µs")]
    if robot.servo_map is None:
        state = "an unfilled template" if path.is_file() else "missing"
        return [Finding("note", f"{path} is {state}: no servo IDs, wbc deploy unavailable")]
    sm = robot.servo_map
    out = [Finding("ok", f"servo map {sm.source}: {len(sm)} servos, one per URDF joint")]
    if not hasattr(sm, "angles_to_ticks_float"):  # another servo type: its own range check
        return [*out, Finding("note", "servo range not checked for this kind of servo map")]
    a = sm.angles_to_ticks_float(robot.q_min)
    b = sm.angles_to_ticks_float(robot.q_max)
    span = np.abs(b - a)
    inside = np.minimum(np.maximum(a, b), sm.tick_max) - np.maximum(np.minimum(a, b), sm.tick_min)
    for i in np.flatnonzero(inside < span - 1.0):  # a tick of slack: rounding of the limits
        share = 100 * max(inside[i], 0.0) / span[i]
        out.append(
            Finding(
                "error" if share < 95 else "warning",
                f"joint {robot.joint_names[i]} (id {sm.ids[i]}): limits [{robot.q_min[i]:.3f}, "
                f"{robot.q_max[i]:.3f}] rad are ticks [{a[i]:.0f}, {b[i]:.0f}]; only "
                f"{share:.0f} % lie inside the servo's {sm.tick_min}..{sm.tick_max} (wrong sign "
                "or zero tick?)",
            )
        )
    return out


def _check_sim(robot: Robot) -> list[Finding]:
    """``robot.toml`` ``[servo]`` and ``[imu]``: the simulator's servo model and IMU."""
    if not (robot.robot_data.servo or robot.robot_data.imu):
        return []
    from .sim.actuator import nominal_servo
    from .sim.model import imu_mount, imu_placement

    try:
        servo = nominal_servo(robot)
        frame, _ = imu_placement(robot)
        mount = imu_mount(robot)
    except WbcError as exc:
        return [Finding("error", str(exc))]
    name = getattr(servo, "name", "AX-12A")
    where = "" if mount is None else f" (mount in the torso frame: {mount})"
    return [Finding("ok", f"simulator: {name} servos on every joint, IMU at {frame!r}{where}")]


def _check_poses(robot: Robot) -> list[Finding]:
    out = []
    names = [n for n in robot.pose_names() if n not in ("zero", "stand")]  # "stand": an alias
    if robot.stand_pose == "zero":
        out.append(Finding("note", f"no pose {STANDING_POSE!r}: tools start from the zero pose"))
        names.append("zero")
    for name in names:
        try:
            q = robot.configuration(name)
        except WbcError as exc:
            out.append(Finding("error", f"pose {name!r}: {exc}"))
            continue
        j = q[7:]
        bad = [
            robot.joint_names[i]
            for i in np.flatnonzero((j < robot.q_min - 1e-9) | (j > robot.q_max + 1e-9))
        ]
        if bad:
            out.append(Finding("error", f"pose {name!r} is outside the joint limits at {bad}"))
        else:
            out.append(Finding("ok", f"pose {name!r} within the joint limits"))
    return out


def _check_stack(robot: Robot, folder: Path) -> list[Finding]:
    if robot.default_stack is None:
        return [Finding("note", f"no {folder / STACK_FILE}: wbc walk uses tasks/walk.toml")]
    from .stacks import load_stack

    try:
        control = load_stack(robot.default_stack, robot)
    except WbcError as exc:
        return [Finding("error", str(exc))]
    n = sum(1 for _ in control.stack.tasks())
    return [Finding("ok", f"stack {robot.default_stack}: {n} tasks load on this robot")]
