"""Getting up in the simulator (wbc.drive.getup_sim)."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from wbc.drive.getup_sim import drop, getup_sim
from wbc.drive.sim import make_sim
from wbc.exceptions import ConfigurationError
from wbc.model import load_robot

ROBOT = load_robot("bioloid")


def test_a_bad_side_is_one_clear_line() -> None:
    sim, _bus, _imu = make_sim(ROBOT)
    with pytest.raises(ConfigurationError, match="side must be one of"):
        drop(sim, ROBOT, "sideways")
    with pytest.raises(ConfigurationError, match="side must be one of"):
        getup_sim(ROBOT, "upside down")
