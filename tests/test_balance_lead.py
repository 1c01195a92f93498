"""The servos' lag led (issue 30, sixteenth session): ``Gains.ref_lead`` (the reference played
ahead of the walk's clock) and ``Gains.goal_lead`` (the goals led by the solved joints'
velocity), both in :class:`wbc.balance.live.SessionSource`."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.balance.stabilizer import Gains
from wbc.exceptions import ConfigurationError


class _Stab:
    """A stand-in stabilizer: enabled, walking (not calibrating), no joint offsets."""

    def __init__(self, gains: Gains) -> None:
        self.gains, self.enabled, self.calibrating = gains, True, False
        self.clock, self.read_time = 1.0, 0.0

    def joint_offsets(self, joints):
        return None


def _source(robot, gains: Gains):
    """A SessionSource whose session's solve at time t is ``robot``'s stand with every
    joint moved by ``0.1 t`` rad (asked times recorded in ``asked``)."""
    from wbc.balance.live import SessionSource
    from wbc.bench.trajectories import build
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    session = Session(StackController(load_stack("walk", robot)), robot, build("walk10", robot))
    session.stabilizer = _Stab(gains)  # type: ignore[assignment]
    base, asked = session.q.copy(), []

    def at_time(t: float) -> np.ndarray:
        asked.append(t)
        q = base.copy()
        q[7:] += 0.1 * t
        return q

    session.at_time = at_time  # type: ignore[method-assign]
    return SessionSource(session), base[7:], asked


@pytest.mark.parametrize("lead", [0.0, 0.04])
def test_ref_lead_plays_the_reference_ahead(robot, lead: float) -> None:
    """Every tick asks the session for the walk's time + ``ref_lead`` (0: the walk's own)."""
    source, _, asked = _source(robot, Gains(ref_lead=lead))
    for tick in range(5):
        source(tick, 0.01 * tick)
    assert asked == pytest.approx([0.01 * k + lead for k in range(5)])


def test_goal_lead_leads_the_goals_by_the_joints_velocity(robot) -> None:
    """The first tick's goals are the solve's; then ``j + goal_lead (j − j_prev) / dt``
    (the joints move 0.1 rad/s: 0.004 rad ahead at 0.04 s), within the joint limits."""
    source, j0, _ = _source(robot, Gains(goal_lead=0.04))
    plain, _, _ = _source(robot, Gains())
    assert np.allclose(source(0, 0.0), j0)
    for tick in range(1, 4):
        t = 0.01 * tick
        want = np.clip(j0 + 0.1 * t + 0.04 * 0.1, robot.q_min, robot.q_max)
        assert np.allclose(source(tick, t), want)
        assert np.allclose(plain(tick, t), np.clip(j0 + 0.1 * t, robot.q_min, robot.q_max))


@pytest.mark.parametrize("code", [0, 1, 2])
def test_goal_lead_stance_leads_only_the_loaded_legs_pitch_joints(robot, code: int) -> None:
    """With ``goal_lead_stance`` only the hip pitch, knee and ankle pitch of the legs on the
    floor in the tick's planned support are led (double: both legs; 1 / 2: the left /
    right); every other joint gets the solve's goal."""
    from wbc.balance.live import sagittal_scale

    source, j0, _ = _source(robot, Gains(goal_lead=0.04, goal_lead_stance=1.0))
    source.session.ref.support[:] = code
    source.session._last_index = 5
    sides = {0: ("left", "right"), 1: ("left",), 2: ("right",)}[code]
    led = sagittal_scale(robot, 0.0, sides) == 0.0
    assert led.sum() == 3 * len(sides)
    source(0, 0.0)
    out = source(1, 0.01)
    j = j0 + 0.001
    assert np.allclose(out[led], np.clip(j + 0.004, robot.q_min, robot.q_max)[led])
    assert np.allclose(out[~led], np.clip(j, robot.q_min, robot.q_max)[~led])


def test_a_negative_lead_is_refused() -> None:
    for name in ("ref_lead", "goal_lead", "goal_lead_stance"):
        with pytest.raises(ConfigurationError, match=name):
            Gains(**{name: -0.01}).check()


def test_ff_sagittal_scales_the_feed_forward_on_the_legs_pitch_joints(robot) -> None:
    """``sagittal_scale``: the factor on the hip pitch, knee and ankle pitch of each leg (by
    role), 1 elsewhere; the compensated goals move those joints' feed-forward by it and leave
    the others' as they were."""
    from wbc.balance.compliance import CompensatedSource, ComplianceCompensator
    from wbc.balance.live import sagittal_scale
    from wbc.recording import SUPPORT_DOUBLE
    from wbc.servos.sources import CallableSource

    scale = sagittal_scale(robot, 2.0)
    pitch = [robot.joint_index(robot.roles.get(s, r)) for s in ("left", "right")
             for r in ("hip_pitch", "knee", "ankle_pitch")]  # fmt: skip
    assert sorted(np.flatnonzero(scale != 1.0).tolist()) == sorted(pitch)
    assert np.all(scale[pitch] == 2.0)
    j = robot.configuration("stand")[7:]
    goals = []
    for s in (None, scale):
        comp = ComplianceCompensator(robot, gain=0.5)
        comp.scale = s
        source = CompensatedSource(CallableSource(lambda _k, _t: j, j, robot.joint_names),
                                   comp, lambda _t: SUPPORT_DOUBLE)  # fmt: skip
        goals.append(source(0, 0.0) - j)
    plain, scaled = goals
    assert np.any(np.abs(plain[pitch]) > 1e-4)  # (the stand loads them)
    others = np.setdiff1d(np.arange(robot.n_joints), pitch)
    assert np.allclose(scaled[others], plain[others])
    inside = (np.abs(j + scaled - robot.q_min) > 1e-9) & (np.abs(j + scaled - robot.q_max) > 1e-9)
    keep = np.intersect1d(pitch, np.flatnonzero(inside))
    assert np.allclose(scaled[keep], 2.0 * plain[keep])


def test_ff_inertial_takes_the_torques_under_the_gravito_inertial_field(robot) -> None:
    """``torques(.., accel)``: the static torques under ``g − accel`` (0: gravity's, exactly;
    a forward acceleration loads the stance ankle's pitch like a backward tilt of gravity),
    the model's gravity left as it was; the compensated goals take ``accel(t)``."""
    from wbc.balance.compliance import CompensatedSource, ComplianceCompensator
    from wbc.recording import SUPPORT_LEFT
    from wbc.servos.sources import CallableSource

    comp = ComplianceCompensator(robot, gain=1.0)
    j = robot.configuration("stand")[7:]
    static = comp.torques(j, SUPPORT_LEFT)
    assert np.array_equal(comp.torques(j, SUPPORT_LEFT, np.zeros(3)), static)
    a = np.array([0.5, 0.0, 0.0])
    moved = comp.torques(j, SUPPORT_LEFT, a)
    assert np.array_equal(robot.model.gravity.linear, [0.0, 0.0, -9.81])
    m = robot.model
    kept = m.gravity.linear.copy()
    m.gravity.linear = np.zeros(3)  # the field −a alone: the torques are linear in the field
    try:
        alone = comp.torques(j, SUPPORT_LEFT, a)
    finally:
        m.gravity.linear = kept
    assert np.any(np.abs(moved - static) > 1e-3)
    assert np.allclose(moved - static, alone, atol=1e-9)
    source = CompensatedSource(CallableSource(lambda _k, _t: j, j, robot.joint_names), comp,
                               lambda _t: SUPPORT_LEFT)  # fmt: skip
    plain = source(0, 0.0)
    source.accel = lambda _t: a
    assert not np.allclose(source(1, 0.01), plain)


def test_ff_inertial_torques_are_the_static_torques_under_g_minus_accel(robot, op3) -> None:
    """``torques(.., accel)`` (computed with the model's gravity untouched) equals the static
    torques of a model whose gravity is ``g − accel``, to 1e-12 N·m: random joints (the base
    tilted on its sole), each support, accelerations of a few m/s² in every direction."""
    from wbc.balance.compliance import ComplianceCompensator
    from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT

    rng = np.random.default_rng(7)
    for r in (robot, op3):
        comp = ComplianceCompensator(r, gain=1.0)
        m = r.model
        kept = m.gravity.linear.copy()
        for _ in range(4):
            j = np.clip(r.configuration("stand")[7:] + rng.uniform(-0.3, 0.3, r.n_joints),
                        r.q_min, r.q_max)  # fmt: skip
            a = rng.normal(0.0, 3.0, 3)
            for support in (SUPPORT_LEFT, SUPPORT_RIGHT, SUPPORT_DOUBLE):
                got = comp.torques(j, support, a)
                assert np.array_equal(m.gravity.linear, kept)
                m.gravity.linear = kept - a  # (the definition: the field g − accel)
                try:
                    field = comp.torques(j, support)
                finally:
                    m.gravity.linear = kept
                assert np.abs(got - field).max() < 1e-12, (r.name, support)
                assert np.abs(got - comp.torques(j, support)).max() > 1e-3  # (a load)
