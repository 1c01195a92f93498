"""The feed-forward's inertial field gated (issue 30, seventeenth session): ``Gains.
ff_inertial_back`` (along the heading, backward only) and ``ff_inertial_band`` (while the
DCM lags its reference), :mod:`wbc.balance.inertial_ff` and the closed loop's wiring."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from wbc.balance.inertial_ff import gated_field
from wbc.balance.stabilizer import Gains
from wbc.exceptions import ConfigurationError

ACC = np.array([-0.6, 0.4, 0.1])


def test_no_gate_is_the_field_itself() -> None:
    assert np.array_equal(gated_field(ACC, 0.3, None, False, 0.0), ACC)


def test_back_keeps_the_backward_part_along_the_heading_only() -> None:
    got = gated_field(ACC, 0.0, None, True, 0.0)
    assert np.allclose(got, [-0.6, 0.0, 0.1])  # the sideways part dropped, z kept
    assert np.allclose(gated_field(-ACC, 0.0, None, True, 0.0), [0.0, 0.0, -0.1])  # forward: none
    h = math.pi / 2  # walking along +y: the part along y, backward only
    assert np.allclose(gated_field(ACC, h, None, True, 0.0), [0.0, 0.0, 0.1], atol=1e-12)
    assert np.allclose(gated_field(-ACC, h, None, True, 0.0), [0.0, -0.4, -0.1], atol=1e-12)


def test_band_feeds_while_the_dcm_lags_and_releases_ahead() -> None:
    band = 0.005
    assert np.allclose(gated_field(ACC, 0.0, np.array([-0.01, 0.0]), False, band), ACC)
    assert np.allclose(gated_field(ACC, 0.0, np.array([-0.0025, 0.3]), False, band), 0.5 * ACC)
    assert np.allclose(gated_field(ACC, 0.0, np.array([0.002, 0.0]), False, band), 0.0)
    assert np.allclose(gated_field(ACC, 0.0, None, False, band), 0.0)  # not yet estimated
    # along the heading: a lag sideways of the walk opens nothing
    assert np.allclose(gated_field(ACC, 0.0, np.array([0.0, -0.05]), False, band), 0.0)
    # from a lag of 20 mm on (``ff_inertial_from``): the walk's own lag left out
    assert np.allclose(gated_field(ACC, 0.0, np.array([-0.015, 0.0]), False, 0.01, 0.02), 0.0)
    assert np.allclose(gated_field(ACC, 0.0, np.array([-0.025, 0.0]), False, 0.01, 0.02), 0.5 * ACC)
    assert np.allclose(gated_field(ACC, 0.0, np.array([-0.04, 0.0]), False, 0.01, 0.02), ACC)
    both = gated_field(ACC, 0.0, np.array([-0.0025, 0.0]), True, band)
    assert np.allclose(both, [-0.3, 0.0, 0.05])


def test_gains_refuse_bad_values_and_default_off() -> None:
    g = Gains()
    assert g.ff_inertial == 0 and g.ff_inertial_back == 0 and g.ff_inertial_band == 0
    assert g.ff_inertial_first == 0 and g.ff_inertial_from == 0
    g.check()
    with pytest.raises(ConfigurationError, match="ff_inertial_back"):
        Gains(ff_inertial_back=0.5).check()
    with pytest.raises(ConfigurationError, match="ff_inertial_band"):
        Gains(ff_inertial_band=-0.01).check()
    with pytest.raises(ConfigurationError, match="ff_inertial_from"):
        Gains(ff_inertial_from=-0.01).check()


class _Est:
    def __init__(self, dcm) -> None:
        self.dcm = np.asarray(dcm, dtype=float)


class _Stab:
    def __init__(self) -> None:
        self.last: _Est | None = None


def test_the_closed_loop_field_follows_the_replanned_reference_and_the_gate(robot) -> None:
    """The field is read from ``session.ref`` at each call (a re-planned plan's own ``c̈``),
    × ``ff_inertial``, gated by the estimate's DCM against the plan's."""
    from wbc.balance.live import _inertial_field
    from wbc.bench.trajectories import build
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    ref = build("walk10", robot)
    session = Session(StackController(load_stack("walk", robot)), robot, ref)
    stab = _Stab()
    session.stabilizer = stab  # type: ignore[assignment]
    i = int(np.argmax(np.abs(ref.com_acc[:, 0])))
    session._last_index = i  # (the tick just solved)
    plain = _inertial_field(session, Gains(ff_inertial=2.0))
    assert np.allclose(plain(0.0), 2.0 * ref.com_acc[i])
    session.ref = replace(ref, com_acc=3.0 * ref.com_acc)
    assert np.allclose(plain(0.0), 6.0 * ref.com_acc[i])  # the re-planned plan's
    session.ref = ref
    gated = _inertial_field(session, Gains(ff_inertial=1.0, ff_inertial_band=0.01))
    assert np.allclose(gated(0.0), 0.0)  # no estimate yet
    u = np.array([math.cos(ref.torso_yaw[i]), math.sin(ref.torso_yaw[i])])
    stab.last = _Est(ref.dcm_at(i) - 0.005 * u)
    assert np.allclose(gated(0.0), 0.5 * ref.com_acc[i])
    stab.last = _Est(ref.dcm_at(i) + 0.005 * u)
    assert np.allclose(gated(0.0), 0.0)
    scoped = _inertial_field(session, Gains(ff_inertial=1.0, ff_inertial_band=0.01,
                                            ff_inertial_from=0.02))  # fmt: skip
    stab.last = _Est(ref.dcm_at(i) - 0.025 * u)
    assert np.allclose(scoped(0.0), 0.5 * ref.com_acc[i])


def test_ff_inertial_first_keeps_the_first_plans_acceleration(robot) -> None:
    """``ff_inertial_first``: the walk's first plan's ``c̈``, a re-planned one ignored."""
    from wbc.balance.live import _inertial_field
    from wbc.bench.trajectories import build
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    ref = build("walk10", robot)
    session = Session(StackController(load_stack("walk", robot)), robot, ref)
    session.stabilizer = _Stab()  # type: ignore[assignment]
    i = int(np.argmax(np.abs(ref.com_acc[:, 0])))
    session._last_index = i
    field = _inertial_field(session, Gains(ff_inertial=1.0, ff_inertial_first=1))
    session.ref = replace(ref, com_acc=3.0 * ref.com_acc)
    assert np.allclose(field(0.0), ref.com_acc[i])
    with pytest.raises(ConfigurationError, match="ff_inertial_first"):
        Gains(ff_inertial_first=2).check()
