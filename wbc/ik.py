"""Closed-form inverse kinematics of the Bioloid legs and arms (CoM-control thesis, ch. 2.3).

The thesis solves each limb on its own and chains them into a whole-body IK:

* **Leg, 6 DOF, kinematic decoupling.** Hip yaw (z), hip roll (x) and hip pitch (y) meet at
  the hip centre H, and ankle pitch (y) and ankle roll (x) meet at the ankle centre A. The
  *position* problem is solved by the three joints nearest the ground (ankle roll, ankle pitch,
  knee): they must bring H to its place seen from the foot. The *orientation* problem is then
  the Euler angles of the remaining hip rotation.
* **Arm, 3 DOF, geometric.** Position of the hand only.
* **Whole body.** Support leg first, then swing leg, then both arms, all targets relative to
  the support sole.

What is changed with respect to the thesis, and why
---------------------------------------------------
The thesis works in its DH frames and assumes a thigh and a shin of equal length, aligned when
the knee is at zero (eqs. 2.18-2.26: ``cos γ = (h² - 2 l²) / (-2 l²)``, ``θ3 = π - γ``). Our
URDF (``robots/bioloid/make_urdf.py``) has every link frame parallel to the torso at q = 0 and
every axis +x, +y or +z, and its leg is neither symmetric nor straight at q = 0: the thigh
offset hip→knee is t1 = (-14.5, 0, -75) mm (|t1| = 76.39 mm) and the shin offset knee→ankle is
t2 = (+14.5, 0, -71) mm (|t2| = 72.47 mm). Writing φ(u) = atan2(-u_x, -u_z) for the pitch angle
of a vector u of the sagittal plane (so that φ(R_y(θ) u) = φ(u) + θ), the law of cosines with
two lengths gives

    |A - H|² = |t1|² + |t2|² + 2 |t1| |t2| cos(q_knee - δ),   δ = φ(t1) - φ(t2) ≈ 22.5°,

so the leg is *stretched* at q_knee = δ, not at 0 (at q = 0 the knee sits 14.5 mm behind the
hip-ankle line). The two knee branches are q_knee = δ ± acos(·). We return the
**knee-forward** branch q_knee = δ + acos(·) ≥ δ (knee in front of the hip-ankle line, positive
flexion as in Walk Ready); if that branch breaks a joint limit and the knee-back branch
q_knee = δ - acos(·) does not (possible only for 0 ≤ q_knee < δ), the knee-back branch is
returned. The thesis reads the orientation as ZYZ Euler angles of R_3^6; our hip is a yaw-roll-
pitch chain, R_hip = R_z(q_yaw) R_x(q_roll) R_y(q_pitch), so we read ZXY angles with
cos(q_roll) > 0 (the hip-roll limits are well inside ±90°). The ankle roll follows from the
hip centre seen in the foot frame, d = R_foot^T (H - A): q_ankle_roll = atan2(d_y, d_z) when
the hip is above the foot plane, or the solution 180° away, atan2(-d_y, -d_z), when it is
below (a leg swung far forward with the foot pitched up; both cannot be within the ±50°
ankle-roll limits); then the ankle pitch from the sagittal angle of d. The candidates are
tried in the order (hip above, knee forward), (above, back), (below, forward), (below, back)
and the first one within the joint limits is returned.

The arm (shoulder pitch y at S → roll x → elbow x → hand) has a 14 mm *downward* offset
between the pitch axis and the roll joint (o = (0, ±44, -14) mm), which the thesis's arm
(eqs. 2.31-2.41, L3 along the pitch axis) does not have. With p = hand - S, the roll and elbow
keep the arm in the plane x = 0 of the shoulder bracket, so R_y(q_pitch)^T p = (0, p_y, ±ρ)
with ρ = √(p_x² + p_z²): two pitch branches, q_pitch = atan2(±p_x, ±p_z). In that plane the
roll→hand vector e = (p_y, ±ρ) - (o_y, o_z) is reached by a planar 2-link chain (upper arm
67.5 mm, forearm 74.5 mm) with two elbow branches. Of these four candidates (each shoulder
pitch also taken modulo 2π into its 300° range) :func:`arm_ik` returns the one within the
joint limits that is nearest to ``q_ref`` (default: zero, the T-pose; pass the previous
angles for continuity along a trajectory). With ``check_limits=False`` the nearest candidate
is returned whatever the limits.

Everything is closed form (numpy + ``pinocchio.SE3``); the geometry is read from the
Pinocchio model and checked against the structure assumed here (a :class:`ModelError` names
what differs).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .exceptions import IKError, ModelError
from .geometry import wrap_angle
from .model import Robot
from .roles import ARM_ROLES, LEG_ROLES

__all__ = ["arm_ik", "leg_ik", "whole_body_ik"]

#: the limbs' joints by role (:mod:`wbc.roles`: found from the kinematic tree, not by name)
LEG_JOINTS = LEG_ROLES
ARM_JOINTS = ARM_ROLES
_SIDES = {"left": "l", "l": "l", "right": "r", "r": "r"}
_SIDE_NAMES = {"l": "left", "r": "right"}

LIMIT_TOL = 1e-9  # rad: a solution this close outside a limit is clipped onto it
REACH_TOL = 1e-12  # relative: |cos| up to 1 + REACH_TOL is rounding, clipped to 1
SINGULAR_TOL = 1e-9  # m (or unitless for matrix entries): below this an angle is undetermined


# ------------------------------------------------------------------------------ geometry
@dataclass(frozen=True)
class _Limb:
    name: str  # "left leg"
    joints: tuple[str, ...]  # model joint names, chain order
    index: np.ndarray  # indices in the actuated-joint vector
    lo: np.ndarray
    hi: np.ndarray


@dataclass(frozen=True)
class _LegGeometry(_Limb):
    hip: np.ndarray  # hip centre in the torso frame
    thigh: np.ndarray  # hip centre -> knee, sagittal (y = 0)
    shin: np.ndarray  # knee -> ankle centre, sagittal (y = 0)
    sole: pin.SE3  # ankle-roll joint frame -> sole frame
    delta: float  # knee angle at which the leg is stretched

    @property
    def reach(self) -> tuple[float, float]:
        a, b = np.linalg.norm(self.thigh), np.linalg.norm(self.shin)
        return abs(a - b), a + b


@dataclass(frozen=True)
class _ArmGeometry(_Limb):
    shoulder: np.ndarray  # shoulder-pitch joint in the torso frame
    offset: np.ndarray  # pitch joint -> roll joint (y, z), x = 0
    upper: np.ndarray  # roll joint -> elbow (y, z)
    fore: np.ndarray  # elbow -> hand frame (y, z)

    @property
    def reach(self) -> tuple[float, float]:
        a, b = np.linalg.norm(self.upper), np.linalg.norm(self.fore)
        return abs(a - b), a + b


_CACHE: weakref.WeakKeyDictionary[Robot, dict[str, _Limb]] = weakref.WeakKeyDictionary()


def _side(side: str) -> str:
    if not isinstance(side, str) or side.lower() not in _SIDES:
        raise IKError(f"unknown side {side!r}; use 'left' or 'right'")
    return _SIDES[side.lower()]


def _pitch_angle(u: np.ndarray) -> float:
    """φ(u) = atan2(-u_x, -u_z): pitch of a sagittal vector, 0 pointing down, φ(R_y(θ)u) = φ+θ."""
    return math.atan2(-u[0], -u[2])


def _chain(robot: Robot, prefix: str, names: tuple[str, ...], kinds: tuple[str, ...]):
    model = robot.model
    ids = []
    joints = []
    parent = 1  # the free-flyer joint, whose frame is the torso frame
    for name, kind in zip(names, kinds, strict=True):
        full = robot.roles.get(_SIDE_NAMES[prefix], name)
        if full is None or not model.existJointName(full):
            raise ModelError(f"{robot.name}: analytic IK needs a {_SIDE_NAMES[prefix]} {name}")
        joints.append(full)
        jid = model.getJointId(full)
        if model.joints[jid].shortname() != f"JointModel{kind}":
            raise ModelError(
                f"{robot.name}: analytic IK needs {full} to be a revolute joint about "
                f"{kind[1].lower()} (got {model.joints[jid].shortname()})"
            )
        if model.parents[jid] != parent:
            raise ModelError(f"{robot.name}: {full} does not follow {model.names[parent]}")
        if not np.allclose(model.jointPlacements[jid].rotation, np.eye(3)):
            raise ModelError(f"{robot.name}: analytic IK needs {full} parallel to its parent")
        ids.append(jid)
        parent = jid
    torso = model.frames[robot.frame_id("torso")]
    if torso.parentJoint != 1 or not torso.placement.isIdentity():
        raise ModelError(f"{robot.name}: the torso frame must be the free-flyer joint frame")
    index = np.array([robot.joint_index(j) for j in joints])
    return ids, tuple(joints), index


def _placement(robot: Robot, jid: int) -> np.ndarray:
    return np.array(robot.model.jointPlacements[jid].translation)


def _require(cond: bool, robot: Robot, what: str) -> None:
    if not cond:
        raise ModelError(f"{robot.name}: analytic IK assumes {what}")


def _leg_geometry(robot: Robot, prefix: str) -> _LegGeometry:
    ids, joints, index = _chain(robot, prefix, LEG_JOINTS, ("RZ", "RX", "RY", "RY", "RY", "RX"))
    yaw, roll, pitch, knee, ankle_pitch, ankle_roll = (_placement(robot, j) for j in ids)
    _require(np.allclose(roll[:2], 0), robot, f"{joints[1]} on the hip-yaw axis")
    _require(np.allclose(pitch, 0), robot, f"{joints[2]} at the {joints[1]} joint")
    _require(np.isclose(knee[1], 0), robot, f"{joints[3]} offset in the sagittal plane")
    _require(np.isclose(ankle_pitch[1], 0), robot, f"{joints[4]} offset in the sagittal plane")
    _require(np.allclose(ankle_roll, 0), robot, f"{joints[5]} at the {joints[4]} joint")
    sole = robot.model.frames[robot.frame_id(f"{prefix}_sole")]
    _require(sole.parentJoint == ids[5], robot, f"{prefix}_sole attached to {joints[5]}")
    thigh, shin = knee, ankle_pitch
    return _LegGeometry(
        name=f"{_SIDE_NAMES[prefix]} leg",
        joints=joints,
        index=index,
        lo=robot.q_min[index],
        hi=robot.q_max[index],
        hip=yaw + roll,
        thigh=thigh,
        shin=shin,
        sole=pin.SE3(sole.placement),
        delta=_pitch_angle(thigh) - _pitch_angle(shin),
    )


def _arm_geometry(robot: Robot, prefix: str) -> _ArmGeometry:
    ids, joints, index = _chain(robot, prefix, ARM_JOINTS, ("RY", "RX", "RX"))
    shoulder, offset, upper = (_placement(robot, j) for j in ids)
    hand = robot.model.frames[robot.frame_id(f"{prefix}_hand")]
    _require(hand.parentJoint == ids[2], robot, f"{prefix}_hand attached to {joints[2]}")
    fore = np.array(hand.placement.translation)
    for vec, what in ((offset, joints[1]), (upper, joints[2]), (fore, f"{prefix}_hand")):
        _require(np.isclose(vec[0], 0), robot, f"{what} offset in the plane x = 0")
    return _ArmGeometry(
        name=f"{_SIDE_NAMES[prefix]} arm",
        joints=joints,
        index=index,
        lo=robot.q_min[index],
        hi=robot.q_max[index],
        shoulder=shoulder,
        offset=offset[1:],
        upper=upper[1:],
        fore=fore[1:],
    )


def _geometry(robot: Robot, limb: str, prefix: str):
    cache = _CACHE.setdefault(robot, {})
    key = f"{prefix}_{limb}"
    if key not in cache:
        try:
            cache[key] = (
                _leg_geometry(robot, prefix) if limb == "leg" else _arm_geometry(robot, prefix)
            )
        except ModelError as exc:  # another robot's limbs: the numerical IK serves any
            raise ModelError(
                f"{exc} (this closed form is the Bioloid's; for other robots use "
                "wbc.pose_ik.StanceIK)"
            ) from None
    return cache[key]


# ------------------------------------------------------------------------------ helpers
def _check_se3(target, what: str) -> pin.SE3:
    if not isinstance(target, pin.SE3):
        raise IKError(f"{what}: expected a pinocchio.SE3, got {type(target).__name__}")
    R, p = target.rotation, target.translation
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(p))):
        raise IKError(f"{what}: target has non-finite values")
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        raise IKError(f"{what}: target rotation is not a rotation matrix")
    return target


def _check_point(target, what: str) -> np.ndarray:
    try:
        p = np.asarray(target, dtype=float)
    except (TypeError, ValueError):
        raise IKError(f"{what}: expected a 3-vector, got {target!r}") from None
    if p.shape != (3,):
        raise IKError(f"{what}: expected a 3-vector, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise IKError(f"{what}: target has non-finite values {p}")
    return p


def _into_limits(q: np.ndarray, limb: _Limb) -> np.ndarray:
    """Each angle wrapped into (-π, π], then shifted by ±2π if only that lies in its limits."""
    out = wrap_angle(q)
    if _valid(out, limb):
        return out
    for i, a in enumerate(out):
        if not _inside(a, limb, i):
            for b in (a - 2.0 * math.pi, a + 2.0 * math.pi):
                if _inside(b, limb, i):
                    out[i] = b
                    break
    return out


def _inside(a: float, limb: _Limb, i: int) -> bool:
    return limb.lo[i] - LIMIT_TOL <= a <= limb.hi[i] + LIMIT_TOL


def _valid(q: np.ndarray, limb: _Limb) -> bool:
    return bool(np.all(q >= limb.lo - LIMIT_TOL) and np.all(q <= limb.hi + LIMIT_TOL))


def _violations(q: np.ndarray, limb: _Limb) -> list[str]:
    return [
        f"{name} = {a:.3f} rad outside limits [{lo:.3f}, {hi:.3f}] rad"
        for i, (name, a, lo, hi) in enumerate(zip(limb.joints, q, limb.lo, limb.hi, strict=True))
        if not _inside(a, limb, i)
    ]


def _select(
    candidates: Iterable[np.ndarray], limb: _Limb, check_limits: bool, none_reason: str = ""
) -> np.ndarray:
    """First candidate (preference order) within the limits, clipped onto them.

    With ``check_limits=False`` the first candidate is returned as is. ``candidates`` may be
    a generator: later candidates are only computed when the earlier ones are rejected.
    """
    seen = []
    for q in candidates:
        if not check_limits:
            return q
        if _valid(q, limb):
            return np.clip(q, limb.lo, limb.hi)
        seen.append(q)
    if not seen:
        raise IKError(f"{limb.name}: {none_reason or 'no solution'}")
    reasons = "; ".join(", ".join(_violations(q, limb)) for q in seen)
    raise IKError(f"{limb.name}: no solution within the joint limits ({reasons})")


def _acos_checked(c: float, limb: _Limb, what: str, dist: float, reach: tuple) -> float:
    if c > 1.0 + REACH_TOL:
        raise IKError(f"{limb.name}: {what} distance {dist:.3f} m exceeds reach {reach[1]:.3f} m")
    if c < -1.0 - REACH_TOL:
        raise IKError(
            f"{limb.name}: {what} distance {dist:.4f} m is inside the minimum reach "
            f"{reach[0]:.4f} m"
        )
    return math.acos(min(1.0, max(-1.0, c)))


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot2(a: float, v: np.ndarray) -> np.ndarray:
    """Rotation by a in the (y, z) plane: what R_x(a) does to (y, z)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


# ------------------------------------------------------------------------------ leg
def leg_ik(
    robot: Robot, side: str, sole_in_torso: pin.SE3, check_limits: bool = True
) -> np.ndarray:
    """Joint angles of one leg placing its sole at ``sole_in_torso`` (torso frame).

    Returns the 6 angles in model order (hip_yaw, hip_roll, hip_pitch, knee, ankle_pitch,
    ankle_roll): the knee-forward branch (knee ≥ δ, see the module docstring), or the
    knee-back branch if only that one is within the limits. Raises :class:`IKError` if the
    hip-ankle distance is out of reach, at a singularity (hip centre on the ankle-roll axis,
    hip roll at ±90°), or, with ``check_limits``, if no branch is within the joint limits
    (``check_limits=False`` returns the first branch -- hip above the foot plane, knee
    forward -- whatever the limits). Angles within 1e-9 rad outside a limit are clipped onto it.

    With the foot (ankle-roll joint) frame F = sole ⊗ sole_offset⁻¹ = (R, A) and the hip
    centre H, d = Rᵀ(H - A) and

        q_ankle_roll = atan2(±d_y, ±d_z),   w = (d_x, 0, ±√(d_y² + d_z²)),
        q_knee = δ ± acos((|d|² - |t1|² - |t2|²) / (2 |t1| |t2|)),
        q_ankle_pitch = φ(t1 + R_y(q_knee) t2) + π - q_knee - φ(w),
        R_z(q_yaw) R_x(q_roll) R_y(q_hip_pitch) = R R_x(q_ankle_roll)ᵀ R_y(q_knee + q_ankle_pitch)ᵀ.
    """
    prefix = _side(side)
    geo: _LegGeometry = _geometry(robot, "leg", prefix)
    target = _check_se3(sole_in_torso, geo.name)
    foot = target * geo.sole.inverse()
    R, ankle = foot.rotation, foot.translation
    d = R.T @ (geo.hip - ankle)

    rho = math.hypot(d[1], d[2])
    if rho < SINGULAR_TOL:
        raise IKError(f"{geo.name}: singular, the hip centre lies on the ankle-roll axis")
    dist = float(np.linalg.norm(d))
    l1, l2 = np.linalg.norm(geo.thigh), np.linalg.norm(geo.shin)
    c = (dist * dist - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    bend = _acos_checked(c, geo, "hip-ankle", dist, geo.reach)

    singular = "singular, hip roll at ±90° (hip yaw and pitch axes aligned)"
    return _select(_leg_candidates(geo, R, d, rho, bend), geo, check_limits, singular)


def _leg_candidates(geo: _LegGeometry, R: np.ndarray, d: np.ndarray, rho: float, bend: float):
    """Leg solutions in preference order: hip above the foot plane (ankle roll within ±90°)
    before below, knee forward before knee back. Gimbal-locked ones (hip roll ±90°) are
    skipped."""
    for wz in (rho, -rho):
        q_ar = math.atan2(d[1] / wz, d[2] / wz)
        w = np.array([d[0], 0.0, wz])  # = R_x(q_ar) d
        for q_knee in (geo.delta + bend, geo.delta - bend) if bend > 0.0 else (geo.delta,):
            v = geo.thigh + _ry(q_knee) @ geo.shin
            q_ap = wrap_angle(_pitch_angle(v) + math.pi - q_knee - _pitch_angle(w))
            R_hip = R @ _rx(q_ar).T @ _ry(q_knee + q_ap).T
            cos_roll = math.hypot(R_hip[2, 0], R_hip[2, 2])
            if cos_roll < SINGULAR_TOL:
                continue
            q_yaw = math.atan2(-R_hip[0, 1], R_hip[1, 1])
            q_roll = math.atan2(R_hip[2, 1], cos_roll)
            q_hp = math.atan2(-R_hip[2, 0], R_hip[2, 2])
            yield _into_limits(np.array([q_yaw, q_roll, q_hp, q_knee, q_ap, q_ar]), geo)


# ------------------------------------------------------------------------------ arm
def arm_ik(
    robot: Robot,
    side: str,
    hand_in_torso: np.ndarray,
    check_limits: bool = True,
    q_ref: np.ndarray | None = None,
) -> np.ndarray:
    """Joint angles (shoulder_pitch, shoulder_roll, elbow) putting the hand frame's origin at
    ``hand_in_torso`` (3-vector, torso frame).

    Of the (up to) four solutions -- shoulder-pitch branch × elbow branch, see the module
    docstring -- returns the one within the limits nearest to ``q_ref`` (3 angles, default
    zero = T-pose) in Euclidean joint distance. Raises :class:`IKError` if the target is out of
    reach, on the shoulder-pitch axis (pitch undetermined), or, with ``check_limits``, if no
    solution is within the limits (``check_limits=False`` then returns the nearest one).
    """
    prefix = _side(side)
    geo: _ArmGeometry = _geometry(robot, "arm", prefix)
    p = _check_point(hand_in_torso, geo.name) - geo.shoulder
    ref = np.zeros(3) if q_ref is None else _check_point(q_ref, f"{geo.name}: q_ref")

    rho = math.hypot(p[0], p[2])
    if rho < SINGULAR_TOL:
        raise IKError(f"{geo.name}: singular, the hand lies on the shoulder-pitch axis")
    l1, l2 = np.linalg.norm(geo.upper), np.linalg.norm(geo.fore)
    # angle of the forearm relative to the upper arm at q_elbow = 0
    elbow0 = math.atan2(geo.fore[1], geo.fore[0]) - math.atan2(geo.upper[1], geo.upper[0])

    candidates: list[np.ndarray] = []
    dists = []
    for bz in (-rho, rho):  # height of the hand in the shoulder-bracket frame: pitch branch
        q_pitch = math.atan2(p[0] / bz, p[2] / bz)
        e = np.array([p[1], bz]) - geo.offset  # roll joint -> hand, in the (y, z) plane
        dist = float(np.linalg.norm(e))
        dists.append(dist)
        c = (dist * dist - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
        if abs(c) > 1.0 + REACH_TOL:
            continue
        if dist < SINGULAR_TOL:
            raise IKError(f"{geo.name}: singular, the hand lies on the shoulder-roll axis")
        bend = math.acos(min(1.0, max(-1.0, c)))
        for q_elbow in (bend - elbow0, -bend - elbow0) if bend > 0.0 else (-elbow0,):
            arm = geo.upper + _rot2(q_elbow, geo.fore)
            q_roll = math.atan2(e[1], e[0]) - math.atan2(arm[1], arm[0])
            candidates.append(_into_limits(np.array([q_pitch, q_roll, q_elbow]), geo))
    if not candidates:
        lo, hi = geo.reach
        raise IKError(
            f"{geo.name}: hand out of reach: shoulder-roll-joint-to-hand distance "
            f"{dists[0]:.4f} m or {dists[1]:.4f} m (the two shoulder-pitch branches) is "
            f"outside the reach [{lo:.4f}, {hi:.4f}] m"
        )
    candidates.sort(key=lambda q: float(np.linalg.norm(q - ref)))
    if check_limits:
        candidates.sort(key=lambda q: not _valid(q, geo))  # stable: valid ones first
    return _select(candidates, geo, check_limits)


# ------------------------------------------------------------------------------ whole body
def whole_body_ik(
    robot: Robot,
    support: str,
    torso_in_support: pin.SE3,
    swing_in_support: pin.SE3 | None = None,
    hands_in_support: Mapping[str, np.ndarray] | None = None,
    q_init: np.ndarray | None = None,
    support_in_world: pin.SE3 | None = None,
    check_limits: bool = True,
) -> np.ndarray:
    """Full configuration (nq) from targets relative to the support sole (thesis §2.3.3).

    * ``support``: ``"left"`` or ``"right"``; its sole is placed at ``support_in_world``
      (default identity: the world origin, flat), and the floating base follows as
      ``support_in_world * torso_in_support``.
    * ``torso_in_support``: torso pose in the support-sole frame; solved by the support leg.
    * ``swing_in_support``: the other sole's pose in the support-sole frame, or ``None`` to keep
      the swing-leg angles of ``q_init``.
    * ``hands_in_support``: ``{"left": xyz, "right": xyz}`` (either key optional) hand positions
      in the support-sole frame; each arm takes the solution nearest to its ``q_init`` angles.
      Arms without a target keep their ``q_init`` angles.
    * ``q_init``: configuration providing the untargeted joints (default: all joints zero).

    Raises :class:`IKError` (naming the limb) if a target is unreachable or out of limits.
    """
    sup = _side(support)
    swing = "r" if sup == "l" else "l"
    torso_in_support = _check_se3(torso_in_support, "torso target")
    if support_in_world is None:
        support_in_world = pin.SE3.Identity()
    support_in_world = _check_se3(support_in_world, "support sole placement")
    q = robot.neutral() if q_init is None else robot.check_configuration(q_init, "q_init").copy()
    joints = q[7:]
    support_in_torso = torso_in_support.inverse()

    leg = _geometry(robot, "leg", sup)
    joints[leg.index] = leg_ik(robot, sup, support_in_torso, check_limits)
    if swing_in_support is not None:
        swing_in_support = _check_se3(swing_in_support, f"{_SIDE_NAMES[swing]} leg")
        leg = _geometry(robot, "leg", swing)
        joints[leg.index] = leg_ik(robot, swing, support_in_torso * swing_in_support, check_limits)
    if hands_in_support is not None and not isinstance(hands_in_support, Mapping):
        raise IKError(
            f"hands_in_support: expected a mapping side -> xyz, got {type(hands_in_support)}"
        )
    for key, target in (hands_in_support or {}).items():
        prefix = _side(key)
        arm = _geometry(robot, "arm", prefix)
        point = _check_point(target, arm.name)
        joints[arm.index] = arm_ik(
            robot, prefix, support_in_torso.act(point), check_limits, q_ref=joints[arm.index]
        )
    q[:7] = pin.SE3ToXYZQUAT(support_in_world * torso_in_support)
    return robot.check_configuration(q)
