"""Closed-loop stabilisation inside the control tick: feedback on the walking targets.

Each tick, :class:`Stabilizer` reads the sensors (present joint positions; a torso IMU, or
none), updates the :class:`~wbc.balance.estimator.StateEstimator`, and changes the targets
the controller is about to track (:class:`~wbc.walking.loop.TickTargets`), so every solver
family (QP stacks, placo, pink) gets the same feedback through the tasks it already has:

* **torso (ankle/hip strategy, the torso orientation task; on by default)** — with
  ``e = log(R_est R_refᵀ)`` the torso's orientation error in the world frame (its vertical,
  heading part scaled by ``k_yaw``) and ``ω`` the gyro rate (world frame, vertical part scaled
  by ``k_yaw``), the torso target becomes ``Exp(−(k_p e + k_i ∫e + k_d ω)) · R_ref``. With the
  soles held by the floor, the legs' joints turn the body back by the commanded
  counter-rotation: each compliant servo's extra torque opposes the sag, ``k_d`` damps the
  sway, ``k_i`` takes the steady part; ``k_roll`` (1: off) scales the command's part about
  the target's heading (the roll: 2 brings ``lateral_wb``'s nominal within 3° but rings
  plants with servo latency; issue 30's ninth pass); ``yaw_cutoff`` (Hz, 0: off) low-passes
  the command's heading part (first order), below the yaw loop's ringing on stiff, late
  plants; ``max_yaw`` (rad, 0: off) clips the heading part on its own and the tilt part to
  ``max_tilt`` (else they share ``max_tilt`` as one vector); ``yaw_ring`` (rad/s, 0: off)
  scales the heading part down by the yaw rate's measured ringing (its RMS above 3 Hz),
  ``lag_yaw`` (s, 0: off) by the servos' measured lag behind their goals
  (:mod:`wbc.balance.servo_lag`, :attr:`Stabilizer.servo_lag`); ``k_twist`` (1: off) scales
  the clipped command's part about the torso target's own vertical axis (its twist: a roll
  about the heading of a torso leaned forward turns the hip yaws; issue 33);
* **the walk's clock** (``lag_clock``) — the reference time runs slower on a plant whose
  servos follow late (:attr:`Stabilizer.clock`, read by :meth:`Session.at_time`);
* **the heading by the footsteps** (``step_yaw``, off) — the stance sole's measured heading
  error at each lift-off turns the swing sole's target (:mod:`wbc.balance.step_yaw`);
* **DCM (capture point) on the CoM reference** (``k_dcm``, off by default) —
  ``c_cmd = c_ref − k_dcm (ξ − ξ_ref)`` (horizontal), ``ξ = c + ċ/ω₀`` estimated, ``ξ_ref``
  from the reference's CoM and velocity: a CoM running ahead of its plan gets a commanded CoM
  behind it; with ``k_dcm_i`` (``k_dcm_i_y`` sideways; off) the error's integral too, kept in
  the torso target's heading frame (the steady lag a wrong servo model leaves: 0.25 /s along
  the walk is the default without the feed-forward, :data:`NO_FEED_FORWARD_GAINS`;
  benchmarks/physics.md, issue 30's fourth and ninth passes);
* **lean** (``k_lean``, off) — the CoM target turned about the stance sole with the torso,
  ``−k_lean h (e × z)``;
* **hip strategy** (``k_hip``, on by default) — in single support, a DCM estimated beyond
  ``hip_band`` outward of the stance sole's centre (toward the side no step can reach) rolls
  the torso target toward it, ``Exp(h (z × u)) R_ref``, ``h = min(k_hip (s − hip_band)⁺, max_hip)``:
  the upper body spun about the stance hip moves the centroidal moment pivot beyond the
  sole's edge while it accelerates (:mod:`wbc.balance.angular` bounds what it can buy;
  ``hip_axis``: about the torso's own axis, :mod:`wbc.balance.hip_roll`); it
  returns at ``hip_release`` rad/s (:meth:`Stabilizer._hip_strategy`); a push (``hip_jump``:
  the outward offset jumping in one tick) asks the whole ``max_hip`` at once, no band, and
  (``hip_kick``) moves the stance hip roll's solved goal further toward the roll, which then
  returns at ``kick_release`` (:meth:`Stabilizer.joint_offsets`: the whole-body solve, its CoM
  task the heaviest, leaves the stance hip ~20° short of the roll asked), the other leg's hip
  roll and that side's shoulder roll with it (``counter_leg``, ``counter_arm``: those limbs
  spun toward the fall beside the torso), the kick braked before the torso tips past
  ``kick_tilt`` (:mod:`wbc.balance.hip_kick`);
* **the push's rise** (``push_rise``, off) — after a push away (the hip strategy's trigger) the
  CoM target raised, held while the push's kick lasts, lowered after
  (:mod:`wbc.balance.push_rise`: the body driven up while the CoM is inside the edge the CoP
  is on pulls it back);
* **narrower sway** (``transfer``, 0.15 by default; 0: off) — not a feedback term: the
  closed loop (:func:`wbc.balance.live.closed_loop`) walks its reference re-planned by the
  walk's own generator (:func:`wbc.walking.gait.narrow_sway`): the ZMP reaches each landed
  sole within the first ``transfer`` of the double support and runs in single support as
  far toward the other sole as the walk's margin allows, so at mid single support the DCM
  is further from the stance sole's outer edge (a push away from the swing foot has
  further to go) while the CoM and its ZMP stay consistent, the ZMP ``margin`` inside;
* **joint level** (``j_p``, ``j_d``, off) — offsets on the solved leg goals along each joint's
  axis, OP3 gains; the loaded legs' sag (solved goal − encoder) integrated slowly into their
  goals (``j_i``, :mod:`wbc.balance.joint_integral`); and the push's hip kick (``hip_kick``,
  above) (:meth:`Stabilizer.joint_offsets`, applied by :class:`wbc.balance.live.SessionSource`).

Each term is clipped (``max_tilt`` rad, ``max_shift`` m), and the joint limits stay hard in
every solver (and the deployment clamps again): no goal ever leaves a joint limit.
``enabled = False`` turns the loop off (the targets pass through unchanged). The gains were
chosen by measurement in the simulator: benchmarks/balance.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numba
import numpy as np

from ..compiled.rows import log3
from ..imu import SETTLE_STILL, Imu, ImuCalibration, calibrate, quietest_window, window_spread
from ..model import Robot
from ..walking.legs import LegGeometry
from ..walking.loop import sole_pack
from .estimator import StateEstimate, StateEstimator, _estimate, exp3_into, mul33t_into
from .fall import _F_SIZE, _L_SIZE, FallDetector, fall_code, fall_tick
from .gains import NO_FEED_FORWARD_GAINS as NO_FEED_FORWARD_GAINS  # (re-exported)
from .gains import Gains as Gains
from .gains import default_gains as default_gains
from .hip_kick import HipKick
from .hip_roll import (
    _K_FALL,
    _K_HIP,
    _K_HIP_AXIS,
    _K_LAG,
    _K_MAX_YAW,
    _K_RING,
    _K_ROLL,
    _K_SIZE,
    _K_TWIST,
    _K_YAW_CUT,
    _K_YAW_D,
    _hip_roll,
)
from .joint_integral import JointIntegral
from .push_rise import PushRise, leg_room
from .servo_lag import clock_rate, lag_state, phase_clock, servo_lag
from .step_yaw import StepYaw

#: Hz: ``yaw_ring``'s high-pass on the vertical gyro rate (above a turn's rate and the
#: steps' sway, below the 5-8 Hz ringing of stiff, late plants: issue 30)
RING_HZ = 3.0
#: s: ``yaw_ring``'s window (the time constant of its mean square)
RING_WINDOW = 0.5


@numba.njit(cache=True, error_model="numpy")
def _torso_feedback(
    est: np.ndarray,
    R_ref: np.ndarray,
    integral: np.ndarray,
    k: np.ndarray,
    dt: float,
    out: np.ndarray,
    yaw: np.ndarray,
) -> None:
    """The torso term of :meth:`Stabilizer.adjust` in one compiled call (small numpy and
    pinocchio calls cost more than the arithmetic): with ``est`` the estimate's values
    (:class:`~wbc.balance.estimator.StateEstimate`: ``R_est`` its first three rows, the gyro
    rate ω its last), ``k``: the gains' array (``_K_*``), ``e = log(R_est R_refᵀ)``
    (``e_z`` × k_yaw), the integral ``clip(∫ + e dt, max_tilt / k_i)``, ``w = R_est ω``
    (``w_z`` × k_yaw) and ``tilt = clip(k_p e + k_i ∫ + k_d w, max_tilt)``, its part along the
    target's heading ``h`` (the roll) scaled by ``k[_K_ROLL]`` first and, with a cut-off
    ``f = k[_K_YAW_CUT]`` > 0 Hz, its vertical (heading) part low-passed first-order before
    the clip: ``y ← y + (1 − exp(−2π f dt)) (tilt_z − y)``, ``tilt_z = y`` (``yaw[0]``: ``y``,
    updated in place); with ``m = k[_K_MAX_YAW]`` > 0 the heading parts (of ∫ and of tilt)
    clipped on their own (to ``m / k_i``, ``m``) and the tilt's horizontal parts to theirs,
    else each vector as a whole; ``k[_K_YAW_D]`` adds to ``k_d`` on ``w_z``; with
    ``g = k[_K_RING]`` > 0 (``yaw[1]``: the low-passed ``w_z``, ``yaw[2]``: the mean square
    of the rest, updated in place) ``u = w_z − yaw[1]``, ``yaw[1] += (1 − exp(−2π RING_HZ
    dt)) u``, ``yaw[2] += (1 − exp(−dt / RING_WINDOW)) (u² − yaw[2])`` and the heading part
    (before the low-pass and the clip) scaled by ``min(1, g / sqrt(yaw[2]))`` and with
    ``s = k[_K_LAG]`` > 0 by ``min(1, s / yaw[3])`` (``yaw[3]``: the servos' lag); after
    the clip, the part along the target's own vertical axis (``R_ref``'s third column: the
    twist, what the hip yaws turn) scaled by ``k[_K_TWIST]``; writes
    ``out = [e, ∫, Exp(−tilt) R_ref (9, row-major), |e_xy|]``."""
    k_p, k_i, k_d, k_yaw, max_tilt = k[0], k[1], k[2], k[3], k[4]
    R_est, omega = est[:3], est[7]
    S = np.empty((2, 3, 3))  # scratch (one allocation: a small array each costs more)
    v = np.empty(3)
    mul33t_into(R_est, R_ref, S[0])
    log3(S[0], v)  # e (the tasks' SO(3) logarithm)
    out[15] = math.sqrt(v[0] * v[0] + v[1] * v[1])
    v[2] *= k_yaw
    n = 0.0
    for i in range(3):
        out[i] = v[i]
        out[3 + i] = integral[i] + v[i] * dt
        n += out[3 + i] * out[3 + i]
    n = math.sqrt(n)
    limit = max_tilt / max(k_i, 1e-9)
    max_yaw = k[_K_MAX_YAW]
    if max_yaw > 0.0:  # the heading's integral clipped on its own, the tilt's to its share
        n = math.sqrt(out[3] * out[3] + out[4] * out[4])
        if n > limit:
            out[3] *= limit / n
            out[4] *= limit / n
        out[5] = min(max(out[5], -max_yaw / max(k_i, 1e-9)), max_yaw / max(k_i, 1e-9))
    elif n > limit:
        for i in range(3):
            out[3 + i] *= limit / n
    n = 0.0
    for i in range(3):  # tilt = k_p e + k_i ∫ + k_d w,  w = R_est ω (w_z × k_yaw)
        w = R_est[i, 0] * omega[0] + R_est[i, 1] * omega[1] + R_est[i, 2] * omega[2]
        d = k_d
        if i == 2:
            w *= k_yaw
            d += k[_K_YAW_D]
        v[i] = k_p * out[i] + k_i * out[3 + i] + d * w
    k_roll = k[_K_ROLL]
    if k_roll != 1.0:  # the part about the target's heading (roll) scaled: k_roll
        h0, h1 = R_ref[0, 0], R_ref[1, 0]
        m = math.sqrt(h0 * h0 + h1 * h1)
        if m > 1e-9:
            h0, h1 = h0 / m, h1 / m
            r = (k_roll - 1.0) * (v[0] * h0 + v[1] * h1)
            v[0] += r * h0
            v[1] += r * h1
    ring = k[_K_RING]
    if ring > 0.0:  # the heading's gain backed off by the yaw rate's ringing (its RMS)
        w = R_est[2, 0] * omega[0] + R_est[2, 1] * omega[1] + R_est[2, 2] * omega[2]
        u = w - yaw[1]
        yaw[1] += (1.0 - math.exp(-2.0 * math.pi * RING_HZ * dt)) * u
        yaw[2] += (1.0 - math.exp(-dt / RING_WINDOW)) * (u * u - yaw[2])
        r = math.sqrt(yaw[2])
        if r > ring:
            v[2] *= ring / r
    lag = k[_K_LAG]
    if lag > 0.0 and yaw[3] > lag:  # the heading's gain backed off by the servos' lag
        v[2] *= lag / yaw[3]
    cut = k[_K_YAW_CUT]
    if cut > 0.0:  # the heading part low-passed (first order, cut-off ``cut`` Hz)
        yaw[0] += (1.0 - math.exp(-2.0 * math.pi * cut * dt)) * (v[2] - yaw[0])
        v[2] = yaw[0]
    if max_yaw > 0.0:  # the heading and the tilt each clipped on its own
        n = math.sqrt(v[0] * v[0] + v[1] * v[1])
        f = -max_tilt / n if n > max_tilt else -1.0
        v[0] *= f
        v[1] *= f
        v[2] = -min(max(v[2], -max_yaw), max_yaw)
    else:
        for i in range(3):
            n += v[i] * v[i]
        n = math.sqrt(n)
        f = -max_tilt / n if n > max_tilt else -1.0
        for i in range(3):
            v[i] *= f
    twist = k[_K_TWIST]
    if twist != 1.0:  # the part about the target's own vertical axis z scaled: k_twist
        r = (twist - 1.0) * (v[0] * R_ref[0, 2] + v[1] * R_ref[1, 2] + v[2] * R_ref[2, 2])
        for i in range(3):
            v[i] += r * R_ref[i, 2]
    exp3_into(v, S[1])  # Exp(−tilt)
    for i in range(3):
        for j in range(3):
            out[6 + 3 * i + j] = (S[1, i, 0] * R_ref[0, j] + S[1, i, 1] * R_ref[1, j]
                                  + S[1, i, 2] * R_ref[2, j])  # fmt: skip


# the feedback's state (Stabilizer._fb): the hip-strategy roll (2), the torso integral (3), the
# IMU calibration applied (1/0), its gyro bias (3) and levelling rotation (9, row-major), the
# largest estimated tilt error (rad), the low-passed heading command (yaw_cutoff; rad) and
# yaw_ring's low-passed vertical rate (rad/s) and mean square of the rest, the servos' lag (s),
# the hip strategy's push trigger (hip_jump: the last outward offset, m; the single support's
# ticks so far; 1 once it fired in this single support; the mean square of the per-tick change;
# hip_kick: 1 from the trigger until the roll is back to 0)
_B_HIP, _B_INT, _B_CAL, _B_BIAS, _B_LEVEL, _B_MAX_TILT = 0, 2, 5, 6, 9, 18
_B_YAW, _B_LAG, _B_JUMP, _B_SIZE = 19, 22, 23, 28  # (3: the low-pass's state, yaw_ring's two)


@numba.njit(cache=True, error_model="numpy")
def _feedback_tick(
    consts: np.ndarray,
    joints: np.ndarray,
    fallback: np.ndarray,
    gyro: np.ndarray,
    acc: np.ndarray,
    dt: float,
    select: int,
    soles: np.ndarray,
    state: np.ndarray,
    fb: np.ndarray,
    R_ref: np.ndarray,
    fall_state: np.ndarray,
    values: np.ndarray,
    o: np.ndarray,
    lag: np.ndarray,
) -> int:
    """:meth:`Stabilizer.adjust`'s tick in one compiled call (a call and a small numpy
    operation each cost more than their arithmetic): the IMU calibration applied to the
    sample (``ω − b``, ``L a``), the state estimate (:func:`~wbc.balance.estimator._estimate`
    into ``values``, ``state`` its filter's; ``soles``: :func:`wbc.walking.loop.sole_pack`,
    the stance sole first in single support, ``select % 8`` 1: the right), the hip strategy
    (:func:`_hip_roll`; single support: the other sole second), the torso feedback
    (:func:`_torso_feedback` into ``o``, (6, 3): rows e, ∫e, the torso target (3), |e_xy|)
    and the fall detector (:func:`~wbc.balance.fall.fall_code`, its answer returned; 0
    without one). ``consts``: the gains (``_K_*``), the fall limits, the estimator's model;
    ``fb``: the feedback's state (``_B_*``; the torso integral updated unless a fall); ``lag``:
    :func:`~wbc.balance.servo_lag.servo_lag`'s state (the joints read against ``fallback``,
    the goals they follow: ``τ`` into ``fb[_B_LAG]``; empty: not measured)."""
    model = consts[_K_SIZE + _L_SIZE :]
    est, k0 = select % 16, 0  # (+16 (1 + k): the estimate on sole k alone, support_down)
    if select >= 16:
        k0 = select // 16 - 1
        est = est - 4 + k0
    select = select % 16
    imu = select >= 8
    w, a = np.empty(3), np.empty(3)
    if imu and fb[_B_CAL] > 0.5:  # the start-up calibration (wbc.imu.calibrate)
        for i in range(3):
            w[i] = gyro[i] - fb[_B_BIAS + i]
        a[:] = np.dot(fb[_B_LEVEL : _B_LEVEL + 9].reshape(3, 3), acc)  # (numpy's BLAS L @ a)
    else:
        w[:] = gyro
        a[:] = acc
    side = select % 8
    first = 16 if side == 1 else 0  # (single support on the right: its sole first)
    S = np.empty((2, 4, 4))  # the anchors, stance first (fall_code's soles too)
    for k in range(16):
        S[0, k // 4, k % 4] = soles[first + k]
        S[1, k // 4, k % 4] = soles[16 - first + k]
    anchor0, anchor1 = S[0], S[1]
    y_norm = soles[33] if side == 1 else soles[32] if side == 0 else 1.0
    _estimate(model, joints, fallback, w, a, dt, est, S[k0], S[1 - k0], state, values)
    if lag.shape[0] > 0:  # (an empty state: the lag not read, not measured)
        fb[_B_LAG] = servo_lag(joints, fallback, dt, lag)
    R = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            R[i, j] = R_ref[i, j]
    if consts[_K_HIP] > 0:
        H = np.empty((3, 3))
        up = R[:, 2] if consts[_K_HIP_AXIS] < 1.5 else values[0:3, 2]  # (hip_axis: target, torso)
        _hip_roll(side < 2, anchor0, anchor1, y_norm, values[6], fb[_B_HIP : _B_HIP + 2],
                  consts, dt, H, fb[_B_JUMP : _B_JUMP + 5], up.copy())  # fmt: skip
        if fb[_B_HIP] != 0.0 or fb[_B_HIP + 1] != 0.0:  # (else H = I exactly: R as it is)
            R = np.dot(H, R)  # (numpy's BLAS H @ R_ref)
    flat = o.reshape(o.size)  # (_torso_feedback's layout: rows e, ∫, R (3), |e_xy|)
    _torso_feedback(values, R, fb[_B_INT : _B_INT + 3], consts, dt, flat, fb[_B_YAW : _B_YAW + 4])
    code = 0
    if consts[_K_FALL] > 0.5:
        fall_tick(fall_state, dt)
        count = 1 if side < 2 else 2
        code = fall_code(o[0], values[0:3], values[7], values[6], S, count,
                         consts[_K_SIZE : _K_SIZE + _L_SIZE], fall_state)  # fmt: skip
    if code == 0:
        fb[_B_INT : _B_INT + 3] = o[1]
        if o[5, 0] > fb[_B_MAX_TILT]:  # (Python's max: the first unless the second is larger)
            fb[_B_MAX_TILT] = o[5, 0]
    return code


@numba.njit(cache=True, error_model="numpy")
def _com_shift(
    com: np.ndarray,
    com_vel_ref: np.ndarray,
    dcm: np.ndarray,
    R_ref: np.ndarray,
    k: np.ndarray,
    dt: float,
    integral: np.ndarray,
    h: float,
    e: np.ndarray,
) -> np.ndarray:
    """:meth:`Stabilizer._shifted`'s CoM target in one compiled call (its numpy operations,
    one a tick each, cost more than their arithmetic): ``k``: ``k_dcm``, ``k_dcm_i``,
    ``k_dcm_i_y``, ``k_lean``, ``max_shift``, ω₀; ``integral`` (the DCM error's, 2) updated in
    place; ``h`` the CoM's height over the support sole (``k_lean``), ``e`` the orientation
    error. The matrix products are numpy's (BLAS, ``np.dot``: the same bits)."""
    shift = np.zeros(2)
    k_i = k[1:3]
    if k[0] > 0 or k_i[0] != 0 or k_i[1] != 0:
        err = np.empty(2)
        for a in range(2):  # ε = ξ − (c_ref + ċ_ref / ω₀)
            err[a] = dcm[a] - (com[a] + com_vel_ref[a] / k[5])
            shift[a] -= k[0] * err[a]
        if k_i[0] != 0 or k_i[1] != 0:
            yaw = math.atan2(R_ref[1, 0], R_ref[0, 0])  # (geometry.yaw_of, rot2)
            c, s = np.cos(yaw), np.sin(yaw)
            R_h = np.empty((2, 2))
            R_h[0, 0], R_h[0, 1], R_h[1, 0], R_h[1, 1] = c, -s, s, c
            local = np.dot(R_h.T, err)
            for a in range(2):
                limit = k[4] / max(k_i[a], 1e-9)
                integral[a] = min(max(integral[a] + local[a] * dt, -limit), limit)
            shift -= np.dot(R_h, k_i * integral)
    if k[3] > 0:  # the CoM turned by −k_lean·e about the support: −k h (e × z)
        lean = k[3] * h
        shift[0] -= lean * e[1]
        shift[1] -= lean * -e[0]
    n = math.sqrt(np.dot(shift, shift))  # (geometry.clip_norm)
    if n > k[4]:
        shift = shift * (k[4] / n)
    out = np.empty(3)
    out[0], out[1], out[2] = com[0] + shift[0], com[1] + shift[1], com[2]
    return out


class _Sample:
    """An IMU sample in the torso frame, built inside the tick (no validation: its arrays
    come from a validated :class:`~wbc.imu.ImuReading`)."""

    __slots__ = ("angular_velocity", "linear_acceleration", "orientation", "t")

    def __init__(self, t, orientation, angular_velocity, linear_acceleration) -> None:
        self.t, self.orientation = t, orientation
        self.angular_velocity, self.linear_acceleration = angular_velocity, linear_acceleration


class Stabilizer:
    """Estimator + feedback on the targets of one walk (module docstring).

    ``present()`` returns the servos' present positions (rad, model order; None or NaN
    entries: not read this tick, the commanded angle is used); ``imu`` a torso
    :class:`~wbc.imu.Imu` or None (encoders only).
    """

    def __init__(
        self,
        robot: Robot,
        com_height: float,
        present: Callable[[], np.ndarray | None],
        imu: Imu | None = None,
        gains: Gains | None = None,
        enabled: bool = True,
        estimator: StateEstimator | None = None,
        fall: FallDetector | None = None,
        calibration_ticks: int = 0,
        settle_ticks: int = 0,
    ) -> None:
        self.robot = robot
        mount = getattr(imu, "mount", None)
        self.mount = None if mount is None or mount.identity else mount
        #: the start-up calibration at rest (wbc.imu.calibrate) once done; before it, the
        #: first ``calibration_ticks`` ticks collect samples and feed nothing back
        self.calibration: ImuCalibration | None = None
        self.calibration_ticks = int(calibration_ticks)  # ticks at rest before the walk
        self._rest_left = self.calibration_ticks
        #: up to this many ticks more at rest while the calibration's window (its last half)
        #: is not still (:data:`~wbc.imu.SETTLE_STILL`); then the quietest window is taken
        self._settle_left = int(settle_ticks) if self.calibration_ticks > 0 else 0
        self._settling = self._settle_left > 0
        self._samples: list[tuple[np.ndarray, np.ndarray]] = []
        self.fall = fall  # raises FallDetected from adjust() on a state beyond recovery
        self.present = present
        self.imu = imu
        self.gains = (gains or Gains()).check()
        self.enabled = enabled
        g = self.gains
        self.estimator = estimator or StateEstimator(
            robot, com_height, use_imu=imu is not None, gyro_heading=g.k_yaw > 0,
            kin_gain=g.kin_tilt, anchor_band=g.anchor_band, joint_lag=g.joint_lag > 0,
            contact_band=g.contact_band, kin_heading=g.kin_heading > 0,
            kin_band=g.kin_band, anchor_down=g.anchor_down,
        )  # fmt: skip
        self._fb = np.zeros(_B_SIZE)  # the feedback's state (_feedback_tick)
        self._lag = lag_state(len(robot.joint_names))  # (servo_lag's)
        self._no_lag = np.zeros(0)  # (passed instead while the lag is not read)
        self._measure_lag = False
        self._applied: ImuCalibration | None = None  # the calibration in _fb
        self._no_fall = np.zeros(_F_SIZE)  # (fall_code's state when there is no detector)
        self.dcm_integral = np.zeros(2)  # m·s, ∫ DCM error dt in the torso target's heading frame
        self._shift_k: tuple = (None, np.zeros(6))  # (gains, _com_shift's k: _shifted)
        self.error = np.zeros(3)  # last orientation error (world) and gyro rate (torso frame)
        self.rate = np.zeros(3)
        self._joint = None
        self._stance = ""  # the stance sole of the last tick ("" in double support)
        self._dt = 0.01  # s: the last tick's
        if self.gains.j_p > 0 or self.gains.j_d > 0:
            from .feedback import GyroFeedback

            self._joint = GyroFeedback(robot, imu, 1.0) if imu is not None else None
        self._kick = HipKick(robot) if self.gains.hip_kick > 0 else None  # (hip_kick)
        self._rise = PushRise()  # (push_rise: the CoM target raised after a push)
        self._legs: LegGeometry | None = None  # (rise_room's: the loaded legs' room)
        if self.gains.push_rise > 0 and self.gains.rise_room > 0:
            self._legs = LegGeometry.from_robot(robot, robot.configuration("stand"))
        #: (gains, _feedback_tick's consts, fall detector, the CoM target moved: _shifted)
        self._packed: tuple = (None, None, None, False, self._no_lag)
        self.last: StateEstimate | None = None
        self.clock = self._clock = 1.0  # the walk's clock rate (lag_clock; Session.at_time)
        self.steps_yaw = StepYaw(robot)  # the footsteps' heading correction (step_yaw)
        self._sag: JointIntegral | None = None  # the loaded joints' integral (j_i)
        #: the servos' stiffness / servos.toml's identified at rest (None: not identified;
        #: set by :func:`wbc.balance.live.closed_loop`'s rest: ``j_i_stiff``)
        self.stiffness_scale: float | None = None
        self.goal_probe = None  # the start-up goal probe's fit (wbc.balance.goal_probe), if run
        self.time = 0.0  # s spent in the last adjust (estimator + feedback)
        self.read_time = 0.0  # s of it spent reading the sensors

    @property
    def integral(self) -> np.ndarray:
        """The torso feedback's integral ∫e dt (rad·s, world; a view: writable)."""
        return self._fb[_B_INT : _B_INT + 3]

    @integral.setter
    def integral(self, value: np.ndarray) -> None:
        self._fb[_B_INT : _B_INT + 3] = value

    @property
    def max_tilt_error(self) -> float:
        """rad, the largest estimated torso tilt error |e_xy| so far."""
        return float(self._fb[_B_MAX_TILT])

    @property
    def servo_lag(self) -> float:
        """s, the servos' lag behind their goals as last measured
        (:func:`~wbc.balance.servo_lag.servo_lag`; 0 until the goals have moved). Measured
        only when read: ``lag_yaw`` or ``lag_clock`` > 0, or :attr:`measure_lag`."""
        return float(self._fb[_B_LAG])

    @property
    def measure_lag(self) -> bool:
        """True: :attr:`servo_lag` measured every tick even when no gain reads it (a
        diagnostic's; set before the walk)."""
        return self._measure_lag

    @measure_lag.setter
    def measure_lag(self, on: bool) -> None:
        if bool(on) != self._measure_lag:
            self._measure_lag = bool(on)
            self._packed = (None, None, None, False, self._no_lag)  # (packed again)

    @property
    def hip(self) -> np.ndarray:
        """The hip-strategy roll (rad, horizontal: toward where the top goes; a view)."""
        return self._fb[_B_HIP : _B_HIP + 2]

    def _consts(self) -> np.ndarray:
        """:func:`_feedback_tick`'s ``consts`` for the current gains (built when they change;
        each tick's: a subclass's may differ, ``LiftedStabilizer``'s hip band)."""
        g, fall = self.gains, self.fall
        if self._packed[0] is not g or self._packed[2] is not fall or self._packed[1] is None:
            limits = fall.limits if fall is not None else np.zeros(_L_SIZE)
            k = [g.k_p, g.k_i, g.k_d, g.k_yaw, g.max_tilt, g.k_hip, g.hip_band, g.max_hip,
                 g.hip_release, float(fall is not None), g.k_roll, g.yaw_cutoff,
                 g.max_yaw, g.yaw_damping, g.yaw_ring, g.lag_yaw,
                 g.hip_jump * g.hip_band, g.kick_release if g.hip_kick > 0 else 0.0,
                 g.k_twist, g.hip_axis]  # fmt: skip
            shift = g.k_dcm > 0 or g.k_lean > 0 or g.k_dcm_i > 0 or g.k_dcm_i_y > 0
            read = g.lag_yaw > 0 or g.lag_clock > 0 or self._measure_lag
            read = read or (g.j_i > 0 and g.j_i_lag > 0)
            lag = self._lag if read else self._no_lag
            self._packed = (g, np.r_[k, limits, self.estimator._model], fall, shift, lag)
        return self._packed[1]

    def adjust(self, targets, com_vel_ref: np.ndarray, q_cmd: np.ndarray, dt: float):
        """The targets of this tick with the feedback applied (``q_cmd``: the controller's
        last configuration, whose joints stand in for unread servos)."""
        if not self.enabled:
            return targets
        start = time.perf_counter()
        joints = q_cmd[7:]
        present = self.present()  # (its unread, NaN entries: the commanded joints)
        reading = self.imu.read() if self.imu is not None else None
        self.read_time = time.perf_counter() - start  # (the drivers')
        if self._rest_left > 0:  # (calibrating)
            return self._calibrate(targets, self._torso_sample(reading),
                                   joints if present is None else present, joints, dt)  # fmt: skip
        estimator = self.estimator
        imu = estimator.use_imu and reading is not None
        if imu:  # the torso's rate and specific force (the mount's and calibration's public
            # ImuReading methods validate more: too slow for a tick)
            w, a = reading.angular_velocity, reading.linear_acceleration
            if self.mount is not None:
                w, a = self.mount.rates(w, a)
            if self.calibration is not self._applied:
                self._apply(self.calibration)
        else:
            w = a = estimator._zeros
        # the stance soles (StateEstimator.select, written out: the tick's cost): the soles'
        # placements and lateral axes' lengths, built once per walk by the Session
        pack = targets.sole_pack
        if pack is None or pack[0] is not targets.l_sole or pack[1] is not targets.r_sole:
            pack = (None, None, sole_pack(targets.l_sole, targets.r_sole))  # (built here)
        soles = pack[2]
        double = targets.phase == "double"
        self._stance = "" if double else targets.support
        self._dt = float(dt)
        select = (8 if imu else 0) + (4 if double else 0 if targets.support == "l_sole" else 1)
        band = targets.anchor_band  # (this tick's: back_anchor; None: the estimator's)
        band = estimator.anchor_band if band is None else band
        if band > 0:  # a sole landed off its plan (off by default)
            read = joints if present is None else present
            soles = soles.copy()
            h = soles[:32].reshape(2, 4, 4)  # (a view: the anchors written in)
            if double:
                stance = [("l_sole", targets.l_sole), ("r_sole", targets.r_sole)]
                h[0], h[1] = estimator._anchors(stance, h[0], h[1], read, joints, band)
            else:
                stance = [(targets.support, targets.support_placement)]
                k = select % 8
                h[k] = estimator._anchors(stance, h[k], h[k], read, joints, band)[0]
        if estimator.contact_band > 0:  # the support the sensors show (off by default)
            select, soles = estimator.contact(
                select, soles, joints if present is None else present, joints
            )
        if double and self.gains.support_down > 0:  # (the estimate on the loaded sole; off)
            k = estimator.loaded(joints if present is None else present, joints,
                                 self.gains.support_down)  # fmt: skip
            select += 0 if k < 0 or select % 8 != 4 else 16 * (1 + k)
        values, o = np.empty((8, 3)), np.empty((6, 3))  # (fresh: the estimate is kept)
        consts = self._consts()  # (packed again when the gains or the detector changed)
        packed = self._packed
        if self._kick is not None:  # (kick_hold: the limbs held while the sole is rolled;
            # kick_hold_edge: while the measured DCM is beyond its outer edge)
            g = self.gains
            held = (g.kick_hold > 0 or g.kick_hold_edge > 0) and self._fb[_B_JUMP + 4] > 0.5
            read = joints if present is None else present
            if held and g.kick_hold_edge > 0:  # (every tick of the kick: its velocity)
                got = self._kick.sole_dcm(estimator, read, joints, float(dt))
                held = got is not None and self._kick.beyond(got[0], got[1], g.kick_hold_edge)
            if held and g.kick_hold > 0:
                held = self._kick.rolled(estimator, read, joints, g.kick_hold)
            self._kick.held = self._kick.debounced(held, float(dt), g.kick_hold_for)
        code = _feedback_tick(
            consts, joints if present is None else present, joints, w, a, float(dt),
            select, soles, estimator._state, self._fb, targets.torso_rotation,
            self._no_fall if self.fall is None else self.fall.state, values, o, packed[4],
        )  # fmt: skip
        est = self.last = estimator.last = StateEstimate(values)
        e = o[0]  # orientation error, world frame (heading part × k_yaw)
        if code:
            self.fall.raise_for(self.fall.declare(code))
        self.error, self.rate = e, est.angular_velocity
        if self.gains.lag_clock > 0.0:  # the walk's clock from the servos' lag
            g, lag = self.gains, self._fb[_B_LAG]  # (ramped to clip(lag_clock / τ, clock_min, 1))
            c = self._clock = clock_rate(self._clock, lag, g.lag_clock, g.clock_min, dt)
            self.clock = phase_clock(c, double, g.clock_single)
        if self.clock != 1.0:  # (the reference's velocity at the clock's rate: its DCM)
            com_vel_ref = com_vel_ref * self.clock
        com = targets.com
        if packed[3]:  # (k_dcm, k_lean, k_dcm_i or k_dcm_i_y > 0)
            com = self._shifted(targets, com_vel_ref, est, e, dt)
        g = self.gains
        if g.push_rise > 0:  # (the CoM target raised after a push away: push_rise)
            com = self._push_rise(com, float(dt), targets, q_cmd)
        out = targets.retarget(com, o[2:5])
        if g.step_yaw > 0:  # the footsteps take the measured heading error (step_yaw)
            read = joints if present is None else np.where(np.isfinite(present), present, joints)
            out = self.steps_yaw.apply(targets, out, est.rotation, read, q_cmd, g.step_yaw,
                                       g.max_step_yaw, g.step_yaw_band, g.step_yaw_turn,
                                       dt, g.step_yaw_cap)  # fmt: skip
        self.time = time.perf_counter() - start
        return out

    def _hip_strategy(self, targets, est: StateEstimate, dt: float) -> np.ndarray:
        """The hip strategy's rotation of the torso target for ``targets`` and ``est``
        (:func:`_hip_roll`, the roll :attr:`hip` updated), as :func:`_feedback_tick` applies
        it: ``Exp(h (z × u)) R_ref``."""
        H, st, other, y_norm = np.empty((3, 3)), np.eye(4), np.eye(4), 1.0
        single = targets.phase != "double"
        if single:
            st = targets.support_placement.homogeneous
            other = (targets.r_sole if targets.support == "l_sole" else targets.l_sole).homogeneous
            y_norm = max(math.hypot(st[0, 1], st[1, 1]), 1e-9)
        k = self._consts()
        R = np.asarray(targets.torso_rotation if k[_K_HIP_AXIS] < 1.5 else est.rotation, float)
        _hip_roll(single, st, other, y_norm, np.asarray(est.dcm, dtype=float), self.hip,
                  k, float(dt), H, self._fb[_B_JUMP : _B_JUMP + 5], R[:, 2].copy())  # fmt: skip
        return H

    def _push_rise(self, com: np.ndarray, dt: float, targets=None, q_cmd=None) -> np.ndarray:
        """``com`` raised by ``push_rise`` (:class:`~wbc.balance.push_rise.PushRise`) while
        the hip strategy's push trigger is latched or the push's kick lasts (with
        ``rise_room``: at most that share of ``targets``' loaded legs' room,
        :func:`~wbc.balance.push_rise.leg_room`; with ``rise_knee``: at most the room of
        the commanded ``q_cmd``'s loaded legs above its CoM, :class:`~.push_rise.KneeRoom`)."""
        fb = self._fb
        pushed = fb[_B_JUMP + 2] > 0.5 or fb[_B_JUMP + 4] > 0.5
        room, g = np.inf, self.gains
        if g.rise_room > 0 and targets is not None and (pushed or self._rise.dz > 0):
            if self._legs is None:  # (gains swapped in after the start: Walker's)
                self._legs = LegGeometry.from_robot(self.robot, self.robot.configuration("stand"))
            room = leg_room(self._legs, targets, com)
        cap = np.inf
        if g.rise_knee > 0 and q_cmd is not None and targets is not None:
            if pushed or self._rise.dz > 0:
                cap = self._rise.knee_cap(self.robot, g.rise_knee, q_cmd, targets, com)
        double = targets is not None and targets.phase == "double"
        return self._rise.raised(com, pushed, dt, g, room, cap, double)

    def _torso_sample(self, reading):
        """``reading`` in the torso frame with the calibration applied (the start-up
        calibration's ticks at rest; the tick's own: :func:`_feedback_tick`)."""
        if reading is None or (self.mount is None and self.calibration is None):
            return reading
        w, a = reading.angular_velocity, reading.linear_acceleration
        if self.mount is not None:
            w, a = self.mount.rates(w, a)
        if self.calibration is not None:
            c = self.calibration
            w, a = w - c.gyro_bias, c.level @ a
        return _Sample(reading.t, reading.orientation, w, a)

    def _apply(self, calibration: ImuCalibration | None) -> None:
        """Write ``calibration`` (gyro bias, levelling) into the feedback's state."""
        fb = self._fb
        fb[_B_CAL] = 0.0 if calibration is None else 1.0
        if calibration is not None:
            fb[_B_BIAS : _B_BIAS + 3] = calibration.gyro_bias
            fb[_B_LEVEL : _B_LEVEL + 9] = np.asarray(calibration.level, dtype=float).ravel()
        self._applied = calibration

    @property
    def calibrating(self) -> bool:
        """True while the start-up calibration at rest collects its samples."""
        return self.enabled and self._rest_left > 0

    def _calibrate(self, targets, reading, present, joints, dt: float):
        """One tick of the start-up calibration at rest: the estimator restarted from the
        kinematics (stance soles flat: the torso's expected up), the sample kept; after
        ``calibration_ticks`` samples, :func:`wbc.imu.calibrate` on the second half (the
        robot settles in the first; its remaining motion, the kinematic rotation's mean rate,
        is not counted as gyro bias; raises on a mount error) and the filter restarted from
        the levelled kinematic orientation. With ``settle_ticks``: the rest goes on (at most
        that many ticks) until that window's gyro is still, then the quietest window
        (:func:`wbc.imu.quietest_window`) is taken. The targets pass unchanged."""
        stance = [("l_sole", targets.l_sole), ("r_sole", targets.r_sole)]
        self.estimator.restart()
        est = self.estimator.update(dt, present, reading, stance, fallback=joints)
        if reading is not None:
            self._samples.append((reading.angular_velocity, reading.linear_acceleration,
                                  est.rotation.copy(), dt))  # fmt: skip
        self._rest_left -= 1
        n = self.calibration_ticks - self.calibration_ticks // 2  # the window's length
        if self._rest_left == 0 and self._settle_left > 0 and len(self._samples) >= n:
            g = np.array([s[0] for s in self._samples[-n:]])
            if window_spread(g) > SETTLE_STILL:  # not still yet: one tick more
                self._rest_left, self._settle_left = 1, self._settle_left - 1
                return targets
        if self._rest_left == 0 and self._samples:
            first = len(self._samples) // 2
            if self._settling:  # the quietest window from the planned end on
                g = np.array([s[0] for s in self._samples])
                first = quietest_window(g, n, self.calibration_ticks)
            half = self._samples[first : first + n] if self._settling else self._samples[first:]
            g, a = (np.array([s[k] for s in half]) for k in (0, 1))
            span = sum(s[3] for s in half[1:])
            motion = np.zeros(3)
            if span > 0:  # the torso's mean rate from the kinematics (torso frame)
                R0, R1 = half[0][2], half[-1][2]
                v = np.empty(3)
                log3(np.ascontiguousarray(R0.T @ R1), v)
                motion = v / span
            where = f"the IMU's mount (Imu.mount: {self.mount or 'the torso frame'})"
            self.calibration = calibrate(g, a, est.rotation[2], where=where, motion=motion)
            self._samples.clear()
            self.estimator.restart()
        return targets

    def _shifted(
        self, targets, com_vel_ref: np.ndarray, est: StateEstimate, e: np.ndarray, dt: float
    ):
        """The CoM target moved by the DCM and lean terms (clipped to ``max_shift``):
        ``−k_dcm ε − R_h K ∫ R_hᵀ ε dt`` with ``ε = ξ − ξ_ref``, ``R_h`` the torso
        target's heading (the integral kept in the walk's frame, so a turn carries it along)
        and ``K = diag(k_dcm_i, k_dcm_i_y)`` (each axis's integral clipped to ``max_shift / k``);
        one compiled call (:func:`_com_shift`)."""
        g, com, omega0 = self.gains, targets.com, self.estimator.omega0
        key, k = self._shift_k
        if key is not g or k[5] != omega0:  # (the gains changed: packed again)
            k = np.array([g.k_dcm, g.k_dcm_i, g.k_dcm_i_y, g.k_lean, g.max_shift, omega0])
            self._shift_k = (g, k)
        h = com[2] - targets.support_placement.translation[2] if g.k_lean > 0 else 0.0
        return _com_shift(np.asarray(com, dtype=float), np.asarray(com_vel_ref, dtype=float),
                          est.dcm, np.asarray(targets.torso_rotation, dtype=float), k,
                          float(dt), self.dcm_integral, float(h), e)  # fmt: skip

    def joint_offsets(self, joints: np.ndarray) -> np.ndarray | None:
        """Joint-level feedback on the solved goals (None when there is none this tick):
        ``δ_j = k_j a_j · (j_p Rᵀe + j_d ω)`` (``j_p``, ``j_d``; OP3 gains ``k_j``, axes
        ``a_j`` in the torso frame, :mod:`wbc.balance.feedback`), clipped to ``max_offset``;
        and the push's hip kick (``hip_kick``: :meth:`_hip_kick`)."""
        if not self.enabled or self.last is None:
            return None
        g = self.gains
        d = None
        if self._joint is not None and (g.j_p > 0 or g.j_d > 0):
            e_body = self.last.rotation.T @ self.error
            v = g.j_p * e_body + g.j_d * self.rate
            d = np.clip(self._joint.k * (self._joint.axes(joints) @ v), -g.max_offset, g.max_offset)
        if g.j_i > 0 and self.sag_integrated:  # the loaded joints' sag (joint_integral)
            if self._sag is None:
                self._sag = JointIntegral(self.robot)
            delay = self._dt + g.j_i_lag * self.servo_lag if g.j_i_lag > 0 else 0.0
            hold = g.j_i_single > 0 and not self._stance  # (double support: held)
            leak = 0.0 if hold and g.j_i_single < 2 else g.j_i_leak  # (2: it leaks)
            i = self._sag.offsets(joints, self.present(), self._stance,
                                  0.0 if hold else g.j_i, g.j_i_max,
                                  leak, self._dt, g.j_i_still, delay,
                                  g.j_i_sagittal > 0, g.j_i_band,
                                  int(g.j_i_joints))  # fmt: skip
            d = i if d is None else d + i
        if g.hip_kick > 0:
            d = self._hip_kick(joints, d)
        return d

    @property
    def sag_integrated(self) -> bool:
        """Whether ``j_i`` may run: always without ``j_i_stiff``; with it only once the
        stiffness identified at rest (:attr:`stiffness_scale`) is below ``j_i_stiff``."""
        g = self.gains
        k = self.stiffness_scale
        return g.j_i_stiff <= 0 or (k is not None and k < g.j_i_stiff)

    def _hip_kick(self, joints: np.ndarray, d: np.ndarray | None) -> np.ndarray | None:
        """``d`` with the push's hip kick added (``hip_kick``, :class:`~wbc.balance.hip_kick.
        HipKick`: from the tick the push trigger fires until the hip-strategy roll is back to
        0; braked by ``kick_tilt``)."""
        est = self.last
        if est is None or self._kick is None:
            return d
        fb = self._fb
        return self._kick.offsets(joints, d, self.gains, fb[_B_HIP : _B_HIP + 2],
                                  fb[_B_JUMP + 2] > 0.5, fb[_B_JUMP + 4] > 0.5, self._stance,
                                  est.rotation, est.angular_velocity, self._dt)  # fmt: skip
