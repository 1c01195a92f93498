"""Standing still after a walk: no torso feedback (wbc.drive.stand)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from wbc.drive.stand import DRIVE_QUIET_STAND, QUIET_STAND_MODES, QuietStand
from wbc.exceptions import ConfigurationError
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT


def _tick(state: str, double: bool = True) -> SimpleNamespace:
    return SimpleNamespace(state=state, support=SUPPORT_DOUBLE if double else SUPPORT_LEFT)


def test_quiet_stand_says_when_the_robot_stands_still() -> None:
    """``"end"``: quiet in the walk's end phase (a closing step landed: the engine's
    ``ending``), while the engine stands and, until the next start, in a finish step's
    double supports (its start and end phases; not its single support); ``"standing"``:
    only while the engine stands, never while a start is asked; ``""``: never. A mode not
    known is refused, with ``on`` False too."""
    # (state, double support, ending, starting): a walk, its stop, a finish step
    walk = [("walking", True, False, False), ("walking", False, False, False),
            ("stopping", True, False, False), ("stopping", False, False, False),
            ("stopping", True, True, False), ("standing", True, False, False),
            ("standing", True, False, True), ("walking", True, False, False),
            ("walking", False, False, False), ("walking", True, True, False),
            ("standing", True, False, False)]  # fmt: skip
    expected = {
        "end": [False, False, False, False, True, True, True, True, False, True, True],
        "standing": [False] * 5 + [True, False, False, False, False, True],
        "": [False] * 11,
    }
    for mode, want in expected.items():
        quiet = QuietStand(mode)
        got = [quiet(_tick(state, double), starting, ending)
               for state, double, ending, starting in walk]  # fmt: skip
        assert got == want, mode
        quiet.start()  # a walk starts: the feedback on from its start phase
        assert quiet(_tick("standing"), True, False) is False
        assert quiet(_tick("walking"), False, False) is False
        assert quiet(_tick("stopping"), False, False) is False
    assert QuietStand("end", on=False)(_tick("standing"), False, False) is False
    assert QuietStand("end", on=False)(_tick("stopping"), False, True) is False
    assert DRIVE_QUIET_STAND in QUIET_STAND_MODES
    for bad in ("yes", None, "END"):
        with pytest.raises(ConfigurationError, match="quiet_stand must be one of"):
            QuietStand(bad)  # type: ignore[arg-type]
        with pytest.raises(ConfigurationError, match="quiet_stand must be one of"):
            QuietStand(bad, on=False)  # type: ignore[arg-type]


@pytest.mark.parametrize("mode", ["end", ""])
def test_the_walker_stands_without_torso_feedback_after_its_walk(mode: str) -> None:
    """The walker (outer loop, IMU) walks on the spot and stops; from the closing step's
    landing (its end phase) on, with ``quiet_stand`` "end", its stabilizer runs without the
    torso feedback (k_p, k_i, k_d 0) and with the integral unwound (this tick's error in it
    alone), and a new start brings the walking gains back; off, the walking gains stay on.
    """
    pytest.importorskip("mujoco")
    from wbc.bench.solvers import registry
    from wbc.drive.sim import make_sim
    from wbc.drive.walker import Walker
    from wbc.model import load_robot

    robot = load_robot("bioloid")
    _sim, _bus, imu = make_sim(robot)
    walker = Walker(robot, registry("physics")["hqp-daqp"].make(robot), imu,
                    yaw_rest_s=0.1, quiet_stand=mode)  # fmt: skip
    walker.present = lambda: walker.q[7:]
    walking = walker._gains[0]
    assert walking.k_p > 0 and walking.k_d > 0
    walker.start()
    while walker.calibrating:
        walker.tick()
    seen: set[float] = set()
    for _ in range(150):
        walker.tick()
        seen.add(walker.stabilizer.gains.k_p)
    assert seen == {walking.k_p}  # walking: the torso feedback on
    walker.stop()
    ending: set[float] = set()  # k_p in the end phase (the closing step landed)
    for _ in range(400):
        walker.tick()
        if walker.engine.ending:
            ending.add(walker.stabilizer.gains.k_p)
        if not walker.walking:
            break
    assert not walker.walking
    assert ending == ({0.0} if mode == "end" else {walking.k_p})
    walker.tick()
    gains = walker.stabilizer.gains
    if mode:
        assert (gains.k_p, gains.k_i, gains.k_d) == (0.0, 0.0, 0.0)
        stab = walker.stabilizer  # (unwound before the tick: this tick's error alone)
        np.testing.assert_allclose(stab.integral, stab.error * walker.engine.dt, atol=1e-12)
    else:
        assert gains is walking
    walker.start()
    walker.tick()
    assert walker.stabilizer.gains is walking
