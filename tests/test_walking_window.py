"""The whole-body balance window (wbc.walking.window) and the references that use it."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wbc.bench import trajectories as traj
from wbc.exceptions import ConfigurationError, TrajectoryError
from wbc.walking import check_reference, forward_walk
from wbc.walking.checks import lateral_offsets
from wbc.walking.feasibility import kinematic_feasibility
from wbc.walking.window import BalanceWindow


@pytest.fixture(scope="module")
def named(robot):
    """The named trajectories, each built once for this module (a build measures a window)."""
    cache: dict = {}

    def get(name):
        if name not in cache:
            cache[name] = traj.build(name, robot)
        return cache[name]

    return get


def test_whole_body_window_is_wider_than_the_legs_alone(robot, window, start):
    legs = start.legs
    half = 0.5 * float(start.left.y - start.right.y)
    legs_only = legs.max_com_lateral(float(start.com[2]), half)
    assert 0.009 < legs_only < 0.013  # the legs-only model: ~11 mm
    # upright, arms free: more than the legs-only model, less than the sole's inner edge + 15 mm
    assert legs_only < window.upright < 0.035
    # a 15 deg lean carries the CoM past the sole's centre (41.4 mm out)
    assert window.max_lateral > window.half_width + 0.005
    held = BalanceWindow.from_robot(robot, samples=2, hold_arms=True)
    assert held.upright < window.upright  # the arms help
    assert held.max_lateral < window.max_lateral + 1e-4


def test_window_grows_with_the_allowed_lean(robot, window):
    small = BalanceWindow.from_robot(robot, max_lean=np.deg2rad(5.0), samples=2)
    assert window.upright - 1e-4 < small.max_lateral < window.max_lateral
    assert small.upright == pytest.approx(window.upright, abs=1e-6)


def test_roll_table_leans_toward_the_stance_and_is_odd(window):
    assert window.rolls[0] == pytest.approx(0.0, abs=0.01)
    assert np.all(np.diff(window.offsets) >= 0)
    assert np.all(np.diff(window.rolls) <= 1e-9)  # CoM to the left: lean left (negative roll)
    assert abs(window.rolls[-1]) <= window.max_lean + 1e-3
    y = np.array([0.01, 0.03, -0.03])
    r = window.roll_for(y)
    assert r[1] == pytest.approx(-r[2])
    assert r[1] < r[0] <= 0.0


def test_bad_window_input_is_one_clear_error(robot):
    with pytest.raises(TrajectoryError, match="max_lean"):
        BalanceWindow.from_robot(robot, max_lean=-0.1)
    with pytest.raises(TrajectoryError, match="samples"):
        BalanceWindow.from_robot(robot, samples=1)


def test_whole_body_walk_is_feasible_with_the_planned_lean(robot, window, start):
    ref = forward_walk(start, 4, zmp_offset=(0.0, 0.018), margin=0.01, window=window)
    assert ref.zmp_margin().min() >= 0.01 - 1e-9
    assert ref.torso_roll is not None and np.abs(ref.torso_roll).max() > np.deg2rad(1.0)
    # the roll leans over the stance side: sign opposite to the CoM's lateral offset
    y = lateral_offsets(ref)
    big = np.abs(y) > window.upright
    assert np.all(np.sign(ref.torso_roll[big]) == -np.sign(y[big]))
    # the legs-only model rejects the same CoM path (hip roll beyond its limit)
    with pytest.raises(TrajectoryError, match="hip would roll"):
        check_reference(ref, legs=start.legs)
    rep = kinematic_feasibility(robot, ref, hold_arms=False)
    assert rep.feasible, rep
    assert rep.min_limit_margin >= -1e-9
    # the torso the IK holds is the planned lean
    torso = ref.torso_rotations()
    assert np.allclose(torso[:, 2, 1], np.sin(ref.torso_roll))


def test_window_check_rejects_a_com_beyond_it(window, start):
    import dataclasses

    ref = forward_walk(start, 2, zmp_offset=(0.0, 0.018), margin=0.01, window=window)
    y = np.abs(lateral_offsets(ref)).max()
    narrow = dataclasses.replace(window, max_lateral=0.5 * y)
    with pytest.raises(TrajectoryError, match="balance window of"):
        check_reference(ref, window=narrow, legs=start.legs)
    assert check_reference(ref, window=window, legs=start.legs).window_margin > 0


def test_session_asks_the_torso_for_the_planned_roll(robot, window, start):
    from wbc.geometry import heading_free
    from wbc.walking.loop import Controller, Session

    class Hold(Controller):
        def track(self, q, targets, dt, phase_changed):
            return q

    ref = forward_walk(start, 2, zmp_offset=(0.0, 0.018), margin=0.01, window=window)
    session = Session(Hold(), robot, ref)
    i = int(np.argmax(np.abs(ref.torso_roll)))
    R = session.targets(i).torso_rotation
    lean = heading_free(robot.frame_placement(session.q, "torso").rotation)
    expect = pin.rpy.rpyToMatrix(float(ref.torso_roll[i]), 0.0, float(ref.torso_yaw[i])) @ lean
    np.testing.assert_allclose(R, expect, atol=1e-12)


@pytest.mark.parametrize("name", ["walk10_wb", "fast_wb", "turn_wb", "lateral_wb"])
def test_named_whole_body_walks_keep_the_zmp_10mm_inside(named, name):
    ref = named(name)
    assert ref.zmp_margin().min() >= 0.010 - 1e-9
    assert ref.meta["check"]["window_margin"] > 0


def test_walk10_wb_keeps_walk10s_timing_with_shorter_lower_steps(named, robot):
    """walk10_wb: walk10's timing and footstep plan (the package's: its steps, a 12 mm apex;
    walk10's 20 mm asks the knee for 1.6x the servo speed and the lagging swing landed 6-9 mm
    beyond each footstep: benchmarks/balance.md); the Bioloid's robot.toml shortens the steps
    to 25 mm and the apex to 8 mm (35/12 mm asked 1.23x the servo speed: benchmarks/robots.md)."""
    wb, plain = named("walk10_wb"), named("walk10")
    stated = robot.robot_data.walking["walk10_wb"]
    assert stated["step_length"] == 0.025 and stated["swing"]["apex"] == 0.008
    assert wb.duration == pytest.approx(plain.duration)
    assert len(wb.footsteps) == len(plain.footsteps)
    ratio = stated["step_length"] / 0.035  # walk10's 35 mm
    for a, b in zip(wb.footsteps, plain.footsteps, strict=True):
        assert a.side == b.side
        assert a.y == pytest.approx(b.y, abs=1e-4)  # the same plan, within 0.1 mm
        assert a.x == pytest.approx(b.x * ratio, abs=1e-4)

    def lift(ref):  # the highest swing, above the sole's start
        return max((s[:, 2] - s[0, 2]).max() for s in (ref.l_sole, ref.r_sole))

    assert lift(wb) == pytest.approx(stated["swing"]["apex"], abs=1e-9)
    assert lift(plain) == pytest.approx(0.020, abs=1e-9)


def test_fast_walk_is_faster_than_6cm_per_s(named):
    ref = named("fast_wb")
    start = 0.5 * (ref.l_sole[0, :2] + ref.r_sole[0, :2])
    end = 0.5 * (ref.l_sole[-1, :2] + ref.r_sole[-1, :2])
    assert np.linalg.norm(end - start) / ref.duration >= 0.06


def test_bad_max_lean_in_robot_data_names_the_key(robot, monkeypatch):
    data = robot.robot_data
    monkeypatch.setitem(data.walking, "walk10_wb", {"max_lean": "much"})
    with pytest.raises(ConfigurationError, match=r"\[walking.walk10_wb\] max_lean"):
        traj.build("walk10_wb", robot)


@pytest.mark.parametrize("name", ["fast_wb", "turn_wb", "lateral_wb", "static_walk"])
def test_new_walks_ask_a_realistic_share_of_the_servo_speed(robot, named, name):
    from wbc.walking.feasibility import PLANNING_SPEED_FRACTION

    ref = named(name)
    rep = kinematic_feasibility(robot, ref, hold_arms=False, iterations=4)
    assert rep.feasible, rep
    assert rep.max_joint_speed <= PLANNING_SPEED_FRACTION * float(np.min(robot.v_max)), rep


def test_walk10_asks_more_than_the_servo_can(robot):
    """Why the new walks are slower per step: walk10's swing knee exceeds no-load speed."""
    rep = kinematic_feasibility(robot, traj.build("walk10", robot), hold_arms=False, iterations=4)
    assert rep.max_joint_speed > float(np.min(robot.v_max))
    assert rep.speed_joint.endswith("knee")


def test_an_upright_reference_asks_the_torso_exactly_as_before(start):
    """No planned roll: the torso targets equal the heading-only ones (kinematic benchmark
    of the existing trajectories unchanged)."""
    from wbc.walking.loop import torso_target

    ref = forward_walk(start, 2)
    lean = pin.rpy.rpyToMatrix(0.01, -0.02, 0.0)
    got = ref.torso_rotations(lean)
    for i in range(0, ref.n, 7):
        np.testing.assert_allclose(got[i], torso_target(float(ref.torso_yaw[i]), lean), atol=1e-15)


@settings(
    max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.floats(-0.08, 0.08), st.floats(-0.08, 0.08))
def test_roll_is_odd_and_grows_with_the_offset(window, a, b):
    """Law: the lean mirrors with the CoM and never shrinks as the CoM goes further out."""
    ra, rb, rma = window.roll_for(np.array([a, b, -a]))
    assert rma == pytest.approx(-ra, abs=1e-12)
    if abs(a) <= abs(b):
        assert abs(ra) <= abs(rb) + 1e-12
    assert abs(ra) <= window.max_lean + 1e-3


def test_the_reach_over_the_front_sole_of_a_step_is_less(robot, window):
    """lateral_reach: the standing stance with the arms held reaches less than the window
    (arms free); the CoM over the front sole of a step less still, over the back one about
    the same; the window's bound holds the torso's pitch and heading (below its roll table's
    lean solve, which may pitch and turn the torso)."""
    from wbc.walking.window import lateral_reach

    stand = lateral_reach(robot)
    assert 0.03 < stand < window.max_lateral
    front = lateral_reach(robot, stagger=0.03, forward=0.015)
    back = lateral_reach(robot, stagger=-0.03, forward=-0.015)
    assert front < stand - 0.002
    assert back < stand - 0.002
    assert window.max_lateral <= window.offsets[-1] + 1e-9
    with pytest.raises(TrajectoryError, match="stagger and forward must be finite"):
        lateral_reach(robot, stagger=float("nan"))
    with pytest.raises(TrajectoryError, match="max_lean"):
        lateral_reach(robot, max_lean=1.0)


def test_a_wider_stance_reads_the_lean_at_the_windows_stance(named):
    """lean_from_window's ``from_stance``: where a lateral walk's soles are wider apart than
    the window's stance, that share of the extra half-width comes off the CoM's offset: at 1
    the lean is the one for the CoM's distance to the nearer sole (a CoM within the extra
    half-width of the midpoint stands upright), at 0 the midpoint's as before; the default
    (LEAN_FROM_STANCE) between, the lean smaller and its reversal across a wide double
    support slower than at 0. Walks at the window's stance (within STANCE_TOLERANCE) are
    bit for bit as before; narrow_sway plans the roll again with the reference's share."""
    import dataclasses

    from wbc.walking.checks import sole_half_widths
    from wbc.walking.gait import (
        LEAN_FROM_STANCE,
        STANCE_TOLERANCE,
        lean_from_window,
        narrow_sway,
    )

    def rate(ref):  # deg/s, the lean's fastest change
        return float(np.abs(np.gradient(np.rad2deg(ref.torso_roll), ref.t)).max())

    def lean(ref, window, share):
        out = dataclasses.replace(ref, meta=dict(ref.meta))
        lean_from_window(out, window, share)
        return out

    lat = named("lateral_wb")
    window = BalanceWindow.from_dict(lat.meta["window"])
    assert 0.0 < LEAN_FROM_STANCE <= 1.0
    assert lat.meta["window"]["lean_from_stance"] == LEAN_FROM_STANCE
    old, full = lean(lat, window, 0.0), lean(lat, window, 1.0)
    extra = sole_half_widths(lat) - window.half_width - STANCE_TOLERANCE  # at share 1
    wide = extra > 0.005
    assert wide.any() and not wide.all()
    for a, b in ((old, lat), (lat, full)):  # the lean shrinks with the share, same side
        assert np.all(np.abs(b.torso_roll) <= np.abs(a.torso_roll) + 1e-12)
        assert np.all(np.sign(a.torso_roll) * np.sign(b.torso_roll) >= 0)
        assert np.max(np.abs(a.torso_roll - b.torso_roll)[wide]) > np.deg2rad(0.5)
    at_stance = extra <= 0
    np.testing.assert_array_equal(full.torso_roll[at_stance], old.torso_roll[at_stance])
    upright = wide & (np.abs(lateral_offsets(lat)) < extra)
    assert upright.any() and np.all(full.torso_roll[upright] == 0.0)
    assert rate(full) < 40.0 < 50.0 < rate(old)  # 36 against 53 deg/s on the Bioloid
    assert rate(lat) < rate(old) - 5.0
    # the re-planned sway leans with the reference's share
    for ref in (lat, old, full):
        out = narrow_sway(ref, 0.5)
        assert out is not ref
        again = lean(out, window, ref.meta["window"]["lean_from_stance"])
        np.testing.assert_array_equal(out.torso_roll, again.torso_roll)
    # a walk at the window's stance: the same lean at any share
    walk = named("walk10_wb")
    own = BalanceWindow.from_dict(walk.meta["window"])
    for share in (0.0, 1.0):
        np.testing.assert_array_equal(walk.torso_roll, lean(walk, own, share).torso_roll)
    with pytest.raises(TrajectoryError, match="from_stance"):
        lean_from_window(lean(lat, window, 0.0), window, 1.5)
