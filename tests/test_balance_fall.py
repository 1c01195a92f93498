"""Fall detection and the safe fall (wbc.balance.fall)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from wbc.balance.fall import FallDetector, FallParams
from wbc.exceptions import ConfigurationError, FallDetected


class Est:
    """A state estimate with the fields the detector reads."""

    def __init__(self, R=None, w=(0.0, 0.0, 0.0), dcm=(0.0, 0.0, 0.2)):
        self.rotation = np.eye(3) if R is None else R
        self.angular_velocity = np.asarray(w, dtype=float)
        self.dcm = np.asarray(dcm, dtype=float)


SOLES = [pin.SE3(np.eye(3), np.array([0.0, 0.04, 0.0])),
         pin.SE3(np.eye(3), np.array([0.0, -0.04, 0.0]))]  # fmt: skip


def test_upright_walking_states_are_not_falls():
    det = FallDetector()
    for k in range(50):
        e = np.array([0.3 * math.sin(k), 0.05, 0.3])  # ≤ 17.5° tilt error, a heading error
        assert det.update(Est(w=(3.0, 0.0, 1.0), dcm=(0.05, 0.1, 0.2)), SOLES, 0.01, e) is None
    assert det.reason is None


def test_tilt_beyond_the_bound_is_a_fall():
    det = FallDetector()
    e = np.array([math.radians(41.0), 0.0, 0.0])
    assert "tilted 41°" in det.update(Est(), SOLES, 0.01, e)
    assert det.time == 0.0


def test_a_moderate_tilt_is_a_fall_only_while_it_grows_fast():
    det = FallDetector()
    e = np.array([0.0, math.radians(25.0), 0.0])  # pitched 25° about +y
    assert det.update(Est(w=(0.0, -3.0, 0.0)), SOLES, 0.01, e) is None  # turning back
    assert det.update(Est(w=(0.0, 1.5, 0.0)), SOLES, 0.01, e) is None  # growing slowly
    assert "falling at 2.5 rad/s" in det.update(Est(w=(0.0, 2.5, 0.0)), SOLES, 0.01, e)
    assert det.time == pytest.approx(0.02)


def test_a_dcm_beyond_any_step_is_a_fall_after_dcm_ticks():
    det = FallDetector(FallParams(dcm_ticks=3))
    far = Est(dcm=(0.05 + 0.16, 0.0, 0.2))  # 0.16 m beyond the front edge (> reach 0.15)
    assert det.update(far, SOLES, 0.01, np.zeros(3)) is None
    assert det.update(far, SOLES, 0.01, np.zeros(3)) is None
    with pytest.raises(FallDetected, match="DCM 160 mm beyond the support"):
        det.raise_if_falling(far, SOLES, 0.01, np.zeros(3))


def test_bad_parameters_one_line():
    with pytest.raises(ConfigurationError, match="torque_limit must be in"):
        FallParams(torque_limit=2.0).check()
    with pytest.raises(ConfigurationError, match="dcm_ticks must be an integer"):
        FallParams(dcm_ticks=0).check()
    with pytest.raises(ConfigurationError, match="rate must be a finite number"):
        FallParams(rate=-1.0).check()


def test_a_push_beyond_recovery_ends_in_the_safe_fall(robot):
    """walk10_wb closed loop, 2.5 N·s forward at mid single support (the LIPM bound with a
    step is 1.03 N·s): detected within 100 ms of the push, the torque limit lowered, the
    protective posture taken and every servo's torque verified off."""
    pytest.importorskip("mujoco")
    from wbc.bench import closed_loop, pushes
    from wbc.bench.solvers import registry
    from wbc.bench.trajectories import build
    from wbc.recording import SUPPORT_DOUBLE

    ref = build("walk10_wb", robot)
    a, b = next((a, b) for a, b, c in ref.phases() if c != SUPPORT_DOUBLE)
    t_push = 0.5 * (ref.t[a] + ref.t[b - 1]) - ref.t[0]
    spec = closed_loop.ClosedLoopSpec(registry()["wqp-daqp"].make, ref)
    force = np.array([2.5 / pushes.PUSH_DURATION, 0.0, 0.0])
    result, loop = closed_loop.play_closed_loop(spec, robot, push=(t_push, force, 0.01), settle=0.2)
    fall = loop.stabilizer.fall
    assert fall.time is not None and 0.0 <= fall.time - t_push - 0.01 <= 0.1, fall.reason
    assert result.deploy.stop_action.startswith("fall: torque limit 30 %, protective posture")
    assert result.deploy.stop_action.endswith("torque-off")
    assert not result.sim.servos.enabled.any()
    cap = result.sim.servos.params.torque_cap
    assert np.allclose(cap, result.sim.servos.params.stall_torque * round(0.3 * 1023) / 1023)
