"""State estimate of a walking robot from what a Bioloid-class robot senses.

Inputs per control tick: the servos' present positions (encoders, rad) and, optionally, a torso
IMU (:class:`wbc.imu.Imu`: gyro + accelerometer). Output (:class:`StateEstimate`): the torso
(base) orientation, the base position, the CoM, its velocity and the DCM.

**Orientation** (with an IMU) — a complementary filter on SO(3): integrate the gyro and pull
the predicted "up" direction toward the accelerometer's specific force::

    R ← R · Exp((ω + k_a · (u_m × u_p)) · dt)     u_m = a/|a|,  u_p = Rᵀ e_z

(``k_a`` the tilt gain, 1/s; the correction is skipped when |a| is not within 20 % of g,
i.e. during impacts). With ``bias_gain`` ``k_b`` > 0 the correction's integral is added to
the gyro (Mahony's filter: ``b ← b + k_b (u_m × u_p) dt``, ``ω + b`` everywhere the gyro is
used): the bias the calibration at rest left about the horizontal axes, which otherwise
tilts the estimate by ``b / k_a`` for good (a robot rocking at rest: 0.05 rad/s, 14° on a
randomised Bioloid, benchmarks/drive.md). Only roll and pitch are observable this way;
the heading (yaw) is taken from the encoders (below), so a gyro's yaw drift never reaches
the controller, unless
``gyro_heading`` (the integrated gyro's heading: it sees the feet's yaw slip, and drifts
with the gyro's bias).

**The soles' heading** (``kin_heading``, off; with ``gyro_heading``): the kinematic terms
below (base, CoM, its velocity, the DCM) at the kinematics' heading (the stance sole where
the plan turned it) while the torso's rotation keeps the gyro's: soles that slipped round by
``δ`` leave a robot balanced about them, whose CoM lead along the walk ``a`` the gyro's frame
reads as a sideways ``a sin δ``; ``kin_band`` (rad): only the slip beyond it (issue 30).

**Encoders only** (``imu=None``): the stance sole is assumed flat at its planned placement;
``R_base = R_sole · (ᵇR_sole)ᵀ`` with ``ᵇR_sole`` from forward kinematics of the present joints.

**IMU + commanded joints** (a bus that reads no positions: hobby PWM servos behind an
SSC-32; chosen by :func:`wbc.balance.live.closed_loop`, which says so in one line): the
orientation as above, and every kinematic term (base, CoM, stance soles) from the *commanded*
joints — the controller's last solve, passed as ``fallback`` with every present position
unread. Not corrected for the servo law's lag; its compliance only through the feed-forward
(the goals sent are the solve plus the model's expected sag, so the solve is where the
nominal servo model expects the joints to be).

**CoM**: with the base rotation ``R`` and the stance sole(s) anchored at their planned
placement, ``p_base = p_sole − R · ᵇp_sole`` (averaged over both soles in double support) and
``c = p_base + R · ᵇc``. **CoM velocity**: the time derivative of the CoM *relative to the
stance sole(s)*, ``d/dt (R (ᵇc − ᵇp_sole))`` (so a support switch never makes it jump),
low-pass filtered (first order, ``velocity_cutoff`` Hz, against the 0.29° encoder steps).
**DCM** ``ξ = c + ċ / ω₀`` with ``ω₀ = √(g / z_c)``. With ``joint_lag`` (the deployment
reads the servos right after writing the goals, so the joints are a tick older than the IMU
sample) these kinematic terms use the filter's rotation of the joints' tick: a fresh rotation
on stale joints reads a body rocking at ω as a CoM moving by ``ω × (c − p_sole)`` every tick,
and its derivative as a CoM velocity (issue 30: 20–40 mm of false DCM on stiff plants with
latency, ringing at a few Hz).

**The landed sole** (``anchor_band`` > 0; off by default): a sole that enters the support
is anchored where the estimate of the tick before and the present joints put it (its
height and rotation the plan's) when that is more than ``anchor_band`` from its planned
placement, until it lifts again. A pushed robot's swing sole lands off its plan (12–20 mm
ahead after a 0.7 N·s forward push); anchored at the plan, the base and DCM estimates jump by
that much at touch-down and read behind the robot for the whole next step (issue 30).

**The support the soles show** (``contact_band`` > 0; off by default): before each estimate,
:meth:`StateEstimator.contact` puts both soles' lowest points (their corners) in the world
with the last estimate's rotation (the IMU's) and the present joints (the encoders'): what
a robot senses of which sole is down, no force sensor needed. A sole more than the band above
the other carries no weight: the planned support soles that are down carry it, and when none
is (a pushed robot still standing on the sole the plan swings), the sole that is down does,
anchored where the estimate put it (continuous) until it leaves the support. The step
adjuster's early touch-down (:mod:`.stepping`, ``touchdown``) reads it.

**Cost** (it runs inside every control tick): one compiled kernel per tick
(:func:`_estimate`) does the forward kinematics of the revolute joints in the base frame
(``ᵇc = Σ m_k ᵇp_com,k / M`` and the stance soles), the filter and the CoM terms, with no
pinocchio call and no small numpy operation; it gives pinocchio's answer to rounding
(tests/test_balance_estimator.py). Figures: benchmarks/compliance.md (cost section).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numba
import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, ModelError
from ..geometry import sole_corners
from ..imu import GRAVITY, ImuReading
from ..model import Robot
from ..roles import SOLE_FRAMES as _SOLE_BY_SIDE
from ..roles import joint_axis

#: the soles' frames in the estimator's order, left first (:data:`wbc.roles.SOLE_FRAMES`)
SOLE_FRAMES = (_SOLE_BY_SIDE["left"], _SOLE_BY_SIDE["right"])
# columns of a joint's row in the kinematic table (StateEstimator._joints)
_R, _P, _AXIS, _LEVER, _MASS, _WIDTH = 0, 9, 12, 15, 18, 19
# the filter's state (StateEstimator._state): torso rotation, has-rotation flag, CoM relative
# to each sole at the last tick, their validity flags, the CoM velocity, the gyro's bias
# correction learnt (``bias_gain``)
_S_ROT, _S_HAS, _S_REL, _S_VALID, _S_VEL, _S_BIAS, _S_SIZE = 0, 9, 10, 16, 18, 21, 24
# the constants (the tail of StateEstimator._model, after the joints' table and links): the
# accelerometer's tilt gain, the CoM velocity cutoff (Hz), ω₀, gyro_heading (1/0), 1 / mass,
# the torso's rotation in the base frame (9), per sole (SOLE_FRAMES order, _SOLE_WIDTH each:
# its rotation in its parent body (9), position (3), the parent's row), kin_gain, bias_gain
_C_TILT, _C_CUTOFF, _C_OMEGA0, _C_HEADING, _C_INV_MASS, _C_TORSO, _C_SOLES = 0, 1, 2, 3, 4, 5, 14
_SOLE_WIDTH = 13
_C_LAG = _C_SOLES + _SOLE_WIDTH * len(SOLE_FRAMES)
_C_KIN = _C_LAG + 1
_C_BIAS, _C_FRAME, _C_SIZE = _C_KIN + 1, _C_KIN + 2, _C_KIN + 4  # (kin_heading, kin_band)


class StateEstimate:
    """One estimate (world frame; the torso is the IMU frame): named views of one (8, 3)
    array, fresh every tick (building six arrays per tick would cost more than the
    estimate)."""

    __slots__ = ("values",)

    def __init__(self, values: np.ndarray) -> None:
        self.values = values  # rows: rotation (3), base, com, com_vel, dcm, angular_velocity

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) torso rotation."""
        return self.values[:3]

    @property
    def base(self) -> np.ndarray:
        """(3,) base position."""
        return self.values[3]

    @property
    def com(self) -> np.ndarray:
        """(3,) centre of mass."""
        return self.values[4]

    @property
    def com_vel(self) -> np.ndarray:
        """(3,) CoM velocity (filtered)."""
        return self.values[5]

    @property
    def dcm(self) -> np.ndarray:
        """(3,) ξ = c + ċ/ω₀ (z: c_z)."""
        return self.values[6]

    @property
    def angular_velocity(self) -> np.ndarray:
        """(3,) rad/s, torso frame (zeros without an IMU)."""
        return self.values[7]

    def __repr__(self) -> str:
        return f"StateEstimate(com={self.com}, dcm={self.dcm}, base={self.base})"


@numba.njit(cache=True, inline="always")
def mul33_into(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """C = A · B (3 × 3; the top-left block of larger matrices; C distinct from A, B)."""
    for i in range(3):
        for j in range(3):
            C[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@numba.njit(cache=True, inline="always")
def mul33t_into(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """C = A · Bᵀ (3 × 3 blocks; C distinct from A, B)."""
    for i in range(3):
        for j in range(3):
            C[i, j] = A[i, 0] * B[j, 0] + A[i, 1] * B[j, 1] + A[i, 2] * B[j, 2]


@numba.njit(cache=True, inline="always")
def exp3_into(w: np.ndarray, R: np.ndarray) -> None:
    """R = Exp(w), Rodrigues: ``I + sin θ [a]× + (1 − cos θ) [a]×²`` (θ = |w|, a = w/θ;
    Taylor series of the coefficients below θ = 1e-4)."""
    t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    if t2 < 1e-8:
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0  # sin θ / θ
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0  # (1 − cos θ) / θ²
    else:
        t = math.sqrt(t2)
        a = math.sin(t) / t
        b = (1.0 - math.cos(t)) / t2
    x, y, z = w[0], w[1], w[2]
    R[0, 0] = 1.0 - b * (y * y + z * z)
    R[1, 1] = 1.0 - b * (x * x + z * z)
    R[2, 2] = 1.0 - b * (x * x + y * y)
    R[0, 1] = b * x * y - a * z
    R[1, 0] = b * x * y + a * z
    R[0, 2] = b * x * z + a * y
    R[2, 0] = b * x * z - a * y
    R[1, 2] = b * y * z - a * x
    R[2, 1] = b * y * z + a * x


@numba.njit(cache=True)
def exp3(w: np.ndarray) -> np.ndarray:
    """Exp(w): the rotation by |w| about w (:func:`exp3_into`)."""
    R = np.empty((3, 3))
    exp3_into(w, R)
    return R


@numba.njit(cache=True)
def _yaw(R: np.ndarray) -> float:
    return math.atan2(R[1, 0], R[0, 0])


@numba.njit(cache=True, error_model="numpy")
def _estimate(
    model: np.ndarray,
    joints: np.ndarray,
    fallback: np.ndarray,
    gyro: np.ndarray,
    acc: np.ndarray,
    dt: float,
    select: int,
    anchor0: np.ndarray,
    anchor1: np.ndarray,
    state: np.ndarray,
    out: np.ndarray,
) -> None:
    """One tick of :meth:`StateEstimator.update` (module docstring): writes ``out`` (8 × 3:
    rotation (3 rows), base, com, com_vel, dcm, angular_velocity) and updates ``state`` in
    place. ``model``: ``StateEstimator._model``; ``select = sole0 + 2 (sole1 + 1) + 8 imu``
    (sole indices in SOLE_FRAMES, ``sole1 = -1``: single support). (Few arguments: each
    costs the dispatcher about as much as a small product.)"""
    n = int(model[0])
    table = model[1 : 1 + _WIDTH * n].reshape(n, _WIDTH)
    links = model[1 + _WIDTH * n : 1 + (_WIDTH + 2) * n].reshape(n, 2)
    consts = model[1 + (_WIDTH + 2) * n :]
    sole0, sole1, imu = select % 2, (select // 2) % 4 - 1, select >= 8
    tilt_gain, cutoff, omega0, gyro_heading, inv_mass = (
        consts[_C_TILT], consts[_C_CUTOFF], consts[_C_OMEGA0], consts[_C_HEADING] > 0.5,
        consts[_C_INV_MASS])  # fmt: skip
    bias_gain, kin_gain, kin_heading = consts[_C_BIAS], consts[_C_KIN], consts[_C_FRAME] > 0.5
    kin_band = consts[_C_FRAME + 1]
    torso_b = consts[_C_TORSO : _C_TORSO + 9].reshape(3, 3)
    # forward kinematics in the base frame (base at the origin), body by body, written in
    # place (an allocation per small product would cost more than the kinematics)
    Rs = np.empty((n, 3, 3))
    ps = np.empty((n, 3))
    E = np.empty((3, 3))
    M = np.empty((3, 3))
    com_b = np.zeros(3)
    for k in range(n):
        row = table[k]
        parent, iq = int(links[k, 0]), int(links[k, 1])
        if parent < 0:
            for i in range(3):
                ps[k, i] = 0.0
                for j in range(3):
                    Rs[k, i, j] = 1.0 if i == j else 0.0
        else:
            th = joints[iq]
            if not math.isfinite(th):
                th = fallback[iq]
            x, y, z = row[_AXIS], row[_AXIS + 1], row[_AXIS + 2]
            sn, cs = math.sin(th), math.cos(th)
            t = 1.0 - cs  # E = Exp(θ a) = I + sin θ [a]× + (1 − cos θ) [a]×², |a| = 1
            E[0, 0] = 1.0 - t * (y * y + z * z)
            E[1, 1] = 1.0 - t * (x * x + z * z)
            E[2, 2] = 1.0 - t * (x * x + y * y)
            E[0, 1] = t * x * y - sn * z
            E[1, 0] = t * x * y + sn * z
            E[0, 2] = t * x * z + sn * y
            E[2, 0] = t * x * z - sn * y
            E[1, 2] = t * y * z - sn * x
            E[2, 1] = t * y * z + sn * x
            for i in range(3):  # M = R_placement · E
                for j in range(3):
                    M[i, j] = (row[3 * i] * E[0, j] + row[3 * i + 1] * E[1, j]
                               + row[3 * i + 2] * E[2, j])  # fmt: skip
            for i in range(3):  # R_k = R_parent · M, p_k = p_parent + R_parent · p_placement
                ps[k, i] = ps[parent, i] + (Rs[parent, i, 0] * row[_P]
                                            + Rs[parent, i, 1] * row[_P + 1]
                                            + Rs[parent, i, 2] * row[_P + 2])  # fmt: skip
                for j in range(3):
                    Rs[k, i, j] = (Rs[parent, i, 0] * M[0, j] + Rs[parent, i, 1] * M[1, j]
                                   + Rs[parent, i, 2] * M[2, j])  # fmt: skip
        m = row[_MASS]
        for i in range(3):  # Σ m_k (R_k lever_k + p_k)
            com_b[i] += m * (Rs[k, i, 0] * row[_LEVER] + Rs[k, i, 1] * row[_LEVER + 1]
                             + Rs[k, i, 2] * row[_LEVER + 2] + ps[k, i])  # fmt: skip
    com_b *= inv_mass
    # the stance soles in the base frame (scratch: sole rotations, filter rotations, vectors)
    count = 1 if sole1 < 0 else 2
    ids = (sole0, sole1)
    W = np.empty((6, 3, 3))  # sole 0, sole 1, R_kin, exp, R, R_base
    V = np.empty((6, 3))  # sole 0, sole 1, w, base, rel 0, rel 1
    for s in range(count):
        r0 = _C_SOLES + _SOLE_WIDTH * ids[s]
        parent = int(consts[r0 + 12])
        Rp = Rs[parent]
        for i in range(3):
            V[s, i] = ps[parent, i] + (Rp[i, 0] * consts[r0 + 9] + Rp[i, 1] * consts[r0 + 10]
                                       + Rp[i, 2] * consts[r0 + 11])  # fmt: skip
            for j in range(3):
                W[s, i, j] = (Rp[i, 0] * consts[r0 + j] + Rp[i, 1] * consts[r0 + 3 + j]
                              + Rp[i, 2] * consts[r0 + 6 + j])  # fmt: skip
    R_kin, Ex, R, R_base = W[2], W[3], W[4], W[5]
    has = state[_S_HAS] > 0.5
    joint_lag = consts[_C_LAG] > 0.5
    if not has or not imu or not gyro_heading or kin_gain > 0 or kin_heading:  # A0 (ᵇR_sole0)ᵀ
        mul33t_into(anchor0, W[0], R_kin)
    if not has:  # start the filter at the kinematics' rotation (StateEstimator.reset)
        mul33_into(R_kin, torso_b, R)
        state[_S_ROT:_S_HAS] = R.ravel()
        state[_S_HAS] = 1.0
        state[_S_VALID:_S_VEL] = 0.0
        state[_S_VEL:_S_BIAS] = 0.0
    if imu:
        R0 = state[_S_ROT:_S_HAS].reshape(3, 3)
        w = V[2]
        norm = math.sqrt(acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2])
        k = tilt_gain / norm if 0.8 * 9.80665 < norm < 1.2 * 9.80665 else 0.0
        # ω + b + k (a × up),  up = R[2] = Rᵀ e_z: the world's up in the torso frame; the bias
        # correction b integrates (a × up)/|a| × bias_gain (Mahony's integral term)
        kb = bias_gain * dt * k / tilt_gain
        if kin_gain > 0:  # the kinematics' up in the torso frame: row 2 of R_kin · ᵇR_torso
            mul33_into(R_kin, torso_b, Ex)
        for i in range(3):
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            cross = acc[i1] * R0[2, i2] - acc[i2] * R0[2, i1]
            state[_S_BIAS + i] += kb * cross
            w[i] = gyro[i] + state[_S_BIAS + i]
            V[3, i] = (w[i] + k * cross) * dt
            if kin_gain > 0:  # + k_kin (u_kin × up): the stance sole flat, slowly
                V[3, i] += kin_gain * (Ex[2, i1] * R0[2, i2] - Ex[2, i2] * R0[2, i1]) * dt
        w[:] = V[3]
        exp3_into(w, Ex)
        mul33_into(R0, Ex, R)
        if not gyro_heading:  # keep the filter's tilt, the heading of the kinematics
            mul33_into(R_kin, torso_b, Ex)
            d = _yaw(Ex) - _yaw(R)
            c, sn = math.cos(d), math.sin(d)
            for j in range(3):  # R ← Rz(d) R
                x, y = R[0, j], R[1, j]
                R[0, j] = c * x - sn * y
                R[1, j] = sn * x + c * y
        # the kinematic terms at the joints' time: the rotation of the tick they were read
        # (``joint_lag``: the previous tick's filter, R0, still intact here) or this one's
        src = R0 if joint_lag and has else R
        if kin_heading and gyro_heading:  # the kinematic terms at the soles' heading
            mul33_into(R_kin, torso_b, Ex)
            d = _yaw(Ex) - _yaw(R)
            if kin_band > 0.0:  # the soles' slip (wrapped), less kin_band
                d = (d + math.pi) % (2.0 * math.pi) - math.pi
                d = math.copysign(max(abs(d) - kin_band, 0.0), d)
            c, sn = math.cos(d), math.sin(d)
            for j in range(3):  # M = Rz(d) src: the stance sole where the plan turned it
                M[0, j] = c * src[0, j] - sn * src[1, j]
                M[1, j] = sn * src[0, j] + c * src[1, j]
                M[2, j] = src[2, j]
            src = M
        mul33t_into(src, torso_b, R_base)
        for i in range(3):
            out[7, i] = gyro[i] + state[_S_BIAS + i]
    else:
        R_base[:] = R_kin
        mul33_into(R_base, torso_b, R)
        out[7] = 0.0
    state[_S_ROT:_S_HAS] = R.ravel()
    base = V[3]
    base[:] = 0.0
    for s in range(count):
        A = anchor0 if s == 0 else anchor1
        sp = V[s]
        for i in range(3):
            rb = R_base[i, 0] * sp[0] + R_base[i, 1] * sp[1] + R_base[i, 2] * sp[2]
            base[i] += A[i, 3] - rb
            # CoM relative to the sole: R_base (ᵇc − ᵇp_sole)
            V[4 + s, i] = (R_base[i, 0] * (com_b[0] - sp[0]) + R_base[i, 1] * (com_b[1] - sp[1])
                           + R_base[i, 2] * (com_b[2] - sp[2]))  # fmt: skip
    vel = state[_S_VEL:_S_BIAS]
    alpha = math.exp(-2.0 * math.pi * cutoff * dt) if dt > 0 else 0.0
    common = 0
    for s in range(count):  # the stance soles also in support at the last tick
        common += 1 if state[_S_VALID + ids[s]] > 0.5 else 0
    for i in range(3):
        base[i] /= count
        com_i = base[i] + (R_base[i, 0] * com_b[0] + R_base[i, 1] * com_b[1]
                           + R_base[i, 2] * com_b[2])  # fmt: skip
        if common > 0 and dt > 0:
            raw = 0.0
            for s in range(count):
                j = ids[s]
                if state[_S_VALID + j] > 0.5:
                    raw += V[4 + s, i] - state[_S_REL + 3 * j + i]
            vel[i] = alpha * vel[i] + ((1.0 - alpha) / dt) * (raw / common)
        out[3, i] = base[i]
        out[4, i] = com_i
        out[5, i] = vel[i]
        out[6, i] = com_i + vel[i] / omega0 if i < 2 else com_i
    state[_S_VALID:_S_VEL] = 0.0
    for s in range(count):
        j = ids[s]
        state[_S_REL + 3 * j : _S_REL + 3 * j + 3] = V[4 + s]
        state[_S_VALID + j] = 1.0
    out[0:3] = R


def _kinematic_table(robot: Robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The robot's joints for :func:`_estimate`: per body (pinocchio order, the floating base
    first) its placement in the parent, axis, CoM lever and mass; its parent's row and its
    index in the joint vector; the soles' parents and placements (in ``consts``' layout)."""
    model = robot.model
    if model.joints[1].shortname() != "JointModelFreeFlyer":
        raise ModelError("state estimator: the robot's first joint must be its floating base")
    rows = model.njoints - 1
    table = np.zeros((rows, _WIDTH))
    links = np.full((rows, 2), -1, dtype=np.int64)
    for j in range(1, model.njoints):
        k = j - 1
        joint = model.joints[j]
        if j > 1:
            axis = joint_axis(model, j, "state estimator")
            links[k] = (model.parents[j] - 1, joint.idx_q - 7)
            placement = model.jointPlacements[j]
            table[k, _R:_P] = placement.rotation.ravel()
            table[k, _P:_AXIS] = placement.translation
            table[k, _AXIS:_LEVER] = axis
        else:
            table[k, _R:_P] = np.eye(3).ravel()
        table[k, _LEVER:_MASS] = model.inertias[j].lever
        table[k, _MASS] = model.inertias[j].mass
    soles = []
    for name in SOLE_FRAMES:
        frame = model.frames[robot.frame_id(name)]
        p = frame.placement
        soles.append(np.r_[p.rotation.ravel(), p.translation, frame.parentJoint - 1])
    return table, links, np.concatenate(soles)


class StateEstimator:
    """Complementary-filter orientation + stance-leg kinematics (module docstring).

    ``com_height`` (m) sets ω₀; ``tilt_gain`` (1/s) is the accelerometer's pull on the
    orientation; ``velocity_cutoff`` (Hz) the CoM velocity filter; ``use_imu=False``:
    encoders only. ``bias_gain`` (1/s², 0: off) learns the gyro's remaining bias about the
    horizontal axes (module docstring): a bias error ``b`` left by the calibration at rest
    otherwise tilts the estimate by ``b / tilt_gain`` for good. ``joint_lag``: the joints
    given to :meth:`update` were read a tick before the IMU sample (the deployment reads the
    servos right after writing the goals, the IMU at the next tick): the base, CoM and CoM
    velocity then use the filter's rotation of that tick, so a body rotating at ω is not
    read as a CoM moving by ``ω × r`` × the tick (module docstring).
    """

    def __init__(
        self,
        robot: Robot,
        com_height: float,
        use_imu: bool = True,
        tilt_gain: float = 0.2,
        velocity_cutoff: float = 6.0,
        gyro_heading: bool = False,
        bias_gain: float = 0.0,
        kin_gain: float = 0.0,
        anchor_band: float = 0.0,
        joint_lag: bool = False,
        contact_band: float = 0.0,
        kin_heading: bool = False,
        kin_band: float = 0.0,
        anchor_down: float = 0.0,
    ) -> None:
        for name, v in (
            ("com_height", com_height),
            ("tilt_gain", tilt_gain),
            ("velocity_cutoff", velocity_cutoff),
        ):
            if not (np.isfinite(v) and v > 0):
                raise ConfigurationError(
                    f"state estimator: {name} must be a finite number > 0, got {v}"
                )
        if not (np.isfinite(bias_gain) and bias_gain >= 0):
            raise ConfigurationError(
                f"state estimator: bias_gain must be a finite number >= 0, got {bias_gain}"
            )
        for name, v in (
            ("kin_gain", kin_gain), ("anchor_band", anchor_band), ("contact_band", contact_band),
            ("kin_band", kin_band), ("anchor_down", anchor_down),
        ):  # fmt: skip
            if not (np.isfinite(v) and v >= 0):
                raise ConfigurationError(
                    f"state estimator: {name} must be a finite number >= 0, got {v}"
                )
        #: m: a sole landing further than this from its planned placement is anchored where
        #: it landed until it lifts (module docstring; 0: always the planned placement)
        self.anchor_band = float(anchor_band)
        self._landed: dict[str, np.ndarray | None] = {}  # per stance sole: its anchor
        #: m (0: off): a sole entering the support is judged (anchored or not) only once its
        #: lowest point is within this of the other sole's (:meth:`sole_heights`): not at the
        #: first support tick while it is still in the air (planned until then)
        self.anchor_down = float(anchor_down)
        #: m: a sole whose lowest point is more than this above the other's carries no weight
        #: (:meth:`contact`; 0: the plan's support, always)
        self.contact_band = float(contact_band)
        #: the soles (SOLE_FRAMES order) :meth:`contact` found carrying the weight last tick
        self.carrying = (True, True)
        self.heights = np.zeros(2)  # m: the soles' lowest points last tick (:meth:`contact`)
        self.down = (True, True)  # the soles within the band of the lowest (:meth:`contact`)
        #: per sole (SOLE_FRAMES order): where it was last found down while the plan swung
        #: it (x, y; :meth:`contact`)
        self.touched = np.zeros((2, 2))
        #: per sole carrying while the plan has it swinging: its anchor (:meth:`contact`)
        self._carried: dict[int, np.ndarray] = {}
        self._corners = sole_corners(*(float(v) for v in robot.foot_size))
        self._fids = [robot.frame_id(name) for name in SOLE_FRAMES]
        self._data = robot.model.createData()  # (its own: the controller's stays untouched)
        self.bias_gain = float(bias_gain)
        self.kin_gain = float(kin_gain)
        self.joint_lag = bool(joint_lag)
        self.robot = robot
        self.omega0 = float(np.sqrt(GRAVITY / com_height))
        self.use_imu = use_imu
        self.gyro_heading = gyro_heading
        #: with ``gyro_heading``: the kinematic terms (base, CoM, its velocity, the DCM) at the
        #: kinematics' heading, the stance sole where the plan turned it (the torso's rotation
        #: keeps the gyro's heading): a robot whose soles slipped round stands balanced about
        #: them, and the plan's frame would read its CoM's lead along the walk as a sideways
        #: error (``Gains.kin_heading``); ``kin_band`` (rad): only the soles' slip beyond it
        self.kin_heading, self.kin_band = bool(kin_heading), float(kin_band)
        self.tilt_gain = float(tilt_gain)
        self.cutoff = float(velocity_cutoff)
        torso = robot.model.frames[robot.frame_id("torso")]
        if torso.parentJoint != 1:
            raise ModelError("state estimator: the torso frame must be on the floating base")
        self.torso_b = torso.placement.rotation.copy()  # constant: torso in the base frame
        table, links, soles = _kinematic_table(robot)
        consts = np.r_[
            self.tilt_gain, self.cutoff, self.omega0, float(gyro_heading),
            1.0 / table[:, _MASS].sum(), self.torso_b.ravel(), soles, float(joint_lag),
            self.kin_gain, self.bias_gain, float(kin_heading), self.kin_band,
        ]  # fmt: skip
        assert len(consts) == _C_SIZE and len(soles) == _SOLE_WIDTH * len(SOLE_FRAMES)
        # everything constant in one array (:func:`_estimate`'s layout; the gains, ω₀ and
        # gyro_heading are fixed at construction)
        self._model = np.r_[len(table), table.ravel(), links.ravel(), consts]
        self._state = np.zeros(_S_SIZE)
        self._zeros = np.zeros(3)
        self.last: StateEstimate | None = None

    @property
    def rotation(self) -> np.ndarray | None:
        """The filter's torso rotation (None before the first update or reset)."""
        if self._state[_S_HAS] < 0.5:
            return None
        return self._state[_S_ROT:_S_HAS].reshape(3, 3).copy()

    @property
    def com_vel(self) -> np.ndarray:
        """The filtered CoM velocity (m/s)."""
        return self._state[_S_VEL:_S_BIAS].copy()

    @property
    def gyro_correction(self) -> np.ndarray:
        """The gyro's bias correction learnt by the filter (``bias_gain``; rad/s, torso
        frame): :attr:`StateEstimate.angular_velocity` is the calibrated gyro plus it."""
        return self._state[_S_BIAS:_S_SIZE].copy()

    def restart(self) -> None:
        """Start the filter again at the next update, from the kinematics' rotation (the
        stance sole flat): the levelled orientation after a start-up calibration."""
        self._state[_S_HAS] = 0.0
        self.last = None
        self._landed.clear()
        self._carried.clear()
        self.carrying = (True, True)
        self.down = (True, True)

    def reset(self, torso_rotation: np.ndarray) -> None:
        """Start the filter at a known torso rotation (e.g. the planned one, standing)."""
        self._state[:] = 0.0
        self._state[_S_ROT:_S_HAS] = np.asarray(torso_rotation, dtype=float).ravel()
        self._state[_S_HAS] = 1.0
        self.last = None
        self._landed.clear()
        self._carried.clear()
        self.carrying = (True, True)
        self.down = (True, True)

    def update(
        self,
        dt: float,
        joints: np.ndarray,
        reading: ImuReading | None,
        stance: Sequence[tuple[str, pin.SE3]],
        fallback: np.ndarray | None = None,
    ) -> StateEstimate:
        """One tick: ``joints`` the present positions (rad, model order), ``reading`` the
        IMU's sample (ignored with ``use_imu=False``), ``stance`` the support sole frame(s)
        with their planned placements; ``fallback`` stands in for the joints whose present
        position is NaN (not read this tick)."""
        imu = self.use_imu and reading is not None
        select, h0, h1 = self.select(stance, imu)
        if self.anchor_band > 0:
            h0, h1 = self._anchors(stance, h0, h1, joints, fallback)
        out = np.empty((8, 3))
        if imu:
            gyro, acc = reading.angular_velocity, reading.linear_acceleration
        else:
            gyro = acc = self._zeros
        _estimate(
            self._model, joints, joints if fallback is None else fallback, gyro, acc,
            float(dt), select, h0, h1, self._state, out,
        )  # fmt: skip
        self.last = StateEstimate(out)  # (a fresh array every tick)
        return self.last

    def landed(self, frame: str, joints: np.ndarray, fallback: np.ndarray | None) -> np.ndarray:
        """Where the last estimate (base pose) and ``joints`` (NaN: ``fallback``'s) put sole
        ``frame`` (world position, m)."""
        config = self._estimated_configuration(joints, fallback)
        return self.robot.frame_placement(config, frame).translation.copy()

    def com_and_placement(
        self, frame: str, joints: np.ndarray, fallback: np.ndarray | None
    ) -> tuple[np.ndarray, pin.SE3]:
        """The CoM (world) and frame ``frame``'s placement (a copy) where the last estimate's
        rotation (the IMU's) and base and ``joints`` (NaN: ``fallback``'s) put the model: the
        kinematics alone, no velocity estimate."""
        config = self._estimated_configuration(joints, fallback)
        model, data = self.robot.model, self._data
        com = np.array(pin.centerOfMass(model, data, config))
        pin.updateFramePlacements(model, data)
        return com, pin.SE3(data.oMf[self.robot.frame_id(frame)])

    def _estimated_configuration(
        self, joints: np.ndarray, fallback: np.ndarray | None
    ) -> np.ndarray:
        """The configuration the last estimate (base position, the torso's rotation as the
        base's) and ``joints`` (NaN: ``fallback``'s) make."""
        est = self.last
        assert est is not None
        q = np.asarray(joints, dtype=float)
        if fallback is not None:
            q = np.where(np.isfinite(q), q, fallback)
        R_base = est.rotation @ self.torso_b.T
        return np.concatenate([est.base, pin.Quaternion(R_base).coeffs(), q])

    def sole_normals(self, joints: np.ndarray, fallback: np.ndarray | None) -> np.ndarray:
        """(2, 3) each sole's normal (its z axis; SOLE_FRAMES order) in the world where the
        last estimate's rotation (the IMU's) and ``joints`` (NaN: ``fallback``'s) turn it:
        a sole rolled onto one edge tilts its normal toward that edge's side."""
        config = self._estimated_configuration(joints, fallback)
        pin.framesForwardKinematics(self.robot.model, self._data, config)
        return np.array([self._data.oMf[fid].rotation[:, 2] for fid in self._fids])

    def sole_heights(self, joints: np.ndarray, fallback: np.ndarray | None) -> np.ndarray:
        """(2,) each sole's lowest point (of its corners, ``robot.foot_size``; SOLE_FRAMES
        order) in the world, m, where the last estimate (the IMU's rotation, the anchored
        base) and ``joints`` (NaN: ``fallback``'s) put it: what a robot senses of which sole
        is down (the encoders' kinematics and the IMU's tilt)."""
        config = self._estimated_configuration(joints, fallback)
        pin.framesForwardKinematics(self.robot.model, self._data, config)
        out = np.empty(2)
        for s, fid in enumerate(self._fids):
            M = self._data.oMf[fid]
            out[s] = float(np.min(self._corners @ M.rotation[2] + M.translation[2]))
        return out

    def contact(
        self, select: int, soles: np.ndarray, joints: np.ndarray, fallback: np.ndarray | None
    ) -> tuple[int, np.ndarray]:
        """The support the sensors show (``contact_band`` > 0), as :func:`_estimate`'s
        ``select`` and the soles' pack (:func:`wbc.walking.loop.sole_pack`; a copy when an
        anchor changes) for the plan's ``select`` and ``soles``: a sole whose lowest point
        (:meth:`sole_heights`, from the last estimate) is more than the band above the
        other's carries no weight. The planned support soles that are down carry it; when
        none is (a pushed robot still standing on the sole the plan swings, or already on
        the one it has not landed), the sole that is down does, anchored where the last
        estimate put it (its lowest point on the floor: the planned soles' height; the
        estimate stays continuous) until it leaves the support. :attr:`carrying` keeps the
        answer. (Called before :func:`_estimate`, on the last tick's estimate.)"""
        band = self.contact_band
        if band <= 0 or self.last is None:
            return select, soles
        side = select % 8
        planned = (True, True) if side >= 2 else (side == 0, side == 1)
        h = self.heights = self.sole_heights(joints, fallback)
        down = (bool(h[0] - h.min() <= band), bool(h[1] - h.min() <= band))
        carry = (planned[0] and down[0], planned[1] and down[1])
        if not any(carry):
            carry = down
        self.carrying, self.down = carry, down
        for s in (0, 1):  # a sole the plan swings, down: where it touched (the step adjuster's)
            if down[s] and not planned[s]:
                self.touched[s] = self.landed(SOLE_FRAMES[s], joints, fallback)[:2]
        for s in list(self._carried):
            if not carry[s]:
                del self._carried[s]  # lifted: its plan's placement again at the next landing
        if carry == planned and not self._carried:
            return select, soles
        out = soles.copy()
        floor = min(soles[11] if planned[0] else math.inf, soles[27] if planned[1] else math.inf)
        for s in (0, 1):
            if carry[s] and not planned[s] and s not in self._carried:
                anchor = soles[16 * s : 16 * s + 16].reshape(4, 4).copy()
                anchor[:2, 3] = self.landed(SOLE_FRAMES[s], joints, fallback)[:2]
                anchor[2, 3] = floor
                self._carried[s] = anchor
            if s in self._carried:
                a = self._carried[s]
                out[16 * s : 16 * s + 16] = a.ravel()
                out[32 + s] = max(math.hypot(a[0, 1], a[1, 1]), 1e-9)
        new = (select - side) + (4 if all(carry) else 0 if carry[0] else 1)
        return new, out

    def _anchors(
        self,
        stance: Sequence[tuple[str, pin.SE3]],
        h0: np.ndarray,
        h1: np.ndarray,
        joints: np.ndarray,
        fallback: np.ndarray | None,
        band: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The stance soles' anchors (``anchor_band``; ``band`` this tick's, None: it): a
        sole entering the support more than the band from its planned placement is anchored
        where it landed (its horizontal position; height and rotation planned) until it
        leaves the support."""
        band = self.anchor_band if band is None else band
        names = [name for name, _ in stance]
        for name in list(self._landed):
            if name not in names:
                del self._landed[name]  # lifted: planned again at its next landing
        out = [h0, h1]
        known = bool(self._landed) and self.last is not None  # (not the first tick)
        for s, (name, placement) in enumerate(stance):
            if name not in self._landed:
                anchor = None
                if known and self.anchor_down > 0 and self._up(name, joints, fallback):
                    continue  # (still in the air: planned this tick, judged when down)
                if known:
                    p = self.landed(name, joints, fallback)
                    d = p[:2] - placement.translation[:2]
                    if math.hypot(d[0], d[1]) > band:
                        anchor = placement.homogeneous.copy()
                        anchor[:2, 3] = p[:2]
                self._landed[name] = anchor
            anchor = self._landed[name]
            if anchor is not None:
                out[s] = anchor
        return out[0], (out[1] if len(stance) > 1 else out[0])

    def loaded(self, joints: np.ndarray, fallback: np.ndarray | None, band: float) -> int:
        """In a double support, the sole (SOLE_FRAMES index) the estimate stands on: -1 both
        (the plan's), else the one whose lowest point is more than ``band`` below the other's
        (:meth:`sole_heights`, from the last estimate): the other is still in the air (a
        caught landing's sole, moving with the swing, would halve the CoM velocity read)."""
        if self.last is None:
            return -1
        h = self.sole_heights(joints, fallback)
        return -1 if abs(h[0] - h[1]) <= band else int(h[1] < h[0])

    def _up(self, name: str, joints: np.ndarray, fallback: np.ndarray | None) -> bool:
        """True when sole ``name``'s lowest point stands more than ``anchor_down`` above the
        other sole's (:meth:`sole_heights`, from the last estimate)."""
        h = self.sole_heights(joints, fallback)
        s = SOLE_FRAMES.index(name)
        return bool(h[s] - h[1 - s] > self.anchor_down)

    @staticmethod
    def select(
        stance: Sequence[tuple[str, pin.SE3]], imu: bool
    ) -> tuple[int, np.ndarray, np.ndarray]:
        """:func:`_estimate`'s ``select`` and anchors (the stance soles' homogeneous
        placements; single support: the first twice) for ``stance`` (:meth:`update`)."""
        if not stance:
            raise ConfigurationError("state estimator: no stance sole given")
        name0, anchor0 = stance[0]
        h0 = anchor0.homogeneous
        select = SOLE_FRAMES.index(name0) + (8 if imu else 0)
        if len(stance) > 1:
            name1, anchor1 = stance[1]
            return select + 2 * (SOLE_FRAMES.index(name1) + 1), h0, anchor1.homogeneous
        return select, h0, h0
