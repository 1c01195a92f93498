"""The loaded joints' sag integrated into their goals (``Gains.j_i``, issue 30): it grows
on the loaded leg toward the encoders' sag, bounded and leaking, lets go on a swinging leg,
holds on unread joints, keeps every goal's change within the speed limits; off (the
default), the stabilizer adds nothing."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.balance.joint_integral import JointIntegral
from wbc.balance.stabilizer import Gains, Stabilizer
from wbc.model import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def _knee(robot, side: str) -> int:
    return robot.joint_names.index(robot.roles.joint(side, "knee"))


def test_the_stance_legs_sag_is_integrated_bounded_and_let_go_when_it_swings(robot):
    ji = JointIntegral(robot)
    q = robot.configuration("stand")[7:]
    k, other = _knee(robot, "left"), _knee(robot, "right")
    present = q.copy()
    present[k] -= 0.02  # (the left knee sags 0.02 rad behind its solved goal)
    present[other] -= 0.02  # (so does the right one, swinging: not integrated)
    v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 0.0, 0.01)
    assert v[k] == pytest.approx(2.0 * 0.01 * 0.02)  # (rate · dt · sag)
    assert v[other] == 0.0 and np.count_nonzero(v) == 1
    for _ in range(199):  # (2 s: rate · sag · t = 0.08, no leak)
        v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 0.0, 0.01)
    assert v[k] == pytest.approx(0.08, abs=1e-9)
    for _ in range(200):
        v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 0.0, 0.01)
    assert v[k] == pytest.approx(0.1)  # (j_i_max)
    for _ in range(2000):  # with the leak: rate · sag / leak = 0.04 rad
        v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 1.0, 0.01)
    assert v[k] == pytest.approx(0.04, abs=1e-6)
    w = ji.offsets(q, present, "r_sole", 2.0, 0.1, 1.0, 0.01)  # the left leg swings
    step = 0.5 * robot.v_max[k] * 0.01
    assert w[k] == pytest.approx(max(0.04 - step, 0.0))  # let go, within the speed
    for _ in range(10):
        w = ji.offsets(q, present, "r_sole", 2.0, 0.1, 1.0, 0.01)
    assert w[k] == 0.0


def test_unread_joints_hold_and_goals_stay_within_the_speed_limits(robot):
    ji = JointIntegral(robot)
    q = robot.configuration("stand")[7:]
    k = _knee(robot, "left")
    present = q - 0.05
    for _ in range(50):
        v = ji.offsets(q, present, "", 50.0, 0.3, 0.0, 0.01)  # (double support: both legs)
    held = v.copy()
    unread = np.full_like(present, np.nan)
    v = ji.offsets(q, unread, "", 50.0, 0.3, 0.0, 0.01)
    np.testing.assert_array_equal(v, held)
    # a fast integral on goals that already move at 0.9 of the speed limit: each goal's
    # change (solved + offset) stays ≤ v_max · dt
    ji2 = JointIntegral(robot)
    last = q.copy()
    for t in range(30):
        solved = q + 0.9 * robot.v_max * 0.01 * t
        v = ji2.offsets(solved, solved - 0.05, "", 500.0, 0.3, 0.0, 0.01)
        assert np.all(np.abs(solved + v - last) <= robot.v_max * 0.01 * (1 + 1e-9))
        last = solved + v
    assert v[k] > 0.05  # (it still grew)


def test_the_stabilizer_adds_the_integral_only_with_j_i(robot):
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    sag = q[7:] - 0.03
    for g, on in ((Gains(hip_kick=0.0), False), (Gains(hip_kick=0.0, j_i=2.0), True)):
        stab = Stabilizer(robot, 0.2, lambda: sag.copy(), None, g)
        stab.last = object()  # (a walk under way: an estimate exists)
        d = stab.joint_offsets(q[7:].copy())
        assert bool(d is not None and np.count_nonzero(d) > 0) is on


def test_a_joint_whose_goal_moves_faster_than_still_holds_its_integral(robot):
    """``j_i_still`` 0.5 rad/s: the left knee's solved goal moving at 1 rad/s (its error
    then the servo's lag) holds its integral; at 0.2 rad/s it integrates; without the
    gate (0) it integrates both."""
    q = robot.configuration("stand")[7:]
    k = _knee(robot, "left")
    for speed, still, grows in ((1.0, 0.5, False), (0.2, 0.5, True), (1.0, 0.0, True)):
        ji = JointIntegral(robot)
        for t in range(20):
            solved = q.copy()
            solved[k] += speed * 0.01 * t
            v = ji.offsets(solved, solved - 0.02, "l_sole", 2.0, 0.1, 0.0, 0.01, still)
        assert bool(v[k] > 0.005) is grows  # (20 ticks: 0.008; the first tick has no last goal)


def test_the_servos_lag_is_not_integrated_with_a_delay_but_their_sag_is(robot):
    """``j_i_lag``: the left knee's solved goal ramps at 0.5 rad/s and its encoder follows
    it 50 ms late (a late servo, no sag): compared with the goals of 50 ms ago nothing is
    integrated, with this tick's (delay 0) the lag is; with a 0.02 rad sag on top the
    delayed form integrates the sag alone (rate · dt · sag a tick); a delay between ticks
    is interpolated; a delay longer than the ticks stored so far reads the oldest."""
    q = robot.configuration("stand")[7:]
    k = _knee(robot, "left")
    dt = 0.01
    for delay, sag, want in ((0.05, 0.0, 0.0), (0.0, 0.0, None), (0.05, 0.02, 1.0 * dt * 0.02),
                             (0.045, 0.0, None)):  # fmt: skip
        ji = JointIntegral(robot)
        for t in range(60):
            solved = q.copy()
            solved[k] += 0.5 * dt * t
            present = q.copy()
            present[k] += 0.5 * max(dt * t - 0.05, 0.0) - sag
            before = ji.value[k]
            v = ji.offsets(solved, present, "l_sole", 1.0, 0.1, 0.0, dt, 0.0, delay)
        if want is None:  # (a lag integrated: 0.025 rad a second at delay 0)
            assert v[k] > 0.0 and (delay > 0 or v[k] > 0.01)
        else:
            assert v[k] - before == pytest.approx(want, abs=1e-12)
    ji = JointIntegral(robot)
    solved = q.copy()
    solved[k] += 0.1  # (the first tick: the oldest stored is this one; no lag yet)
    v = ji.offsets(solved, solved.copy(), "l_sole", 1.0, 0.1, 0.0, dt, 0.0, 0.15)
    assert v[k] == 0.0


def test_the_band_leaves_a_small_error_and_a_ringing_alone_and_integrates_a_sag(robot):
    """``j_i_band`` 0.03 rad: a steady 0.02 rad error (a stiff servo's) integrates nothing;
    an 8 Hz ±0.1 rad ringing about the goal (low-passed 0.1 s: ±0.02) all but nothing; a steady
    0.1 rad sag integrates what lies beyond the band (rate · dt · 0.07 a tick, once the
    low-pass has settled); without the band (0) the ringing is integrated a tick at a time."""
    q = robot.configuration("stand")[7:]
    k = _knee(robot, "left")
    dt = 0.01

    def run(err, band: float) -> tuple[float, float]:
        ji = JointIntegral(robot)
        before = v = 0.0
        for t in range(200):
            present = q.copy()
            present[k] -= err(t * dt)
            before = ji.value[k]
            v = ji.offsets(q, present, "l_sole", 1.0, 0.5, 0.0, dt, 0.0, 0.0, False, band)[k]
        return v, v - before

    assert run(lambda t: 0.02, 0.03) == (0.0, 0.0)
    ring = lambda t: 0.1 * np.sin(2 * np.pi * 8.0 * t)  # noqa: E731
    assert abs(run(ring, 0.03)[0]) < 1e-5  # (the low-pass's first cycle: 2e-6 rad)
    assert run(ring, 0.0)[1] != 0.0
    total, last = run(lambda t: 0.1, 0.03)
    assert last == pytest.approx(dt * 0.07, rel=1e-6) and total > 0.1


def test_sagittal_integrates_the_pitch_joints_only(robot):
    """``j_i_sagittal``: every joint of the loaded left leg sags 0.02 rad; the hip pitch, knee
    and ankle pitch integrate, its hip yaw, hip roll and ankle roll do not (all six do
    without it)."""
    q = robot.configuration("stand")[7:]
    leg = {r: robot.joint_names.index(robot.roles.joint("left", r)) for r in
           ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")}  # fmt: skip
    present = q - 0.02
    for sagittal in (True, False):
        v = JointIntegral(robot).offsets(q, present, "l_sole", 1.0, 0.1, 0.0, 0.01,
                                         0.0, 0.0, sagittal)  # fmt: skip
        on = {r for r, j in leg.items() if v[j] > 0}
        assert on == ({"hip_pitch", "knee", "ankle_pitch"} if sagittal else set(leg))


def test_joints_selects_the_integrating_set(robot):
    """``j_i_joints``: every joint of both loaded legs (double support) sags 0.02 rad; each
    set integrates its roles on both legs and nothing else (the others, the arms, hold 0)."""
    q = robot.configuration("stand")[7:]
    present = q - 0.02
    expect = (
        {"hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll"},
        {"hip_pitch", "knee", "ankle_pitch", "ankle_roll"},
        {"knee", "ankle_pitch"},
        {"knee"},
    )
    for code, roles in enumerate(expect):
        v = JointIntegral(robot).offsets(q, present, "", 1.0, 0.1, 0.0, 0.01,
                                         joints=code)  # fmt: skip
        on = {robot.joint_names[j] for j in np.flatnonzero(v > 0)}
        assert on == {robot.roles.joint(s, r) for s in ("left", "right") for r in roles}
    with pytest.raises(Exception, match="j_i_joints"):
        Gains(j_i_joints=4).check()


def test_single_grows_in_single_support_and_holds_or_leaks_in_double_support(robot):
    """``j_i_single``: the knees' integral grows in single support; in double support it
    grows without the gate (0), holds with 1 and leaks (without growing) with 2."""
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    sag = q[7:] - 0.03
    k = _knee(robot, "left")
    for single in (0.0, 1.0, 2.0):
        g = Gains(hip_kick=0.0, j_i=2.0, j_i_leak=2.0, j_i_joints=3, j_i_single=single)
        stab = Stabilizer(robot, 0.2, lambda: sag.copy(), None, g)
        stab.last = object()  # (a walk under way: an estimate exists)
        stab._stance = "l_sole"
        for _ in range(20):
            grown = stab.joint_offsets(q[7:].copy())[k]
        assert grown > 0.005
        stab._stance = ""
        for _ in range(10):
            after = stab.joint_offsets(q[7:].copy())[k]
        if single == 0:
            assert after > grown
        elif single == 1:
            assert after == pytest.approx(grown)
        else:
            assert 0 < after < grown


def test_j_i_stiff_integrates_only_on_servos_identified_softer(robot):
    """``j_i_stiff`` 1: no integral while the stiffness is not identified, none on servos
    identified at 1.2 × servos.toml's, the integral on servos identified at 0.6 ×; without
    the gate (0) it integrates unidentified."""
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    sag = q[7:] - 0.03
    for stiff, scale, on in ((1.0, None, False), (1.0, 1.2, False), (1.0, 0.6, True),
                             (0.0, None, True)):  # fmt: skip
        g = Gains(hip_kick=0.0, j_i=2.0, j_i_stiff=stiff)
        stab = Stabilizer(robot, 0.2, lambda: sag.copy(), None, g)
        stab.stiffness_scale = scale
        stab.last = object()  # (a walk under way: an estimate exists)
        d = stab.joint_offsets(q[7:].copy())
        assert bool(d is not None and np.count_nonzero(d) > 0) is on
        assert stab.sag_integrated is on


@pytest.mark.parametrize("stiffness", [0.55, 1.8])
def test_closed_loop_identifies_the_stiffness_at_rest_for_j_i_stiff(soft_plant_loop, stiffness):
    """Through :func:`wbc.balance.live.closed_loop` on the simulated robot: with
    ``j_i_stiff`` 1.2 the rest identifies the servos' stiffness from the encoders' sag (a
    plant ``stiffness`` × servos.toml's: identified on its side of 1.2), the stabilizer
    gets it, the integral runs on the soft plant only and says so; the feed-forward's model
    stays servos.toml's (no ``servo='identify'``)."""
    said: list[str] = []
    g = Gains(j_i=1.0, j_i_max=0.05, j_i_joints=3, j_i_stiff=1.2)
    loop = soft_plant_loop(stiffness, g, said)
    assert loop.stabilizer.stiffness_scale is None
    loop.deployment.run()
    k = loop.stabilizer.stiffness_scale
    assert k is not None and loop.stiffness_scale == k and (k < 1.2) is (stiffness < 1.0)
    assert loop.stabilizer.sag_integrated is (stiffness < 1.0)
    assert any(f"joint integral {'on' if stiffness < 1.0 else 'off'}" in s for s in said)
    assert loop.servo_model == "servos.toml (nominal)"
