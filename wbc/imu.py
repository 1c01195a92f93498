"""The IMU interface: what a balance controller may read from a torso IMU.

An implementation (the simulated torso IMU :class:`wbc.sim.SimImu`, a USB/serial IMU on the
real robot, another simulator) subclasses :class:`Imu` and returns :class:`ImuReading` values.
Conventions (those of the rest of wbc):

* ``orientation``: unit quaternion ``(x, y, z, w)`` of the IMU frame in the world frame
  (z up; the heading is whatever the sensor's yaw reference is);
* ``angular_velocity``: rad/s, in the IMU frame (what a gyro measures);
* ``linear_acceleration``: m/s², in the IMU frame, *specific force* as an accelerometer
  measures it: at rest it reads ``+9.81`` along the IMU's up axis (gravity is not removed);
* ``t``: seconds on the clock of the source (simulation time, or the host's monotonic clock).

A user plugging in hardware implements :meth:`Imu.read` (and :meth:`Imu.open` /
:meth:`Imu.close` if a port must be opened)::

    class MyImu(Imu):
        name = "my-imu"
        def read(self) -> ImuReading:
            x, y, z, w, gx, gy, gz, ax, ay, az = my_driver.sample()
            return ImuReading(time.monotonic(), np.array([x, y, z, w]),
                              np.array([gx, gy, gz]), np.array([ax, ay, az]))
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from .exceptions import ConfigurationError, WbcError


class ImuError(WbcError):
    """An IMU could not be opened or read (the message names the device and what to check)."""


#: standard gravity (m/s²)
GRAVITY = 9.80665
_FLOAT = np.dtype(float)


@dataclass(frozen=True)
class ImuReading:
    """One IMU sample (see the module docstring for frames and units)."""

    t: float
    orientation: np.ndarray  # (4,) quaternion x, y, z, w
    angular_velocity: np.ndarray  # (3,) rad/s, IMU frame
    linear_acceleration: np.ndarray  # (3,) m/s², IMU frame, specific force

    def __post_init__(self) -> None:
        o, w, a = self.orientation, self.angular_velocity, self.linear_acceleration
        if (  # float arrays of the right sizes, all finite: the one path of every control tick
            type(o) is type(w) is type(a) is np.ndarray
            and o.dtype is w.dtype is a.dtype is _FLOAT
            and o.shape == (4,)
            and w.shape == a.shape == (3,)
            and math.isfinite(sum(o.tolist()) + sum(w.tolist()) + sum(a.tolist()))
        ):
            return
        for name, size in (("orientation", 4), ("angular_velocity", 3), ("linear_acceleration", 3)):
            v = getattr(self, name)
            if type(v) is not np.ndarray or v.dtype != np.float64:
                v = np.asarray(v, dtype=float)
                object.__setattr__(self, name, v)
            # (cheap, in every control tick: the sum is NaN or ±inf if a value is, or overflows)
            if v.shape != (size,) or not math.isfinite(sum(v.tolist())):
                raise ConfigurationError(
                    f"ImuReading.{name}: expected {size} finite values, got {v}"
                )

    def rotation(self) -> np.ndarray:
        """The orientation as a 3x3 rotation matrix (IMU frame -> world)."""
        x, y, z, w = self.orientation / np.linalg.norm(self.orientation)
        return np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ])  # fmt: skip

    def tilt(self) -> float:
        """Angle (rad) between the IMU's z axis and the world's vertical."""
        return float(np.arccos(np.clip(self.rotation()[2, 2], -1.0, 1.0)))


@dataclass(frozen=True)
class ImuMount:
    """Where the IMU sits on the torso: its frame's ``rotation`` (3x3, IMU axes in the torso
    frame) and ``position`` (m, its origin in the torso frame). :meth:`to_torso` turns a
    reading into the torso's: ``R_torso = R_imu Mᵀ``, ``ω_torso = M ω``, and the specific
    force ``M a − ω × (ω × p)`` (the lever arm's centripetal part removed; its angular
    acceleration part is not, it averages out over a gait)."""

    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        R = np.asarray(self.rotation, dtype=float)
        p = np.asarray(self.position, dtype=float)
        if (
            R.shape != (3, 3)
            or not np.allclose(R @ R.T, np.eye(3), atol=1e-6)
            or (np.linalg.det(R) < 0)
        ):
            raise ConfigurationError(f"ImuMount.rotation must be a 3x3 rotation, got {R.tolist()}")
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ConfigurationError(f"ImuMount.position must be 3 finite numbers (m), got {p}")
        object.__setattr__(self, "rotation", R)
        object.__setattr__(self, "position", p)

    @classmethod
    def from_rpy(cls, rpy_deg=(0.0, 0.0, 0.0), position=(0.0, 0.0, 0.0)) -> ImuMount:
        """A mount from roll, pitch, yaw (degrees, ``R = Rz(y) Ry(p) Rx(r)``)."""
        r, p, y = np.radians(np.asarray(rpy_deg, dtype=float))
        cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
        R = np.array([
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ])  # fmt: skip
        return cls(R, np.asarray(position, dtype=float))

    @property
    def identity(self) -> bool:
        """True when the IMU frame is the torso frame."""
        return bool(np.array_equal(self.rotation, np.eye(3)) and not self.position.any())

    def rates(self, gyro: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The torso's rate and specific force from the IMU's (class docstring)."""
        M, p = self.rotation, self.position
        w = M @ gyro
        return w, M @ acc - np.cross(w, np.cross(w, p))

    def to_torso(self, reading: ImuReading) -> ImuReading:
        """The reading of an IMU at the torso frame (class docstring)."""
        w, a = self.rates(reading.angular_velocity, reading.linear_acceleration)
        x, y, z, qw = _quat_of(reading.rotation() @ self.rotation.T)
        return ImuReading(reading.t, np.array([x, y, z, qw]), w, a)


def _quat_of(R: np.ndarray) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation matrix (Shepperd's method)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return ((R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s,
                0.25 * s)  # fmt: skip
    i = int(np.argmax([R[0, 0], R[1, 1], R[2, 2]]))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(max(1.0 + R[i, i] - R[j, j] - R[k, k], 1e-12))
    q = [0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (R[j, i] + R[i, j]) / s
    q[k] = (R[k, i] + R[i, k]) / s
    return q[0], q[1], q[2], (R[k, j] - R[j, k]) / s


@dataclass(frozen=True)
class ImuCalibration:
    """A start-up calibration at rest (:func:`calibrate`): the gyro bias (rad/s, torso
    frame), the levelling rotation ``level`` (applied to the specific force: it turns the
    measured gravity direction onto the kinematic one) and the angle between the two
    (``tilt_error``, rad) before levelling."""

    gyro_bias: np.ndarray
    level: np.ndarray
    tilt_error: float
    samples: int

    def apply(self, reading: ImuReading) -> ImuReading:
        """A (torso-frame) reading with the bias removed and the specific force levelled."""
        return ImuReading(
            reading.t,
            reading.orientation,
            reading.angular_velocity - self.gyro_bias,
            self.level @ reading.linear_acceleration,
        )


#: rad: the largest angle between the measured and the kinematic gravity direction that a
#: start-up calibration levels; beyond it the IMU's mount is wrong (reported, not absorbed)
MOUNT_TOLERANCE = math.radians(5.0)


def calibrate(
    gyros: np.ndarray,
    accs: np.ndarray,
    expected_up: np.ndarray,
    tolerance: float = MOUNT_TOLERANCE,
    where: str = "the IMU mount",
    motion: np.ndarray | None = None,
) -> ImuCalibration:
    """Calibration from samples at rest (torso frame, rows): the gyro bias is their mean
    less ``motion`` (rad/s: the torso's true mean rate meanwhile, e.g. from the kinematics);
    the measured "up" (the mean specific force's direction) is compared with
    ``expected_up`` (the torso frame's up from the standing robot's kinematics). Beyond
    ``tolerance`` raises :class:`ImuError` naming the angle and ``where`` (the mount is
    wrong: not silently absorbed); within it, the levelling rotation takes the rest."""
    g = np.atleast_2d(np.asarray(gyros, dtype=float))
    a = np.atleast_2d(np.asarray(accs, dtype=float))
    if len(g) < 1 or len(g) != len(a) or g.shape[1] != 3 or a.shape[1] != 3:
        raise ConfigurationError(f"IMU calibration needs N x 3 gyro and accelerometer samples, "
                                 f"got {g.shape} and {a.shape}")  # fmt: skip
    up = a.mean(axis=0)
    norm = float(np.linalg.norm(up))
    if not 0.5 * GRAVITY < norm < 1.5 * GRAVITY:
        raise ImuError(f"IMU calibration: the accelerometer reads {norm:.2f} m/s² at rest, "
                       f"not g ({GRAVITY:g}): not at rest, or its scale is wrong")  # fmt: skip
    up /= norm
    e = np.asarray(expected_up, dtype=float)
    e = e / np.linalg.norm(e)
    axis = np.cross(up, e)
    s, c = float(np.linalg.norm(axis)), float(up @ e)
    angle = math.atan2(s, c)
    if angle > tolerance:
        raise ImuError(
            f"IMU calibration: gravity measured {math.degrees(angle):.1f}° from where the "
            f"robot's kinematics put it (tolerance {math.degrees(tolerance):.0f}°): check "
            f"{where} (measured up {np.round(up, 3).tolist()}, expected "
            f"{np.round(e, 3).tolist()} in the torso frame)"
        )
    level = np.eye(3)
    if s > 1e-12:
        k = axis / s
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        level = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    bias = g.mean(axis=0) - (np.zeros(3) if motion is None else np.asarray(motion, dtype=float))
    return ImuCalibration(bias, level, angle, len(g))


#: rad/s: the gyro's motion over a window (:func:`window_spread`, 3 axes) below which a
#: settling calibration (:func:`quietest_window`'s caller) takes the robot as still
SETTLE_STILL = 0.01


def window_spread(gyros: np.ndarray) -> float:
    """The motion in a window of gyro samples (rows, rad/s, at a steady rate): the true bias
    is constant, so the samples' spread about their mean is motion and white noise,
    ``mean |ω_k − ω̄|²``, less the noise's share estimated from successive differences
    (``mean |ω_k − ω_{k−1}|² / 2``: smooth motion hardly changes between samples);
    ``sqrt`` of what is left (0 if none)."""
    g = np.asarray(gyros, dtype=float)
    total = float(np.mean(np.sum((g - g.mean(axis=0)) ** 2, axis=1)))
    noise = 0.5 * float(np.mean(np.sum(np.diff(g, axis=0) ** 2, axis=1))) if len(g) > 1 else 0.0
    return math.sqrt(max(0.0, total - noise))


def quietest_window(gyros: np.ndarray, length: int, first_end: int) -> int:
    """The start of the ``length``-sample window of ``gyros`` (rows) with the least
    :func:`window_spread`, among those ending at sample ``first_end`` (exclusive end index)
    or later: where the robot turned least, so its mean is the bias with least motion in it."""
    g = np.atleast_2d(np.asarray(gyros, dtype=float))
    length = max(1, min(int(length), len(g)))
    starts = range(max(0, min(int(first_end), len(g)) - length), len(g) - length + 1)
    return min(starts, key=lambda i: window_spread(g[i : i + length]))


class Imu(ABC):
    """A source of :class:`ImuReading` values (simulated or real). ``mount``: where it sits
    on the torso (:class:`ImuMount`; None: its frame is the torso frame); the closed loop
    turns every reading into the torso's with it."""

    name: str = "imu"
    mount: ImuMount | None = None

    def open(self) -> None:  # noqa: B027 - optional hook
        """Open the device (default: nothing to open)."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release the device (safe to call twice)."""

    @abstractmethod
    def read(self) -> ImuReading:
        """The latest sample."""

    def __enter__(self) -> Imu:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()
