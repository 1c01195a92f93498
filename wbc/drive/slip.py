"""The stance sole's slip from the IMU: what the encoders cannot see of a driven walk.

The outer loop's odometry (:class:`~wbc.drive.odometry.PoseOdometry`) chains the soles: at
each landing the landed sole is placed from the stance sole by the encoders, and a stance
sole is taken not to slide. On the compliant randomised Bioloids it does (a random ±2 mm a
landing on model 0, benchmarks/drive.md). :class:`SlipEstimate` measures it as a real robot
can: over each stance interval (from a sole's landing to the next landing, the landed sole
then the stance sole throughout), the torso's horizontal displacement by the IMU — its
specific force, on the torso's rotation (the encoders' tilt over the stance sole, the
odometry's heading), integrated twice from the velocity the stance leg's kinematics give at
the interval's start — against the displacement the stance leg's kinematics give (the
torso from the stance sole, the sole taken still). The difference is the sole's slide (plus
the integration's noise and the tilt's error); the share ``gain`` of it, within ``most``
(m), moves the stance sole in the odometry before the landed sole is placed from it
(``Walker(slip_gain=...)``, off by default).

**Not usable on the simulated Bioloids** (benchmarks/drive.md, 2026-12-07, nineteenth
session; ``benchmarks/slip_probe.py``): per stance interval the slide is ±2.7–2.9 mm on model
0, the estimate's error ±47–58 mm (the start velocity the legs give, over 5 ticks); with
the simulator's own start velocity and rotation still ±14 mm (the simulated accelerometer
samples the contacts' and servos' vibration unfiltered), with an ideal low-passed one ±6 mm
(the legs' own torso displacement is ±4.5 mm off over a step: the soles roll, the play).
The best gain, fitted on the truth, takes 0–1 % off the slide's spread (13–18 % with the
simulator's start velocity, 9–25 % with a perfect IMU). At ``slip_gain=0.05`` the errors
of runs 13/0, 3/15 and 0/0 grew 47 → 71, 34 → 94 and 10 → 84 mm.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..exceptions import ConfigurationError
from ..geometry import clip_norm, heading_free, rot2, rot_z
from ..imu import Imu, ImuReading
from ..model import Robot
from ..roles import SOLE_FRAMES
from ..walking.footsteps import Side

GRAVITY_Z = 9.81  # m/s² (the calibration levels the specific force to the kinematics' up)


class LastReading(Imu):
    """An IMU whose last reading is kept (:attr:`last`): the one the stabiliser took."""

    def __init__(self, imu: Imu) -> None:
        self.imu = imu
        self.last: ImuReading | None = None
        self.name = getattr(imu, "name", "imu")
        self.mount = getattr(imu, "mount", None)

    def open(self) -> None:
        self.imu.open()

    def close(self) -> None:
        self.imu.close()

    def read(self) -> ImuReading:
        self.last = self.imu.read()
        return self.last


class SlipEstimate:
    """The stance sole's slide per stance interval by the IMU against the kinematics
    (module docstring). :meth:`tick` every walking tick, :meth:`landed` at each landing
    (returns the stance sole's slide, m, world xy, to move it by)."""

    def __init__(self, robot: Robot, gain: float, most: float = 0.005, window: int = 5) -> None:
        if not (math.isfinite(gain) and 0.0 <= gain <= 1.0):
            raise ConfigurationError(f"slip gain must be in [0, 1], got {gain}")
        if not (math.isfinite(most) and most >= 0.0):
            raise ConfigurationError(f"slip most must be a finite number >= 0 (m), got {most}")
        if window < 1:
            raise ConfigurationError(f"slip window must be >= 1 tick, got {window}")
        self.robot, self.gain, self.most, self.window = robot, float(gain), float(most), window
        self.anchor: Side | None = None  # the interval's stance sole (the last landed)
        self._rel: list[np.ndarray] = []  # the torso from the anchor sole (kinematics), per tick
        self._velocity: np.ndarray | None = None  # the torso's, world xy (m/s), IMU-integrated
        self._imu = np.zeros(2)  # the torso's displacement by the IMU this interval (m)
        self._kin = np.zeros(2)  # ... by the kinematics (m)
        self._acc = np.zeros(2)  # the last tick's horizontal acceleration (m/s², world)
        self.last = np.zeros(2)  #: the last interval's slide estimated (m, world xy)

    def restart(self) -> None:
        """A new walk: no interval under way."""
        self.anchor, self._velocity = None, None
        self._rel.clear()
        self._imu[:], self._kin[:] = 0.0, 0.0

    def tick(
        self, q: np.ndarray, acc: np.ndarray, sole_heading: float, heading: float, dt: float
    ) -> None:
        """One tick: ``q`` the present joints' configuration, ``acc`` the calibrated specific
        force (m/s², torso frame), ``sole_heading`` the anchor sole's heading and ``heading``
        the torso's (rad, world, the odometry's)."""
        if self.anchor is None:
            return
        (torso,) = self.robot.placements_in(q, SOLE_FRAMES[self.anchor], ["torso"])
        rel = rot2(sole_heading) @ torso.translation[:2]  # the torso from the sole, world axes
        rows = self._rel
        if self._velocity is None:  # (the interval's first ticks: the kinematics' velocity)
            rows.append(rel)
            if len(rows) <= self.window:
                return
            self._velocity = (rows[-1] - rows[0]) / (self.window * dt)
            self._rel = [rel]
        else:  # the last tick's specific force over the last dt, against the legs' move
            a = self._acc
            self._imu += self._velocity * dt + 0.5 * a * dt * dt
            self._velocity = self._velocity + a * dt
            self._kin += rel - rows[-1]
            rows[-1] = rel
        # the torso's tilt by the kinematics, its heading the odometry's
        world = rot_z(heading) @ heading_free(torso.rotation) @ acc
        self._acc = world[:2]

    def landed(self, side: Side) -> np.ndarray:
        """``side`` has landed: the interval of the other (stance) sole ends; returns the
        share of its slide to move that sole by (m, world xy), and starts ``side``'s."""
        slide = np.zeros(2)
        if self.anchor is not None and self.anchor != side and self._velocity is not None:
            self.last = self._imu - self._kin
            slide = clip_norm(self.gain * self.last, self.most)
        self.anchor = side
        self._velocity = None
        self._rel = []
        self._imu[:], self._kin[:] = 0.0, 0.0
        return slide

    def walker_tick(self, walker: Any, dt: float) -> None:
        """:meth:`tick` from a :class:`~wbc.drive.walker.Walker`'s state after its estimate:
        the IMU's last reading (its :class:`LastReading`) with the stabiliser's mount and
        calibration, the present joints (the play out), the odometry's headings."""
        stab, odo = walker.stabilizer, walker.odometry
        reading = getattr(stab.imu, "last", None)
        q = walker._present_configuration()
        if reading is None or q is None or self.anchor is None or odo is None:
            return
        w, a = reading.angular_velocity, reading.linear_acceleration
        if stab.mount is not None:
            w, a = stab.mount.rates(w, a)
        if stab.calibration is not None:
            a = stab.calibration.level @ a
        self.tick(q, np.asarray(a, dtype=float), float(odo.soles[self.anchor][2]),
                  float(odo.heading), dt)  # fmt: skip
