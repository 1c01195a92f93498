"""The IMU interface: readings are checked, and a user's own IMU plugs in."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc.exceptions import ConfigurationError
from wbc.imu import GRAVITY, Imu, ImuReading


def test_reading_rotation_and_tilt():
    half = math.radians(30) / 2
    r = ImuReading(0.5, [math.sin(half), 0, 0, math.cos(half)], [0, 0, 0], [0, 0, GRAVITY])
    np.testing.assert_allclose(
        r.rotation(), [[1, 0, 0], [0, math.cos(2 * half), -math.sin(2 * half)],
                       [0, math.sin(2 * half), math.cos(2 * half)]], atol=1e-12)  # fmt: skip
    assert math.degrees(r.tilt()) == pytest.approx(30)


@pytest.mark.parametrize(
    ("field", "value"),
    [("orientation", [0, 0, 1]), ("angular_velocity", [0, np.nan, 0]),
     ("linear_acceleration", [0, 0])],
)  # fmt: skip
def test_bad_readings_are_refused(field, value):
    good = {"orientation": [0, 0, 0, 1], "angular_velocity": [0, 0, 0],
            "linear_acceleration": [0, 0, GRAVITY]}  # fmt: skip
    with pytest.raises(ConfigurationError, match=f"ImuReading.{field}"):
        ImuReading(0.0, **{**good, field: value})


def test_a_user_imu_plugs_in():
    class Level(Imu):
        name = "level"

        def read(self) -> ImuReading:
            return ImuReading(1.0, [0, 0, 0, 1], [0, 0, 0], [0, 0, GRAVITY])

    with Level() as imu:
        assert imu.read().tilt() == 0.0
    with pytest.raises(TypeError):
        Imu()  # read() is abstract
