"""The MuJoCo model of a robot, built at run time from its URDF (no hand-kept MJCF copy).

``MjSpec.from_file(urdf)`` reads the URDF with MuJoCo's URDF defaults (``discardvisual``:
visual geoms dropped, the collision geoms kept; ``fusestatic``: massless fixed links such as
``l_sole`` merged into their parent; inertias taken as written, rotated to their principal
axes). Then :func:`build_spec` adds a free joint on the root link, a floor, one torque
actuator per joint (the servo law in :mod:`wbc.sim.actuator` sets its control every step),
the servo's joint properties (reflected rotor inertia, back-EMF damping, gear friction: the
robot's servo model, :func:`wbc.sim.actuator.nominal_servo`, unless :class:`ModelParams`
gives them), sites at the robot's operational frames (torso and soles; hands if it has
them) and the IMU (at ``robot.toml`` ``[imu] frame`` + ``offset``, default the torso) with
its sensors. Nothing here is Bioloid-specific: any robot folder's URDF with the frames
``torso``, ``l_sole``, ``r_sole`` (or their ``[frames]`` aliases) builds.
The robot's own geoms collide with the floor only (self-collision is the controller's
business: issue 14).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ..exceptions import ModelError
from ..model import Robot
from . import mujoco_module

if TYPE_CHECKING:
    from .actuator import HobbyServoParams, ServoParams

SITES = ("torso", "l_sole", "r_sole")  # required
OPTIONAL_SITES = ("l_hand", "r_hand")
IMU_SITE = "imu"


@dataclass(frozen=True)
class ModelParams:
    """Physical parameters of one simulated model (nominal values by default).

    ``mass_scale`` / ``com_offset`` are per link (MuJoCo body order after the world, i.e. the
    order of :func:`link_names`); None = as in the URDF. ``armature``, ``damping`` and
    ``friction_loss`` None = the robot's servo model's (:meth:`resolved`); ``imu_offset``
    None = the robot data's (``[imu] offset``, default 0).
    """

    timestep: float = 0.002
    floor_friction: float = 0.8  # sliding friction coefficient (dry plastic on a table)
    armature: float | np.ndarray | None = None
    damping: float | np.ndarray | None = None
    friction_loss: float | np.ndarray | None = None
    mass_scale: np.ndarray | None = None
    com_offset: np.ndarray | None = None  # (n_links, 3) m
    imu_offset: Sequence[float] | None = None  # IMU site in the IMU frame, m
    #: the IMU's real rotation in its frame (3x3; None: the robot data's ``[imu] rpy_deg``):
    #: a plant whose IMU is mounted otherwise than its robot folder says
    imu_rotation: np.ndarray | None = None
    #: MuJoCo's friction cone: ``"pyramidal"`` (MuJoCo's default) or ``"elliptic"``
    #: (isotropic); :data:`FRICTION_CONES`
    friction_cone: str = "pyramidal"
    #: MuJoCo's ``impratio``: the friction constraints' impedance over the normal's (> 1:
    #: stiffer friction, a loaded sole creeps less below the friction limit; MuJoCo advises
    #: it with the elliptic cone)
    impratio: float = 1.0
    #: MuJoCo's ``noslip_iterations`` (0: off): a post-solve pass that removes the soft
    #: friction's slip
    noslip_iterations: int = 0
    #: the floor's contact dimensions (MuJoCo ``condim``: 3 sliding friction, MuJoCo's
    #: default; 4 adds torsional friction, the floor's ``friction[1]``, 5 mm: a sole on an
    #: edge or a corner then resists a turn; 6 rolling friction too); :data:`CONDIMS`
    condim: int = 3
    extra: dict = field(default_factory=dict)

    def resolved(self, servo: ServoParams | HobbyServoParams) -> ModelParams:
        """A copy whose unset joint properties are those of ``servo`` (servo parameters)."""
        return replace(
            self,
            armature=servo.armature if self.armature is None else self.armature,
            damping=servo.damping if self.damping is None else self.damping,
            friction_loss=servo.friction_loss if self.friction_loss is None else self.friction_loss,
        )


#: :attr:`ModelParams.friction_cone`'s choices
FRICTION_CONES = ("pyramidal", "elliptic")
#: :attr:`ModelParams.condim`'s choices
CONDIMS = (1, 3, 4, 6)

IMU_KEYS = ("frame", "offset", "rpy_deg")


def imu_placement(robot: Robot) -> tuple[str, np.ndarray]:
    """The IMU's frame and offset (m, in that frame) from ``robot.toml`` ``[imu]``
    (default: the torso frame, no offset)."""
    frame, offset, _ = imu_pose(robot)
    return frame, offset


def imu_pose(robot: Robot) -> tuple[str, np.ndarray, np.ndarray]:
    """The IMU's frame, offset (m, in that frame) and rotation (3x3: the IMU's axes in that
    frame, from ``rpy_deg`` = roll, pitch, yaw in degrees) from ``robot.toml`` ``[imu]``
    (default: the torso frame, no offset, no rotation)."""
    from ..imu import ImuMount

    table = robot.robot_data.imu
    where = f"{robot.robot_data.source}/robot.toml [imu]"
    extra = sorted(set(table) - set(IMU_KEYS))
    if extra:
        raise ModelError(f"{where}: unknown keys {extra}; allowed: {', '.join(IMU_KEYS)}")
    rpy = table.get("rpy_deg", [0.0, 0.0, 0.0])
    ok = isinstance(rpy, (list, tuple)) and len(rpy) == 3
    if not ok or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in rpy):
        raise ModelError(f"{where}: rpy_deg = {rpy!r} must be 3 numbers (roll, pitch, yaw, °)")
    rotation = ImuMount.from_rpy(rpy).rotation
    frame = table.get("frame", "torso")
    if not isinstance(frame, str) or not robot.has_frame(frame):
        raise ModelError(f"{where}: frame = {frame!r} is not a frame of {robot.urdf_path.name}")
    offset = table.get("offset", [0.0, 0.0, 0.0])
    ok = isinstance(offset, (list, tuple)) and len(offset) == 3
    if not ok or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in offset):
        raise ModelError(f"{where}: offset = {offset!r} must be 3 numbers (m)")
    return frame, np.asarray(offset, dtype=float), rotation


def imu_mount(robot: Robot):
    """The robot's IMU mount in the torso frame (:class:`wbc.imu.ImuMount`) from
    ``robot.toml`` ``[imu]``; None when the IMU sits at the torso frame, unrotated. Its frame
    must be on the torso's link (one clear line otherwise)."""
    from ..imu import ImuMount

    frame, offset, rotation = imu_pose(robot)
    if frame == "torso" and not offset.any() and np.array_equal(rotation, np.eye(3)):
        return None
    model = robot.model
    f, t = model.frames[robot.frame_id(frame)], model.frames[robot.frame_id("torso")]
    if f.parentJoint != t.parentJoint:
        raise ModelError(
            f"{robot.robot_data.source}/robot.toml [imu]: frame = {frame!r} moves with a joint "
            "the torso does not: the IMU must sit on the torso's link"
        )
    rel = t.placement.inverse() * f.placement
    return ImuMount(rel.rotation @ rotation, rel.translation + rel.rotation @ offset)


def build_spec(robot: Robot, params: ModelParams | None = None):
    """The MuJoCo spec of ``robot`` (free base, floor, actuators, sites, IMU sensors)."""
    from .actuator import nominal_servo

    mj = mujoco_module()
    p = params or ModelParams()
    if p.armature is None or p.damping is None or p.friction_loss is None:
        p = p.resolved(nominal_servo(robot))
    try:
        spec = mj.MjSpec.from_file(str(robot.urdf_path))
    except Exception as exc:
        raise ModelError(f"MuJoCo cannot read the URDF {robot.urdf_path}: {exc}") from exc
    spec.option.timestep = p.timestep
    spec.option.integrator = mj.mjtIntegrator.mjINT_IMPLICITFAST
    _contact_options(spec, p, mj)
    bodies = {b.name: b for b in spec.bodies}
    root = _root_body(robot, bodies)
    root.add_freejoint(name="base")
    spec.worldbody.add_geom(
        name="floor",
        type=mj.mjtGeom.mjGEOM_PLANE,
        size=[5.0, 5.0, 0.05],
        friction=[p.floor_friction, 0.005, 0.0001],
        condim=p.condim,
        contype=1,
        conaffinity=1,
        rgba=[0.8, 0.8, 0.8, 1.0],
    )
    for g in spec.geoms:
        if g.name != "floor":
            g.contype, g.conaffinity = 1, 0  # robot <-> floor only
    links = link_names(spec)
    if p.mass_scale is not None or p.com_offset is not None:
        scale = np.ones(len(links)) if p.mass_scale is None else np.asarray(p.mass_scale)
        offset = np.zeros((len(links), 3)) if p.com_offset is None else np.asarray(p.com_offset)
        for k, name in enumerate(links):
            b = bodies[name]
            b.mass = b.mass * float(scale[k])
            b.fullinertia = np.asarray(b.fullinertia) * float(scale[k])
            b.ipos = np.asarray(b.ipos) + offset[k]
    n = robot.n_joints
    arm = np.broadcast_to(np.asarray(p.armature, dtype=float), (n,))
    damp = np.broadcast_to(np.asarray(p.damping, dtype=float), (n,))
    fric = np.broadcast_to(np.asarray(p.friction_loss, dtype=float), (n,))
    joints = {j.name: j for j in spec.joints}
    for i, name in enumerate(robot.joint_names):
        j = joints.get(name)
        if j is None:
            raise ModelError(f"MuJoCo model of {robot.urdf_path.name} lacks joint {name!r}")
        j.armature, j.frictionloss = float(arm[i]), float(fric[i])
        try:
            j.damping = [float(damp[i]), 0.0, 0.0]  # MuJoCo 4: polynomial, linear term first
        except TypeError:
            j.damping = float(damp[i])  # MuJoCo 3
        spec.add_actuator(
            name=name,
            target=name,
            trntype=mj.mjtTrn.mjTRN_JOINT,
            gainprm=[1.0] + [0.0] * 9,
            biasprm=[0.0] * 10,
            ctrllimited=0,
        )
    for frame in site_names(robot):
        body, placement = _site_placement(robot, frame, bodies)
        body.add_site(name=frame, pos=placement.translation, quat=_wxyz(placement.rotation))
    imu_frame, imu_offset, imu_rotation = imu_pose(robot)
    if p.imu_offset is not None:
        imu_offset = np.asarray(p.imu_offset, dtype=float)
    if p.imu_rotation is not None:
        imu_rotation = np.asarray(p.imu_rotation, dtype=float)
    body, placement = _site_placement(robot, imu_frame, bodies)
    body.add_site(
        name=IMU_SITE,
        pos=placement.translation + placement.rotation @ imu_offset,
        quat=_wxyz(placement.rotation @ imu_rotation),
    )
    spec.add_sensor(name="imu_quat", type=mj.mjtSensor.mjSENS_FRAMEQUAT,
                    objtype=mj.mjtObj.mjOBJ_SITE, objname=IMU_SITE)  # fmt: skip
    spec.add_sensor(name="imu_gyro", type=mj.mjtSensor.mjSENS_GYRO,
                    objtype=mj.mjtObj.mjOBJ_SITE, objname=IMU_SITE)  # fmt: skip
    spec.add_sensor(name="imu_acc", type=mj.mjtSensor.mjSENS_ACCELEROMETER,
                    objtype=mj.mjtObj.mjOBJ_SITE, objname=IMU_SITE)  # fmt: skip
    return spec


def _contact_options(spec, p: ModelParams, mj) -> None:
    """The friction cone, ``impratio`` and noslip iterations of ``p`` on ``spec``'s options
    (bad values: one clear line)."""
    if p.friction_cone not in FRICTION_CONES:
        raise ModelError(f"friction_cone {p.friction_cone!r}: choose from {FRICTION_CONES}")
    if not (np.isfinite(p.impratio) and p.impratio > 0.0):
        raise ModelError(f"impratio must be > 0, got {p.impratio}")
    if p.condim not in CONDIMS:
        raise ModelError(f"condim {p.condim!r}: choose from {CONDIMS}")
    if int(p.noslip_iterations) != p.noslip_iterations or p.noslip_iterations < 0:
        raise ModelError(
            f"noslip_iterations must be a whole number >= 0, got {p.noslip_iterations}"
        )
    cones = {"pyramidal": mj.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mj.mjtCone.mjCONE_ELLIPTIC}
    spec.option.cone = cones[p.friction_cone]
    spec.option.impratio = float(p.impratio)
    spec.option.noslip_iterations = int(p.noslip_iterations)


def build_model(robot: Robot, params: ModelParams | None = None):
    """The compiled ``MjModel`` of :func:`build_spec`."""
    spec = build_spec(robot, params)
    try:
        return spec.compile()
    except Exception as exc:
        raise ModelError(
            f"MuJoCo cannot compile the model of {robot.urdf_path.name}: {exc}"
        ) from exc


def site_names(robot: Robot) -> list[str]:
    """The operational frames that get a site: torso and soles (required), hands if any."""
    missing = [f for f in SITES if not robot.has_frame(f)]
    if missing:
        raise ModelError(
            f"{robot.urdf_path.name}: frames {missing} missing: the simulator needs torso, "
            "l_sole, r_sole (add fixed links, or map them in robot.toml [frames])"
        )
    return [*SITES, *(f for f in OPTIONAL_SITES if robot.has_frame(f))]


def _root_body(robot: Robot, bodies: dict):
    """The MuJoCo body of the URDF's root link (the one pinocchio's free flyer moves)."""
    for f in robot.model.frames:
        if f.parentJoint == 1 and f.type == pin.FrameType.BODY and f.name in bodies:
            return bodies[f.name]
    raise ModelError(f"MuJoCo model of {robot.urdf_path.name}: no body for the root link")


def link_names(spec) -> list[str]:
    """Names of the spec's bodies that carry mass (the links; massless fixed frames such as
    ``l_sole`` are merged into their parent at compile time)."""
    return [b.name for b in spec.bodies if b.name != "world" and b.mass > 0]


def _wxyz(R: np.ndarray) -> np.ndarray:
    x, y, z, w = pin.Quaternion(R).coeffs()
    return np.array([w, x, y, z])


def _site_placement(robot: Robot, frame: str, bodies: dict):
    """The MuJoCo body carrying ``frame`` and the frame's placement in that body."""
    model = robot.model
    fid = robot.frame_id(frame)
    joint = model.frames[fid].parentJoint
    # the body frame of the link that the joint moves: a BODY frame with that parent joint
    for f in model.frames:
        if f.parentJoint == joint and f.type == pin.FrameType.BODY and f.name in bodies:
            body_frame = f
            break
    else:
        raise ModelError(f"no MuJoCo body carries frame {frame!r}")
    placement = body_frame.placement.inverse() * model.frames[fid].placement
    return bodies[body_frame.name], placement
