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
from dataclasses import dataclass

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


class Imu(ABC):
    """A source of :class:`ImuReading` values (simulated or real)."""

    name: str = "imu"

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
