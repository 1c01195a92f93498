"""State estimate of a walking robot from what a Bioloid-class robot senses.

Inputs per control tick: the servos' present positions (encoders, rad) and, optionally, a torso
IMU (:class:`wbc.imu.Imu`: gyro + accelerometer). Output (:class:`StateEstimate`): the torso
(base) orientation, the base position, the CoM, its velocity and the DCM.

**Orientation** (with an IMU) — a complementary filter on SO(3): integrate the gyro and pull
the predicted "up" direction toward the accelerometer's specific force::

    R ← R · Exp((ω + k_a · (u_m × u_p)) · dt)     u_m = a/|a|,  u_p = Rᵀ e_z

(``k_a`` the tilt gain, 1/s; the correction is skipped when |a| is not within 20 % of g,
i.e. during impacts). Only roll and pitch are observable this way; the heading (yaw) is taken
from the encoders (below), so a gyro's yaw drift never reaches the controller, unless
``gyro_heading`` (the integrated gyro's heading: it sees the feet's yaw slip, and drifts
with the gyro's bias).

**Encoders only** (``imu=None``): the stance sole is assumed flat at its planned placement;
``R_base = R_sole · (ᵇR_sole)ᵀ`` with ``ᵇR_sole`` from forward kinematics of the present joints.

**CoM**: with the base rotation ``R`` and the stance sole(s) anchored at their planned
placement, ``p_base = p_sole − R · ᵇp_sole`` (averaged over both soles in double support) and
``c = p_base + R · ᵇc``. **CoM velocity**: the time derivative of the CoM *relative to the
stance sole(s)*, ``d/dt (R (ᵇc − ᵇp_sole))`` (so a support switch never makes it jump),
low-pass filtered (first order, ``velocity_cutoff`` Hz, against the 0.29° encoder steps).
**DCM** ``ξ = c + ċ / ω₀`` with ``ω₀ = √(g / z_c)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..exceptions import WbcError
from ..imu import GRAVITY, ImuReading
from ..model import Robot

SOLE_FRAMES = ("l_sole", "r_sole")


@dataclass
class StateEstimate:
    """One estimate (world frame; the torso is the IMU frame)."""

    rotation: np.ndarray  # (3, 3) torso rotation
    base: np.ndarray  # (3,) base position
    com: np.ndarray  # (3,)
    com_vel: np.ndarray  # (3,)
    dcm: np.ndarray  # (3,) ξ = c + ċ/ω₀ (z: c_z)
    angular_velocity: np.ndarray  # (3,) rad/s, torso frame (zeros without an IMU)


def _exp(w: np.ndarray) -> np.ndarray:
    return pin.exp3(np.asarray(w, dtype=float))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors (np.cross costs ~30 µs a call: too much inside a tick)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


class StateEstimator:
    """Complementary-filter orientation + stance-leg kinematics (module docstring).

    ``com_height`` (m) sets ω₀; ``tilt_gain`` (1/s) is the accelerometer's pull on the
    orientation; ``velocity_cutoff`` (Hz) the CoM velocity filter; ``use_imu=False``:
    encoders only.
    """

    def __init__(
        self,
        robot: Robot,
        com_height: float,
        use_imu: bool = True,
        tilt_gain: float = 0.2,
        velocity_cutoff: float = 6.0,
        gyro_heading: bool = False,
    ) -> None:
        for name, v in (
            ("com_height", com_height),
            ("tilt_gain", tilt_gain),
            ("velocity_cutoff", velocity_cutoff),
        ):
            if not (np.isfinite(v) and v > 0):
                raise WbcError(f"state estimator: {name} must be a finite number > 0, got {v}")
        self.robot = robot
        self.omega0 = float(np.sqrt(GRAVITY / com_height))
        self.use_imu = use_imu
        self.gyro_heading = gyro_heading
        self.tilt_gain = float(tilt_gain)
        self.cutoff = float(velocity_cutoff)
        self.model = robot.model
        self.data = robot.model.createData()
        self.sole_ids = {s: robot.frame_id(s) for s in SOLE_FRAMES}
        self._q = robot.neutral()
        torso = robot.model.frames[robot.frame_id("torso")]
        if torso.parentJoint != 1:
            raise WbcError("state estimator: the torso frame must be on the floating base")
        self.torso_b = torso.placement.rotation.copy()  # constant: torso in the base frame
        self.rotation: np.ndarray | None = None  # torso rotation (the filter's state)
        self._rel: dict[str, np.ndarray] = {}  # CoM relative to each sole, last tick
        self.com_vel = np.zeros(3)
        self.last: StateEstimate | None = None

    def reset(self, torso_rotation: np.ndarray) -> None:
        """Start the filter at a known torso rotation (e.g. the planned one, standing)."""
        self.rotation = np.array(torso_rotation, dtype=float)
        self._rel = {}
        self.com_vel = np.zeros(3)
        self.last = None

    def _orientation(self, reading: ImuReading, dt: float) -> np.ndarray:
        R = self.rotation
        omega = reading.angular_velocity
        a = reading.linear_acceleration
        norm = math.sqrt(float(a @ a))
        w = omega.copy()
        if 0.8 * GRAVITY < norm < 1.2 * GRAVITY:
            up_pred = R[2]  # Rᵀ e_z: the world's up in the torso frame
            w += (self.tilt_gain / norm) * cross(a, up_pred)
        R = R @ _exp(w * dt)
        self.rotation = R
        return R

    def update(
        self,
        dt: float,
        joints: np.ndarray,
        reading: ImuReading | None,
        stance: Sequence[tuple[str, pin.SE3]],
    ) -> StateEstimate:
        """One tick: ``joints`` the present positions (rad, model order), ``reading`` the
        IMU's sample (ignored with ``use_imu=False``), ``stance`` the support sole frame(s)
        with their planned placements."""
        if not stance:
            raise WbcError("state estimator: no stance sole given")
        m, d = self.model, self.data
        q = self._q
        q[7:] = joints
        com_b = pin.centerOfMass(m, d, q, False).copy()  # (runs the forward kinematics)
        soles = {name: pin.updateFramePlacement(m, d, self.sole_ids[name]) for name, _ in stance}
        torso_b = self.torso_b  # torso in the base frame
        # heading (and, encoders only, the whole rotation) from the first stance sole
        name0, anchor0 = stance[0]
        imu = self.use_imu and reading is not None
        R_kin = None
        if self.rotation is None or not imu or not self.gyro_heading:
            R_kin = anchor0.rotation @ soles[name0].rotation.T  # base rotation
        if self.rotation is None:
            self.reset(R_kin @ torso_b)
        if imu:
            R_t = self._orientation(reading, dt)
            if not self.gyro_heading:  # keep the filter's tilt, the heading of the kinematics
                yaw_kin = _yaw(R_kin @ torso_b)
                R_t = pin.rpy.rpyToMatrix(0.0, 0.0, yaw_kin - _yaw(R_t)) @ R_t
                self.rotation = R_t
            R_base = R_t @ torso_b.T
            omega = reading.angular_velocity
        else:
            R_base = R_kin
            self.rotation = R_base @ torso_b
            omega = np.zeros(3)
        bases, rel = [], {}
        for name, anchor in stance:
            sole_b = soles[name].translation
            bases.append(anchor.translation - R_base @ sole_b)
            rel[name] = R_base @ (com_b - sole_b)
        base = bases[0] if len(bases) == 1 else 0.5 * (bases[0] + bases[1])
        com = base + R_base @ com_b
        common = [s for s in rel if s in self._rel]
        if common and dt > 0:
            raw = rel[common[0]] - self._rel[common[0]]
            if len(common) == 2:
                raw = 0.5 * (raw + rel[common[1]] - self._rel[common[1]])
            alpha = math.exp(-2.0 * math.pi * self.cutoff * dt)
            self.com_vel = alpha * self.com_vel + ((1.0 - alpha) / dt) * raw
        self._rel = rel
        dcm = com + self.com_vel / self.omega0
        dcm[2] = com[2]
        # (fresh arrays every tick: the filter's state is reassigned, never written in place)
        self.last = StateEstimate(self.rotation, base, com, self.com_vel, dcm, omega)
        return self.last


def _yaw(R: np.ndarray) -> float:
    return float(np.arctan2(R[1, 0], R[0, 0]))
