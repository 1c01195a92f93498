"""Getting up after a fall: a whole-body motion planned with the project's own QP stack.

A get-up is a sequence of **support phases** (:class:`Phase`). Each phase names the frames in
contact with the floor — held where they are as **hard** tasks of a lexicographic QP
(:class:`~wbc.solvers.HierarchicalQP`): soles and the torso as 6-D contacts, hands, toes and
heels as point contacts, *sliding* points (a hand pushing back along the floor) at their height
only — together with self-collision rows, floor rows (no hand, toe or heel below the floor; the
torso and the hips no lower than they lay) and, once the soles are among the contacts, the CoM
inside their hull (:class:`SupportHullConstraint`). One level below: where some frames go (a
hand to the floor), soles turned flat, the torso's pitch, the CoM (over the centre of the
phase's support) and a light posture. The targets move from their values at the phase's start
to their goals (a smooth ramp), the QP ticking at ``rate`` with the joint limits and the
servos' speed (``speed_scale`` · v_max) as hard bounds: the phase's joint trajectory.
:func:`static_torques` gives the joint torques that hold a planned configuration on its
contacts (least-norm contact forces). Every frame is a standard frame of the model (``torso``,
``l_sole``, ``r_sole``, ``l_hand``, ``r_hand``; toes and heels at the front and back edges of
each sole, :func:`with_toes`), the hip and shoulder joints come from the joint roles, the
lengths from the model (:class:`BodySizes`): nothing names a robot's joint.

From **prone** (lying on the front): hands to the floor beside the chest, a push-up onto hands
and toes, a pike (hips up, the toes drawn in), the soles rolled flat about the toes, the CoM
brought back over the feet into a squat (the hands sliding back), the hands lifted, the rise
to the standing pose, a settle. From **supine** (on the back): hands beside the waist, a
sit-up onto hands and heels, a crab (the heels drawn in), the soles flat, the crossing onto
the feet (the shins turned forward, the trunk leaning back, the hands sliding behind until the
CoM is over the feet: :func:`supine_phases`), the trunk brought forward over the feet, the rise
and a settle, the servos stiffened ×8 (:data:`SUPINE_STIFFNESS`) until the trunk is over the
feet.

The plan is made from the measured fallen state (:func:`lying_state`: the joints from the
servos, the torso's orientation from the IMU, the base put on the floor) and played phase by
phase in the closed loop (:mod:`wbc.balance.getup_play`): each phase is planned from the
state the previous one left.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, WbcError
from ..geometry import convex_hull, sole_corners
from ..limits.limit import Constraint, Inequality, way_back
from ..model import Kinematics, Robot
from ..roles import HAND_FRAMES, SIDES, SOLE_FRAMES
from ..walking.spline import smooth

TOE_FRAMES = {"left": "l_toe", "right": "r_toe"}
HEEL_FRAMES = {"left": "l_heel", "right": "r_heel"}
SIDES_LYING = ("prone", "supine")
#: the servos' stiffness (× the configured) while the arms lift the trunk from the back: the
#: sit-up asks ~0.8 N·m of each shoulder, which at the Bioloid's configured compliance slope
#: (128) it gives only a third of a radian short of its goal; x8 (slopes 16, hips 4)
#: lifts the trunk in the simulator, x4 does not (benchmarks/getup.md)
SUPINE_STIFFNESS = 8.0
#: the trunk's pitch (deg about the ground frame's y; −90 face up) while the CoM crosses onto
#: the feet from the back: −75..−85 get the randomised Bioloids up, −70 does not (its arms
#: no longer reach the floor behind the heels: benchmarks/getup.md)
CROSS_PITCH = -80.0
#: where the crossing leaves the CoM: this share of the foot's length ahead of the heels
CROSS_AHEAD = 0.15


@dataclass(frozen=True)
class GetupParams:
    """Settings of the planner (speeds as a share of the servos', times in s)."""

    rate: float = 50.0  # Hz: the plan's samples (the QP's ticks)
    speed_scale: float = 0.5  # share of the servos' no-load speed any joint may use
    hold_s: float = 0.3  # s at the end of each phase with the targets at their goals
    self_collision_margin: float = 0.005  # m
    #: m: the CoM kept this far inside the hull of a phase's contacts once the soles are
    #: among them (:class:`SupportHullConstraint`); None: no such rows
    support_margin: float | None = 0.005
    #: m: the margin instead in a phase with sliding contacts (hands sliding along the floor
    #: stop this far behind the CoM: at 5 mm the hips rose with the hands under nearly all the
    #: weight and the arms gave way; benchmarks/getup.md)
    sliding_margin: float = 0.015

    def check(self) -> GetupParams:
        for name in ("rate", "speed_scale", "hold_s", "self_collision_margin"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigurationError(f"getup: {name} must be a finite number >= 0, got {v}")
        m = self.support_margin
        if m is not None and not (math.isfinite(m) and m >= 0):
            raise ConfigurationError(f"getup: support_margin must be None or >= 0 m, got {m}")
        m = self.sliding_margin
        if not (math.isfinite(m) and m >= 0):
            raise ConfigurationError(f"getup: sliding_margin must be >= 0 m, got {m}")
        if not 0 < self.speed_scale <= 1:
            raise ConfigurationError(
                f"getup: speed_scale must be in (0, 1], got {self.speed_scale}"
            )
        if self.rate <= 0:
            raise ConfigurationError(f"getup: rate must be > 0 Hz, got {self.rate}")
        return self


@dataclass(frozen=True)
class Phase:
    """One support phase (module docstring). Positions are in the ground frame (x the
    robot's heading on the floor, z up, origin below the shoulders at the plan's start).

    ``contacts``: frames held where they are (hard); ``sliding``: point contacts held on the
    floor (their height, hard) but free to slide along it (a hand pushing back); ``moves``:
    frame -> goal position;
    ``flat``: frames turned to the ground frame's orientation (a sole flat, facing ahead);
    ``torso_pitch``: the torso's goal pitch (rad about the ground frame's y: 0 upright, +π/2
    face down, −π/2 face up); ``com_over``: frames whose centroid the CoM goes above (with
    ``com_shift`` m added along x); ``com_z``: the CoM's goal height; ``posture``: a named
    pose as the light posture target (None: the phase's start); ``duration`` (s) of the ramp.
    """

    name: str
    contacts: tuple[str, ...]
    duration: float
    sliding: tuple[str, ...] = ()
    moves: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    flat: tuple[str, ...] = ()
    torso_pitch: float | None = None
    com_over: tuple[str, ...] = ()
    com_shift: float = 0.0
    com_z: float | None = None
    posture: str | None = None
    posture_weight: float = 0.01
    #: the CoM kept inside the contacts' hull (:class:`SupportHullConstraint`: the phases
    #: whose contacts include the soles)
    quasi_static: bool = True
    #: the servos' stiffness during the phase, × the configured one (the bus writes it:
    #: :meth:`wbc.servos.bus.ServoBus.set_stiffness`); 1: as ``servos.toml`` sets them
    stiffness: float = 1.0


@dataclass
class PhasePlan:
    """A planned phase: times (s from the phase start), configurations (rows, wbc
    convention), the contacts' anchors (frame -> position) and the ground frame."""

    phase: Phase
    t: np.ndarray
    q: np.ndarray
    anchors: dict[str, np.ndarray]
    failed_solves: int = 0


def with_toes(robot: Robot) -> Robot:
    """A copy of ``robot`` with a frame at the middle of each sole's front and back edges
    (``l_toe``, ``r_toe``, ``l_heel``, ``r_heel``: half the foot length ahead of and behind
    the sole frame)."""
    if all(robot.has_frame(f) for f in (*TOE_FRAMES.values(), *HEEL_FRAMES.values())):
        return robot
    out = copy.deepcopy(robot)
    half = 0.5 * float(robot.foot_size[0])
    for side in SIDES:
        sole = out.frame_id(SOLE_FRAMES[side])
        f = out.model.frames[sole]
        for name, dx in ((TOE_FRAMES[side], half), (HEEL_FRAMES[side], -half)):
            placement = f.placement * pin.SE3(np.eye(3), np.array([dx, 0.0, 0.0]))
            frame = pin.Frame(name, f.parentJoint, sole, placement, pin.FrameType.OP_FRAME)
            out.model.addFrame(frame)
    out.data = out.model.createData()
    out.frame_names = tuple(f.name for f in out.model.frames)
    out._frame_ids = {}
    return out


@dataclass(frozen=True)
class BodySizes:
    """Lengths measured on the model at its zero pose (m): leg (hip pitch joint to sole),
    arm (shoulder pitch joint to hand), trunk (hip pitch to shoulder pitch, vertical), the
    shoulders' and hips' half widths, the foot's length."""

    leg: float
    arm: float
    trunk: float
    shoulder_y: float
    hip_y: float
    foot: float  # the sole's length

    @classmethod
    def of(cls, robot: Robot) -> BodySizes:
        q = robot.neutral()
        roles = robot.roles
        kin = Kinematics(robot, q)

        def joint_pos(name: str) -> np.ndarray:
            j = robot.model.getJointId(name)
            return np.asarray(kin.data.oMi[j].translation)

        hip = joint_pos(roles.joint("left", "hip_pitch"))
        sole = kin.translation(robot.frame_id(SOLE_FRAMES["left"]))
        shoulder = joint_pos(roles.joint("left", "shoulder_pitch"))
        hand = kin.translation(robot.frame_id(HAND_FRAMES["left"]))
        return cls(
            leg=float(np.linalg.norm(hip - sole)),
            arm=float(np.linalg.norm(shoulder - hand)),
            trunk=float(shoulder[2] - hip[2]),
            shoulder_y=float(abs(shoulder[1])),
            hip_y=float(abs(hip[1])),
            foot=float(robot.foot_size[0]),
        )


def check_robot(robot: Robot) -> None:
    """One line if ``robot`` lacks what a get-up needs (hand frames, arms with a shoulder
    pitch)."""
    missing = [f for f in (*HAND_FRAMES.values(), *SOLE_FRAMES.values(), "torso")]
    missing = [f for f in missing if not robot.has_frame(f)]
    if missing:
        raise ConfigurationError(
            f"get-up: {robot.name} has no frames {missing} (hands and soles are its contacts)"
        )
    for side in SIDES:
        if robot.roles.get(side, "shoulder_pitch") is None:
            raise ConfigurationError(f"get-up: {robot.name}'s {side} arm has no shoulder pitch")


# ---------------------------------------------------------------------- the fallen state
def lying_side(torso_rotation: np.ndarray, threshold: float = 0.6) -> str | None:
    """``"prone"`` if the torso's front (its x axis) points down more than ``threshold``
    (the cosine to the vertical), ``"supine"`` if up, None otherwise (on a side, or up)."""
    fz = float(np.asarray(torso_rotation)[2, 0])
    if fz < -threshold:
        return "prone"
    if fz > threshold:
        return "supine"
    return None


def heading_of(torso_rotation: np.ndarray, side: str) -> float:
    """The ground frame's heading (rad) of a robot lying on ``side``: the direction its head
    points to on the floor (the torso's z axis projected)."""
    z = np.asarray(torso_rotation)[:, 2]
    return math.atan2(float(z[1]), float(z[0]))


def lowest_point(robot: Robot, q: np.ndarray) -> float:
    """The height (m) of the lowest corner of the robot's collision boxes at ``q``."""
    from ..limits.collision_boxes import _box_vertices, collision_model

    cm = collision_model(robot)
    data = robot.model.createData()
    gdata = pin.GeometryData(cm.geometry)
    pin.forwardKinematics(robot.model, data, q)
    low = math.inf
    for g in cm.geometry.geometryObjects:
        local = _box_vertices(g)  # in the parent joint's frame
        M = data.oMi[g.parentJoint]
        z = local @ M.rotation.T[:, 2] + M.translation[2]
        low = min(low, float(z.min()))
    del gdata
    return low


def lying_state(robot: Robot, joints: np.ndarray, torso_rotation: np.ndarray) -> np.ndarray:
    """The configuration of a robot lying on the floor: the measured joints, the torso turned
    as measured (the IMU) and the base put down so its lowest point touches z = 0, the torso
    frame above the world's origin."""
    q = robot.neutral()
    q[7:] = np.asarray(joints, dtype=float)
    kin = Kinematics(robot, q)
    torso = kin.placement(robot.frame_id("torso"))
    base = pin.XYZQUATToSE3(q[:7])
    want = pin.SE3(np.asarray(torso_rotation, dtype=float), np.zeros(3))
    new = want * torso.inverse() * base
    q[:7] = pin.SE3ToXYZQUAT(new)
    q[2] -= lowest_point(robot, q)
    return q


def ground_frame(q: np.ndarray, robot: Robot, side: str) -> pin.SE3:
    """The ground frame of a plan from ``q`` lying on ``side`` (:class:`Phase`): origin below
    the shoulders, x the way the robot will face when up (prone: where its head points;
    supine: where its feet do)."""
    torso = robot.frame_placement(q, "torso")
    yaw = heading_of(torso.rotation, side) + (math.pi if side == "supine" else 0.0)
    kin = Kinematics(robot, q)
    roles = robot.roles
    shoulders = [
        kin.data.oMi[robot.model.getJointId(roles.joint(s, "shoulder_pitch"))].translation
        for s in SIDES
    ]
    p = np.mean(shoulders, axis=0)
    p[2] = 0.0
    return pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), p)


# ---------------------------------------------------------------------- phases
def prone_phases(robot: Robot) -> list[Phase]:
    """The get-up from the front (module docstring), sized from the model's lengths."""
    s = BodySizes.of(robot)
    ys, yh = s.shoulder_y, s.hip_y
    hands_chest = {
        "l_hand": (-0.1 * s.trunk, ys + 0.35 * s.arm, 0.0),
        "r_hand": (-0.1 * s.trunk, -ys - 0.35 * s.arm, 0.0),
    }
    x_toes = -0.1 * s.trunk - 0.8 * s.leg  # the pike: toes drawn in this far behind the hands
    toes_in = {"l_toe": (x_toes, yh, 0.0), "r_toe": (x_toes, -yh, 0.0)}
    return [
        Phase("hands down", ("torso",), 0.8, moves=hands_chest, posture="zero"),
        Phase(
            "push up",
            ("l_hand", "r_hand", "l_toe", "r_toe"),
            1.0,
            torso_pitch=math.radians(60),
            posture="zero",
        ),
        Phase(
            "pike",
            ("l_hand", "r_hand"),
            1.5,
            sliding=("l_toe", "r_toe"),
            torso_pitch=math.radians(150),
            moves=toes_in,
        ),
        Phase(
            "feet flat",
            ("l_hand", "r_hand", "l_toe", "r_toe"),
            0.8,
            flat=("l_sole", "r_sole"),
            torso_pitch=math.radians(150),
        ),
    ] + rise_phases(robot)


def rise_phases(robot: Robot) -> list[Phase]:
    """From hands and feet on the floor to standing: the CoM brought over the feet (the
    hands sliding back), the hands lifted, the rise, a settle re-planned from the state."""
    s = BodySizes.of(robot)
    stand = robot.stand_pose
    return [
        Phase(
            "squat",
            ("l_sole", "r_sole"),
            2.0,
            sliding=("l_hand", "r_hand"),
            com_over=("l_sole", "r_sole"),
            com_shift=-0.1 * s.foot,
            torso_pitch=math.radians(80),
        ),
        Phase(
            "hands up",
            ("l_sole", "r_sole"),
            1.5,
            com_over=("l_sole", "r_sole"),
            com_shift=-0.1 * s.foot,
            posture=stand,
            posture_weight=0.1,
        ),
    ] + stand_phases(robot)


def stand_phases(robot: Robot) -> list[Phase]:
    """From a squat with the CoM over the feet to standing: the rise to the standing pose and
    a settle re-planned from the state."""
    stand = robot.stand_pose
    return [
        Phase(
            "rise",
            ("l_sole", "r_sole"),
            2.5,
            com_over=("l_sole", "r_sole"),
            posture=stand,
            posture_weight=1.0,
        ),
        Phase(
            "settle",
            ("l_sole", "r_sole"),
            1.0,
            com_over=("l_sole", "r_sole"),
            posture=stand,
            posture_weight=1.0,
        ),
    ]


def supine_phases(robot: Robot) -> list[Phase]:
    """The get-up from the back (module docstring), sized from the model's lengths.

    The crossing onto the feet: the feet flat and the knees bent as far as they go, the
    ankles turn the shins forward with the trunk held 50° up (``shins forward``: the CoM to a
    tenth of the foot behind the heels), then the trunk leans back (:data:`CROSS_PITCH`) while
    the hands, sliding behind, carry the rest, until the CoM is :data:`CROSS_AHEAD` of the
    foot's length ahead of the heels (``cross``); only leaning back do the arms reach the
    floor behind the heels with the CoM over the feet (``benchmarks/getup_reach.py``). Then
    the trunk comes forward over the feet (``sit forward``), the hands in the air. Leaning
    back while the shins come forward overloads the arms after a real fall (their shoulder
    rolls at the torque cap, the trunk drops: benchmarks/getup.md)."""
    s = BodySizes.of(robot)
    ys, yh = s.shoulder_y, s.hip_y
    x_hands = 0.4 * s.trunk  # beside the waist: closer to the hips the sit-up fails
    hands = {
        "l_hand": (x_hands, ys + 0.6 * s.arm, 0.0),
        "r_hand": (x_hands, -ys - 0.6 * s.arm, 0.0),
    }
    x_heels = 0.6 * s.trunk + 0.7 * s.leg  # the crab: heels drawn in this far
    heels_in = {"l_heel": (x_heels, yh, 0.0), "r_heel": (x_heels, -yh, 0.0)}
    four = ("l_hand", "r_hand", "l_heel", "r_heel")
    soles = ("l_sole", "r_sole")
    stiff = SUPINE_STIFFNESS
    return [
        Phase("hands down", ("torso",), 0.8, moves=hands, posture="zero", stiffness=stiff),
        Phase("sit up", four, 1.2, torso_pitch=math.radians(-60), posture="zero", stiffness=stiff),
        Phase(
            "crab",
            ("l_hand", "r_hand"),
            1.5,
            sliding=("l_heel", "r_heel"),
            torso_pitch=math.radians(-20),
            moves=heels_in,
            stiffness=stiff,
        ),
        Phase(
            "feet flat",
            four,
            0.8,
            flat=soles,
            torso_pitch=math.radians(-20),
            stiffness=stiff,
        ),
        Phase(
            "shins forward",
            soles,
            2.5,
            sliding=("l_hand", "r_hand"),
            com_over=soles,
            com_shift=-0.6 * s.foot,
            torso_pitch=math.radians(-40),
            stiffness=stiff,
        ),
        Phase(
            "cross",
            soles,
            2.0,
            sliding=("l_hand", "r_hand"),
            com_over=soles,
            com_shift=(CROSS_AHEAD - 0.5) * s.foot,
            torso_pitch=math.radians(CROSS_PITCH),
            stiffness=stiff,
        ),
        Phase(
            "sit forward",
            soles,
            2.0,
            com_over=soles,
            com_shift=-0.1 * s.foot,
            torso_pitch=math.radians(20),
            stiffness=stiff,
        ),
    ] + stand_phases(robot)


def phases_for(robot: Robot, side: str) -> list[Phase]:
    """The phases of a get-up from ``side`` (``prone`` or ``supine``)."""
    if side == "prone":
        return prone_phases(robot)
    if side == "supine":
        return supine_phases(robot)
    raise ConfigurationError(f"get-up: side must be one of {SIDES_LYING}, got {side!r}")


# ---------------------------------------------------------------------- planning
def _is_point(frame: str) -> bool:
    points = (*HAND_FRAMES.values(), *TOE_FRAMES.values(), *HEEL_FRAMES.values())
    return frame in points


def _pitch_rotation(pitch: float, frame: pin.SE3) -> np.ndarray:
    return frame.rotation @ pin.rpy.rpyToMatrix(0.0, pitch, 0.0)


class SupportHullConstraint(Constraint):
    """The CoM's ground projection inside the convex hull of the phase's contacts (points and
    soles' corners) shrunk by ``margin``, the points free to move (a sliding hand): for each
    hull edge (a, b) with outward unit normal n (held fixed over the step),

        n · (c + J_c Δq − (m + J_m Δq)) <= −margin,   m = (a + b) / 2,

    J_m the mean of the two vertices' Jacobians (xy). A CoM outside at the start
    (a phase planned from a measured state) is asked back :func:`~wbc.limits.limit.way_back`
    (a fraction per step, as the floor rows), never further out (:meth:`split`)."""

    held_rows_met = True

    def __init__(
        self,
        robot: Robot,
        points: Sequence[str],
        soles: Sequence[str],
        margin: float = 0.005,
        damping: float = 0.4,
        most: float = 0.002,
    ) -> None:
        super().__init__("support_hull")
        self.robot = robot
        self.margin, self.damping, self.most = margin, damping, most
        corners = sole_corners(*(float(v) for v in robot.foot_size))
        #: (frame id, offset in the frame): the vertices the hull is made of
        self.vertices = [(robot.frame_id(f), np.zeros(3)) for f in points] + [
            (robot.frame_id(f), corner) for f in soles for corner in corners
        ]

    def _rows(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        pts, jacs = [], []
        frames: dict[int, np.ndarray] = {}
        for fid, r in self.vertices:
            R, p = kin.rotation(fid), kin.translation(fid)
            J = frames[fid] if fid in frames else frames.setdefault(fid, kin.frame_jacobian(fid))
            w = R @ r
            # the point's velocity: v + ω × w = J_v − [w]× J_ω
            Jp = J[:3] - np.cross(w, J[3:].T).T if w.any() else J[:3]
            pts.append((p + w)[:2])
            jacs.append(Jp[:2])
        hull = convex_hull(np.asarray(pts))
        if len(hull) < 3:
            return np.zeros((0, kin.model.nv)), np.zeros(0)
        index = [int(np.argmin(np.linalg.norm(np.asarray(pts) - v, axis=1))) for v in hull]
        c, Jc = kin.com[:2], kin.com_jacobian[:2]
        G, h = [], []
        for i, a in enumerate(index):
            b = index[(i + 1) % len(index)]
            e = pts[b] - pts[a]
            n = np.array([e[1], -e[0]]) / np.linalg.norm(e)
            m = 0.5 * (pts[a] + pts[b])
            G.append(n @ (Jc - 0.5 * (jacs[a] + jacs[b])))
            h.append(-self.margin - n @ (c - m))
        return np.asarray(G), np.asarray(h)

    def compute(self, kin: Kinematics) -> Inequality:
        G, h = self._rows(kin)
        out = h < 0.0
        h[out] = way_back(-h[out], self.damping, self.most)
        return Inequality(G, h)

    def split(self, kin: Kinematics, recovering: bool = False) -> tuple[Inequality, Inequality]:
        G, h = self.compute(kin)
        ask = h < 0.0
        return Inequality(G[~ask], h[~ask]), Inequality(G[ask], h[ask])


class PhasePlanner:
    """Plans phases with the QP stack (module docstring) on a copy of the robot with toe and
    heel frames (:attr:`robot`)."""

    def __init__(self, robot: Robot, params: GetupParams | None = None) -> None:
        check_robot(robot)
        self.robot = with_toes(robot)
        self.params = (params or GetupParams()).check()
        #: the torso's and the hips' heights lying (m, at the first plan): the lowest the
        #: plan lets them go (their boxes touch the floor there)
        self.floor: dict[str, float] = {}
        roles = self.robot.roles
        self.body_points = ("torso", *(roles.joint(side, "hip_pitch") for side in SIDES))

    def plan(self, phase: Phase, q0: np.ndarray, ground: pin.SE3) -> PhasePlan:
        """The joint trajectory of ``phase`` from ``q0`` (module docstring)."""
        from ..limits import GroundClearanceConstraint, SelfCollisionConstraint
        from ..solvers import HierarchicalQP, TaskStack
        from ..tasks import (
            ComTask,
            ContactTask,
            FrameOrientationTask,
            FramePositionTask,
            PostureTask,
        )

        robot, p = self.robot, self.params
        kin = Kinematics(robot, q0)
        stack = TaskStack(robot)
        assert stack.velocity_limit is not None
        stack.velocity_limit.scale = p.speed_scale
        stack.level(0, hard=True)
        anchors: dict[str, np.ndarray] = {}
        for frame in phase.contacts:
            if _is_point(frame):
                point = FramePositionTask(robot, frame, name=f"contact_{frame}")
                point.set_target_from(kin)
                stack.add(point, level=0)
            else:
                contact = ContactTask(robot, frame)
                contact.make_contact(kin)
                stack.add(contact, level=0)
            anchors[frame] = kin.translation(robot.frame_id(frame)).copy()
        for frame in phase.sliding:
            slide = FramePositionTask(
                robot, frame, name=f"slide_{frame}", mask=(False, False, True)
            )
            slide.set_target_from(kin)
            stack.add(slide, level=0)
            anchors[frame] = kin.translation(robot.frame_id(frame)).copy()
        stack.add_constraint(
            SelfCollisionConstraint(robot, margin=p.self_collision_margin), level=0
        )
        # the floor: no point frame below it, the torso and hips no lower than they lay
        if not self.floor:
            for f in self.body_points:
                self.floor[f] = float(kin.translation(robot.frame_id(f))[2])
        body = [(f, min(float(kin.translation(robot.frame_id(f))[2]), self.floor[f]))
                for f in self.body_points]  # fmt: skip
        points = (*HAND_FRAMES.values(), *TOE_FRAMES.values(), *HEEL_FRAMES.values())
        for frame, clearance in (*((f, 0.0) for f in points), *body):
            if frame in phase.contacts:
                continue
            stack.add_constraint(
                GroundClearanceConstraint(robot, frame, clearance, length=0.0, width=0.0),
                level=0,
            )
        if phase.quasi_static and p.support_margin is not None:
            bodies = [f for f in (*phase.contacts, *phase.sliding) if not _is_point(f)]
            if bodies and all(f in SOLE_FRAMES.values() for f in bodies):
                on_floor = [f for f in (*phase.contacts, *phase.sliding) if _is_point(f)]
                margin = p.sliding_margin if phase.sliding else p.support_margin
                hull = SupportHullConstraint(robot, on_floor, bodies, margin)
                stack.add_constraint(hull, level=0)
        stack.level(1, hard=False)
        ramps: list[tuple] = []  # (task, start, goal) for positions; rotations separately
        for frame, xyz in phase.moves.items():
            move = FramePositionTask(robot, frame, name=f"move_{frame}", weight=100.0)
            start = kin.translation(robot.frame_id(frame)).copy()
            ramps.append((move, start, ground.act(np.asarray(xyz, dtype=float))))
            stack.add(move, level=1)
        turns: list[tuple] = []
        for frame in phase.flat:
            flat = FrameOrientationTask(robot, frame, name=f"flat_{frame}", weight=10.0)
            turns.append((flat, kin.rotation(robot.frame_id(frame)).copy(), ground.rotation))
            stack.add(flat, level=1)
        if phase.torso_pitch is not None:
            torso = FrameOrientationTask(robot, "torso", name="torso_pitch", weight=10.0)
            pitch_goal = _pitch_rotation(phase.torso_pitch, ground)
            turns.append((torso, kin.rotation(robot.frame_id("torso")).copy(), pitch_goal))
            stack.add(torso, level=1)
        if phase.com_over or phase.com_z is not None:
            mask = (bool(phase.com_over), bool(phase.com_over), phase.com_z is not None)
            com = ComTask(robot, name="com", weight=100.0, mask=mask)
            com_start = kin.com.copy()
            com_goal = com_start.copy()
            if phase.com_over:
                pts = [self._goal_point(f, anchors, phase, ground, kin) for f in phase.com_over]
                centre = np.mean(pts, axis=0)
                com_goal[:2] = centre[:2] + phase.com_shift * ground.rotation[:2, 0]
            if phase.com_z is not None:
                com_goal[2] = phase.com_z
            ramps.append((com, com_start, com_goal))
            stack.add(com, level=1)
        posture = PostureTask(robot, name="posture", weight=phase.posture_weight)
        target = q0 if phase.posture is None else robot.configuration(phase.posture)
        posture.set_target(target)
        stack.add(posture, level=1)
        solver = HierarchicalQP(
            stack, "daqp", regularization=1e-6, on_infeasible="relax", pdas_ties=True
        )
        dt = 1.0 / p.rate
        n = max(1, round(phase.duration * p.rate)) + max(0, round(p.hold_s * p.rate))
        ts, qs = [0.0], [q0.copy()]
        q = q0.copy()
        failed = 0
        for k in range(1, n + 1):
            s = smooth(k * dt / phase.duration) if phase.duration > 0 else 1.0
            for task, a, b in ramps:
                task.set_target(a + s * (b - a))
            for task, a, b in turns:
                task.set_target(a @ pin.exp3(s * pin.log3(a.T @ b)))
            try:
                q = solver.step(q, dt)
            except WbcError:
                failed += 1
            ts.append(k * dt)
            qs.append(q.copy())
        return PhasePlan(phase, np.asarray(ts), np.asarray(qs), anchors, failed)

    def _goal_point(self, frame, anchors, phase, ground, kin) -> np.ndarray:
        if frame in anchors:
            return anchors[frame]
        if frame in phase.moves:
            return ground.act(np.asarray(phase.moves[frame], dtype=float))
        return kin.translation(self.robot.frame_id(frame)).copy()


def plan_getup(
    robot: Robot, q0: np.ndarray, side: str, params: GetupParams | None = None
) -> list[PhasePlan]:
    """The whole get-up from ``q0`` lying on ``side``, planned open loop (each phase from the
    planned end of the previous one)."""
    planner = PhasePlanner(robot, params)
    ground = ground_frame(q0, planner.robot, side)
    plans = []
    q = np.asarray(q0, dtype=float)
    for phase in phases_for(robot, side):
        plan = planner.plan(phase, q, ground)
        plans.append(plan)
        q = plan.q[-1]
    return plans


def static_torques(robot: Robot, q: np.ndarray, phase: Phase) -> np.ndarray:
    """Static joint torques (N·m) holding ``q`` on the phase's contacts::

        τ = g_j(q) − J_c,jᵀ f,   f the least-norm solution of  J_c,bᵀ f = g_b(q)

    (``b``: the floating base's 6 rows; soles and the torso carry 6-D wrenches, points —
    hands, toes, heels, sliding or held — 3-D forces), as
    :meth:`wbc.balance.compliance.ComplianceCompensator.torques` for the soles. ``robot``
    must have the toe and heel frames (:func:`with_toes`)."""
    m = robot.model
    d = m.createData()
    g = pin.computeGeneralizedGravity(m, d, q)
    pin.computeJointJacobians(m, d, q)
    pin.updateFramePlacements(m, d)
    rows = []
    for frame in (*phase.contacts, *phase.sliding):
        J = pin.getFrameJacobian(m, d, robot.frame_id(frame), pin.LOCAL_WORLD_ALIGNED)
        rows.append(J[:3] if _is_point(frame) else J)
    if not rows:
        return g[6:].copy()
    jc = np.vstack(rows)
    f = np.linalg.lstsq(jc[:, :6].T, g[:6], rcond=None)[0]
    return g[6:] - jc[:, 6:].T @ f


def joint_speeds(plan: PhasePlan) -> np.ndarray:
    """The largest |q̇| of each joint over a planned phase (rad/s)."""
    if len(plan.t) < 2:
        return np.zeros(plan.q.shape[1] - 7)
    return np.max(np.abs(np.diff(plan.q[:, 7:], axis=0)) / np.diff(plan.t)[:, None], axis=0)


__all__: Sequence[str] = (
    "BodySizes",
    "GetupParams",
    "Phase",
    "PhasePlan",
    "PhasePlanner",
    "SupportHullConstraint",
    "ground_frame",
    "lying_side",
    "lying_state",
    "phases_for",
    "plan_getup",
    "static_torques",
    "with_toes",
)
