"""The walk engine on velocity commands: its walks pass the walks' own checks, its steps the
footstep validation, commands take effect within a step, the velocity limits hold."""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc import load_robot
from wbc.exceptions import ConfigurationError
from wbc.geometry import mean_angle, polygon_distance, wrap_angle
from wbc.types import SUPPORT_LEFT, SUPPORT_RIGHT
from wbc.walking import Foot, FootstepPlan, GaitTiming, LegGeometry, StandingState, SwingParams
from wbc.walking.checks import check_reference
from wbc.walking.engine import (
    EngineParams,
    VelocityLimits,
    WalkEngine,
    rollout,
)
from wbc.walking.footgaps import rectangle_gaps
from wbc.walking.footsteps import Footstep

#: the legs-only gait (upright torso; walk10's timing and ZMP path): no balance window to
#: measure, so the tests stay fast
LEGS_ONLY = EngineParams(
    timing=GaitTiming(), swing=SwingParams(apex=0.015), zmp_offset=(0.0, 0.0285), transfer=1.0
)
LIMITS = VelocityLimits(0.08, 0.06, 0.03, 0.5)


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("bioloid")
    start = StandingState.from_robot(robot, robot.configuration("stand"))
    return robot, start, Foot(*robot.foot_size), LegGeometry.from_robot(robot)


def engine(setup, params=LEGS_ONLY, limits=LIMITS) -> WalkEngine:
    _, start, foot, legs = setup
    return WalkEngine(start, params, limits, foot, legs)


COMMANDS = [(1.6, 0.07, 0.0, 0.0), (1.2, 0.0, 0.025, 0.0), (1.2, 0.02, 0.0, -0.4),
            (1.6, -0.05, -0.02, 0.2), (0.8, 0.0, 0.0, 0.0)]  # fmt: skip


def test_a_driven_walk_passes_the_walks_checks(setup) -> None:
    """The targets of a mixed command sequence, as a reference, pass check_reference: the
    ZMP of the CoM inside the support polygon, soles above the ground and apart, legs within
    reach and hip roll; the walk ends standing, the CoM between the feet."""
    _, _, _, legs = setup
    e = engine(setup)
    ref = rollout(e, COMMANDS)
    report = check_reference(ref, margin=0.0005, legs=legs)
    assert report.zmp_margin >= 0.0005
    assert e.state == "standing" and e.steps_taken >= 10
    mid = 0.5 * (ref.l_sole[-1, :2] + ref.r_sole[-1, :2])
    assert np.linalg.norm(ref.com[-1, :2] - mid) < 1e-3
    # the plain closing step (close_on_target off) lands beside the stance sole
    plain = engine(setup, replace(LEGS_ONLY, close_on_target=False))
    ref = rollout(plain, COMMANDS)
    assert check_reference(ref, margin=0.0005, legs=legs).zmp_margin >= 0.0005
    width = np.linalg.norm(ref.l_sole[-1, :2] - ref.r_sole[-1, :2])
    assert width == pytest.approx(2 * plain.half_width, abs=1e-6)


@pytest.mark.parametrize("command", [(1.3, 0.05, 0.0, 0.0), (1.45, 0.03, 0.0, 0.25),
                                     (2.1, 0.0, 0.0, 0.4), (1.1, -0.03, -0.01, 0.0),
                                     (1.3, 0.02, 0.0, -0.2)])  # fmt: skip
def test_a_stop_closes_on_the_commanded_pose(setup, command) -> None:
    """A stop's closing step lands where the commanded pose at the stop puts the walking
    frame (``close_on_target``, the default): straight, within a millimetre of it; turning,
    within 2.5 mm and 1.2° (a turned sole is moved outward, never closer to the other than
    side by side); the plain closing step (beside the stance sole) ends off it by the step's
    latency and the frame's half stride (here 4–9 mm or 1.6–2.7°; the engine's own
    convention: short of it; with the Walker's odometry, the soles' midpoint, beyond it).
    The commanded pose stops at the stop instead of running on with the command."""
    _, start, foot, legs = setup
    ends, gaps = {}, {}
    for close in (True, False):
        e = engine(setup, replace(LEGS_ONLY, close_on_target=close))
        e.start()
        e.command(*command[1:])
        for _ in range(round(command[0] / e.dt)):
            e.tick()
        at_stop = e.pose_cmd.copy()
        e.stop()
        while e.walking:
            e.tick()
        left, right = e.feet["left"], e.feet["right"]
        mid = np.r_[0.5 * (left.xy + right.xy), mean_angle(left.yaw, right.yaw)]
        ends[close] = (float(np.linalg.norm(mid[:2] - at_stop[:2])),
                       abs(wrap_angle(mid[2] - at_stop[2])))  # fmt: skip
        gaps[close] = e._gap(left, right)
        if close:
            assert np.allclose(e.pose_cmd, at_stop)  # frozen at the stop
            FootstepPlan(start.left, start.right, tuple(e.planned)).validate(
                foot, legs, e.height, 0.005
            )
    turning = command[3] != 0.0
    assert ends[True][0] < (0.0025 if turning else 0.001)
    assert ends[True][1] < math.radians(1.2 if turning else 0.1)
    assert gaps[True] >= gaps[False] - 1e-3
    off = {k: v[0] + 0.1 * v[1] for k, v in ends.items()}  # (m; 1.75 mm a degree)
    assert off[True] < 0.8 * off[False]


def test_every_committed_step_passes_the_footstep_validation(setup) -> None:
    """No crossing, clearance along each swing (21 samples), relative yaw, reach."""
    _, start, foot, legs = setup
    e = engine(setup)
    rollout(e, COMMANDS)
    plan = FootstepPlan(start.left, start.right, tuple(e.planned))
    plan.validate(foot, legs, e.height, 0.005)


def test_a_new_command_takes_effect_within_one_step(setup) -> None:
    """Walking forward, a sideways command: the first step committed after it (at most one
    step time later) is planned from it: the walking frame moves sideways."""
    e = engine(setup)
    e.command(0.06, 0.0, 0.0)
    e.start()
    for _ in range(150):
        e.tick()
    n = len(e.planned)
    e.command(0.0, 0.02, 0.0)
    t0 = e.k
    while len(e.planned) == n:
        e.tick()
    waited = (e.k - t0) * e.dt
    assert waited <= LEGS_ONLY.timing.step_time + 1e-9
    new = e.planned[-1]
    prev = e.planned[-2]
    # the new step does not advance (vx = 0) and it moves the frame to the left
    assert new.relative_to(prev)[0] == pytest.approx(0.0, abs=1e-9) or new.x - prev.x < 0.01
    for _ in range(2 * round(LEGS_ONLY.timing.step_time / e.dt)):
        e.tick()
    left, right = e.feet["left"], e.feet["right"]
    assert 0.5 * (left.y + right.y) > 0.005


def test_the_walking_frame_follows_the_commanded_pose(setup) -> None:
    """Each step moves the walking frame to where the command (integrated since the start)
    puts the body at the step's landing: in steady walking on an arc, by the arc's chord
    per step; the start's latency is made up (the frame ends where the command puts it)."""
    e = engine(setup)
    vx, _, wz = e.command(0.03, 0.0, 0.15)
    assert (vx, wz) == (0.03, 0.15)  # inside the limits (room to make up the start's lag)
    e.start()
    frames, lags = [], []
    steps = 0
    while steps < 30:
        e.tick()
        if e.steps_taken != steps:  # a landing: the frame against the commanded pose now
            steps = e.steps_taken
            frames.append(e.centre.copy())
            lags.append(float(np.linalg.norm(e.centre[:2] - e.pose_cmd[:2])))
    T = LEGS_ONLY.timing.step_time
    chord = np.array([math.sin(wz * T), 1.0 - math.cos(wz * T)]) * vx / wz
    for a, b in itertools.pairwise(frames[20:]):
        R = np.array([[math.cos(a[2]), math.sin(a[2])], [-math.sin(a[2]), math.cos(a[2])]])
        assert np.allclose(R @ (b[:2] - a[:2]), chord, atol=1e-6)
        assert wrap_angle(b[2] - a[2]) == pytest.approx(wz * T, abs=1e-6)
    # the start's lag (the 0.8 s start phase) made up: at a landing the frame is where the
    # command has put the body by then (to a tick's motion)
    assert lags[0] > 0.01 and max(lags[20:]) < 2 * vx * e.dt


def test_measured_landings_are_made_up(setup) -> None:
    """Leg odometry: every step lands 30 % short of its plan (as told by ``on_landing``);
    the walk goes on from where the soles are (the targets hold them there) and the next
    steps still land where the command puts the body: no lag builds up."""
    e = engine(setup)
    told: dict[str, Footstep] = {}

    def short(step: Footstep) -> Footstep:
        other = e.feet["right" if step.side == "left" else "left"]
        sign = 1.0 if step.side == "left" else -1.0
        nominal = other.xy + np.array([0.0, sign * 2 * e.half_width])  # (heading 0 here)
        xy = nominal + 0.7 * (step.xy - nominal)
        told[step.side] = Footstep(step.side, float(xy[0]), float(xy[1]), step.yaw)
        return told[step.side]

    e.on_landing = short
    vx, _, _ = e.command(0.03, 0.0, 0.0)
    e.start()
    for _ in range(round(8.0 / e.dt)):
        e.tick()
    assert len(e.landing_errors) >= 15 and max(e.landing_errors) > 0.005
    for side, foot in told.items():  # held where they landed, not where planned
        held = e.contact[side]
        assert held == foot or held == e.feet[side]  # (or landed since: not measured yet)
    feet = 0.5 * (e.feet["left"].x + e.feet["right"].x)  # where the soles really are
    commanded = e.pose_cmd[0]
    assert commanded - feet < vx * LEGS_ONLY.timing.step_time * 2.5  # no growing lag
    assert feet > 0.7 * commanded + 0.03  # (not made up: the soles at 0.7 of the way)


def test_short_landings_are_caught_up(setup) -> None:
    """Leg odometry drives the make-up: every step lands 30 % short of its plan; where the
    body really is (the planned walking frame plus the landings' offsets,
    ``odometry_offset``) keeps up with the commanded pose — the steps lengthen within
    ``catch_up`` — instead of falling behind by 30 % of the way."""
    e = engine(setup)
    offset = np.zeros(2)  # the landings' offsets from their plans, summed

    def short(step: Footstep) -> Footstep:
        other = e.feet["right" if step.side == "left" else "left"]
        sign = 1.0 if step.side == "left" else -1.0
        nominal = other.xy + np.array([0.0, sign * 2 * e.half_width])  # (heading 0 here)
        xy = nominal + 0.7 * (step.xy - nominal)
        offset[:] += xy - step.xy
        return Footstep(step.side, float(xy[0]), float(xy[1]), step.yaw)

    e.on_landing = short
    vx, _, _ = e.command(0.03, 0.0, 0.0)
    e.start()
    for _ in range(round(10.0 / e.dt)):
        e.tick()
    assert e.odometry_offset == pytest.approx([*offset, 0.0])  # (x, y, heading: none here)
    real = 0.5 * (e.feet["left"].x + e.feet["right"].x) + offset[0]
    commanded = e.pose_cmd[0]
    assert offset[0] < -0.05  # the short landings add up
    assert commanded - real < vx * LEGS_ONLY.timing.step_time * 2.5  # caught up


def test_make_up_keeps_the_command_at_the_limit(setup) -> None:
    """At the forward limit, landings drifting sideways are made up only in the room the
    limits leave: every step still strides the full forward limit (the make-up never
    scales the command down)."""
    e = engine(setup)

    def drift(step: Footstep) -> Footstep:
        return Footstep(step.side, step.x, step.y - 0.004, step.yaw)  # 4 mm right each

    e.on_landing = drift
    vx, _, _ = e.command(LIMITS.vx_forward, 0.0, 0.0)
    e.start()
    for _ in range(round(6.0 / e.dt)):
        e.tick()
    steps = [s for s in e.planned if s.side == "left"]
    assert e.odometry_offset[1] < -0.02
    strides = np.diff([s.x for s in steps])[2:]
    assert np.allclose(strides, 2 * vx * LEGS_ONLY.timing.step_time, atol=1e-6)


def test_turning_through_the_half_turn(setup) -> None:
    """Headings wrap at ±π: a walk turning on the spot past 180° keeps its full steps (the
    swing's yaw is interpolated the short way round) and turns as commanded."""
    e = engine(setup)
    ref = rollout(e, [(9.0, 0.0, 0.0, 0.5)])
    assert e.shortened == 0
    turned = np.unwrap(ref.torso_yaw)[-1] - ref.torso_yaw[0]
    assert turned == pytest.approx(0.5 * LEGS_ONLY.timing.step_time * e.steps_taken, abs=0.3)
    assert turned > math.pi + 0.5


def test_commands_are_clipped_to_the_limits(setup) -> None:
    e = engine(setup)
    assert e.command(1.0, 0.0, 0.0) == pytest.approx((0.08, 0.0, 0.0))
    vx, vy, wz = e.command(-1.0, 1.0, 1.0)
    assert vx < 0 and vy > 0 and wz > 0
    assert abs(vx) / 0.06 + abs(vy) / 0.03 + abs(wz) / 0.5 == pytest.approx(1.0)
    with pytest.raises(ConfigurationError, match="three finite numbers"):
        e.command(float("nan"), 0.0, 0.0)
    with pytest.raises(ConfigurationError, match="velocity limit vy"):
        VelocityLimits(0.1, 0.1, -1.0, 0.1).check()


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-0.2, 0.2), st.floats(-0.1, 0.1), st.floats(-1.0, 1.0), st.floats(-0.06, 0.06),
    st.floats(-0.06, 0.06), st.floats(-0.8, 0.8),
)  # fmt: skip
def test_rectangle_gaps_equal_polygon_distance(x, y, yaw, ox, oy, oyaw) -> None:
    """The vectorised gaps are wbc.geometry.polygon_distance, separated or overlapping."""
    foot = Foot(0.101, 0.061)
    xy = np.array([[x, y], [0.5 * x, 0.5 * y]])
    yaws = np.array([yaw, 0.5 * yaw])
    got = rectangle_gaps(xy, yaws, np.array([ox, oy]), oyaw, foot)
    for i in range(2):
        want = polygon_distance(
            foot.rectangle(xy[i], yaws[i]), foot.rectangle(np.array([ox, oy]), oyaw)
        )
        assert got[i] == pytest.approx(want, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.floats(-0.06, 0.06), st.floats(-0.05, 0.08), st.floats(-0.7, 0.7),
       st.sampled_from(["left", "right"]))  # fmt: skip
def test_the_engines_step_check_agrees_with_validate(dx, dy, dyaw, side) -> None:
    """The engine's fast step check says what FootstepPlan.validate says (with the same
    swing samples)."""
    start, foot, legs = _bioloid()
    e = WalkEngine(start, LEGS_ONLY, LIMITS, foot, legs)
    stance = e.feet["right" if side == "left" else "left"]
    sign = 1.0 if side == "left" else -1.0
    xy = stance.xy + np.array([dx, sign * (2 * e.half_width + dy)])
    step = Footstep(side, float(xy[0]), float(xy[1]), stance.yaw + dyaw)
    plan = FootstepPlan(e.feet["left"], e.feet["right"], (step,))
    try:
        plan.validate(foot, legs, e.height, 0.005, swing_samples=LEGS_ONLY.swing_samples)
        ok = True
    except Exception:
        ok = False
    assert e._valid(dict(e.feet), step) == ok


@functools.cache
def _bioloid() -> tuple[StandingState, Foot, LegGeometry]:
    robot = load_robot("bioloid")
    start = StandingState.from_robot(robot, robot.configuration("stand"))
    return start, Foot(*robot.foot_size), LegGeometry.from_robot(robot)


def test_stop_from_standing_and_bad_params(setup) -> None:
    e = engine(setup)
    e.start()
    e.stop()
    for _ in range(5):
        assert e.tick().state == "standing"
    with pytest.raises(ConfigurationError, match="horizon_steps"):
        EngineParams(horizon_steps=0).check()
    with pytest.raises(ConfigurationError, match="transfer"):
        EngineParams(transfer=0.0).check()


def test_the_command_moves_the_origin(setup) -> None:
    """The commanded pose is the ``origin``'s (a Walker's: the base, ahead of the soles'
    midpoint): turning on the spot the walking frame circles the origin, which stays put,
    instead of the origin circling the soles' midpoint (2 |b| sin(θ/2) off: 3.6 cm at a
    half turn for the Bioloid's base). (The frame's sideways motion is a make-up: within
    ``catch_up`` and the room the limits leave, so at 0.6 of the turning limit here.)"""
    b = np.array([0.02, 0.0])
    moved = {}
    for origin in (b, np.zeros(2)):
        e = engine(setup)
        e.origin[:] = origin
        c0 = e.centre.copy()
        rollout(e, [(6.0, 0.0, 0.0, 0.3)])
        c = e.centre
        assert abs(wrap_angle(c[2] - c0[2])) > 1.7  # turned nearly 100°
        point = lambda f: f[:2] + np.array([[math.cos(f[2]), -math.sin(f[2])],  # noqa: E731
                                            [math.sin(f[2]), math.cos(f[2])]]) @ b  # fmt: skip
        moved[origin[0]] = float(np.linalg.norm(point(c) - point(c0)))
    assert moved[0.02] < 0.008  # the base stayed over its start (to the closing step)
    assert moved[0.0] > 0.025  # (it circled the soles' midpoint)


def test_a_heading_offset_turns_the_steps(setup) -> None:
    """The odometry's heading (``odometry_offset[2]``: the body 0.1 rad right of its plan,
    e.g. a stance sole turned on the floor, seen by a gyro) is made up like its position: walking
    straight on, the plan turns 0.1 rad left so that the body heads as commanded."""
    e = engine(setup)
    e.command(0.04, 0.0, 0.0)
    e.start()
    for _ in range(round(1.0 / e.dt)):
        e.tick()
    e.odometry_offset[2] = -0.1
    for _ in range(round(5.0 / e.dt)):
        e.tick()
    assert e.centre[2] == pytest.approx(0.1, abs=0.005)
    assert max(abs(s.yaw) for s in e.planned) < 0.101  # (no overshoot)
    yaws = [s.yaw for s in e.planned]
    assert np.max(np.diff(yaws)) < 0.025  # gently, within catch_up


def _swings(e: WalkEngine, commands) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per swing of a rollout: the swing sole's (x, y, yaw) per tick, its height per tick
    and where it landed (x, y, yaw)."""
    ref = rollout(e, commands)
    sup = ref.support
    out = []
    for code, pos, yaw in ((SUPPORT_RIGHT, ref.l_sole, ref.l_sole_yaw),
                           (SUPPORT_LEFT, ref.r_sole, ref.r_sole_yaw)):  # fmt: skip
        single = sup == code
        edges = np.flatnonzero(np.diff(single.astype(int)))
        for i0, i1 in zip(edges[::2] + 1, edges[1::2] + 1, strict=False):
            track = np.c_[pos[i0:i1, :2], yaw[i0:i1]]
            out.append((track, pos[i0:i1, 2] - pos[i1, 2], np.r_[pos[i1, :2], yaw[i1]]))
    return out


def test_a_settled_swing_comes_down_in_place(setup) -> None:
    """``settle``: over the swing's last share the sole only comes down — its horizontal
    place and heading are the landing's while it is still above the floor — and the swing
    is otherwise the same (the height as before, the landings where they were); without
    it (``settle=0``, the swing before) the sole is still moving over the floor there."""
    commands = [(1.6, 0.07, 0.0, 0.3), (1.2, 0.0, 0.025, -0.3)]
    plain = _swings(engine(setup, replace(LEGS_ONLY, settle=0.0)), commands)
    settled = _swings(engine(setup, replace(LEGS_ONLY, settle=0.25)), commands)
    assert len(plain) == len(settled) >= 6
    moved = 0.0
    for (a, za, land_a), (b, zb, land_b) in zip(plain, settled, strict=True):
        np.testing.assert_allclose(land_b, land_a, atol=1e-9)
        np.testing.assert_allclose(zb, za, atol=1e-12)
        n = len(b)
        last = slice(int(np.ceil(0.75 * n)) + 1, n)  # (s >= 0.75 after a tick's rounding)
        np.testing.assert_allclose(b[last], np.broadcast_to(land_b, b[last].shape), atol=1e-9)
        assert np.all(zb[last] > 0.0)  # still above the floor: it comes down in place
        moved = max(moved, float(np.abs(a[last] - land_a).max()))
    assert moved > 1e-3  # the plain swing is still moving there
    with pytest.raises(ConfigurationError, match="settle"):
        EngineParams(settle=1.0).check()


def test_a_stance_move_is_kept_clear_of_the_landing(setup) -> None:
    """:meth:`WalkEngine.clear_of_landing`: in single support, a stance sole's move straight
    toward the swing's planned landing stops where their rectangles are ``min_clearance``
    apart (the last of the sampled points before it); a move away is taken whole, and so is
    any move with nothing swinging."""
    e = engine(setup)
    e.command(0.0, 0.0, 0.5)
    e.start()
    while e.landing is None:
        e.tick()
    step = e.landing
    stance = e.feet["right" if step.side == "left" else "left"]
    start = stance.position
    gap0 = float(rectangle_gaps(start[None, :2], np.array([stance.yaw]), step.xy, step.yaw,
                                e.foot)[0])  # fmt: skip
    assert gap0 >= e.params.min_clearance
    toward = np.r_[step.xy - stance.xy, 0.0]
    toward *= 0.02 / np.linalg.norm(toward)  # 2 cm: well inside the landing's sole
    got = e.clear_of_landing(stance, start, start + toward)
    gap = float(rectangle_gaps(got[None, :2], np.array([stance.yaw]), step.xy, step.yaw,
                               e.foot)[0])  # fmt: skip
    assert e.params.min_clearance <= gap < e.params.min_clearance + 0.02 / 8
    assert np.allclose(e.clear_of_landing(stance, start, start - toward), start - toward)
    while e.landing is not None:  # (the double support: nothing swings)
        e.tick()
    assert np.allclose(e.clear_of_landing(stance, start, start + toward), start + toward)


@pytest.mark.parametrize("seed", [2, 5, 9])
def test_a_random_sequence_ends_where_its_integral_puts_it(setup, seed) -> None:
    """A random 30 s command sequence (a change every 2–5 s inside the velocity limits, as
    benchmarks/drive.py draws them) played on the engine alone, then a stop: its walking
    frame ends within 5 mm and 0.5° of where :func:`~wbc.drive.commands.integrate` — the
    drive record's commanded displacement — puts it: the turns, the starts' latency, the
    step latency of each change and the closing step add no error of their own (on the
    Bioloid's 20 sequences of benchmarks/drive.md: 0.94 mm mean, 4.2 mm at most)."""
    from wbc.drive.commands import integrate, random_commands
    from wbc.walking.geometry import rot2

    e = engine(setup)
    share = (LIMITS.vx_forward, LIMITS.vx_backward, LIMITS.vy, LIMITS.wz)
    commands = random_commands(np.random.default_rng([0, 1000 + seed]), share, 30.0)
    c0 = e.centre.copy()
    e.command(*commands[0].velocity)
    e.start()
    for c in commands:
        e.command(*c.velocity)
        for _ in range(round(c.duration / e.dt)):
            e.tick()
    e.stop()
    while e.walking:
        e.tick()
    xy, yaw = integrate(commands)
    moved = rot2(c0[2]).T @ (e.centre[:2] - c0[:2])
    assert np.linalg.norm(moved - xy) < 0.005
    assert abs(wrap_angle(e.centre[2] - c0[2] - yaw)) < math.radians(0.5)


@pytest.mark.parametrize("error", [(0.0, 0.0, 0.035), (0.006, -0.004, -0.03), (-0.008, 0.005, 0.0)])
def test_a_finish_step_closes_a_measured_error(setup, error) -> None:
    """Standing after a stop, :meth:`WalkEngine.finish_step` takes one more closing step
    aimed at the same commanded pose from the walking frame's measured error (measured less
    planned): the planned frame plus the error ends closer to the commanded pose (here the
    turning walk's own closing step was 1.5–5° and 9–15 mm off it too: less than half of
    that is left, the heading's less than 0.4), the commanded pose kept, the step valid, one
    step more; asked while walking it is refused in one line."""
    _, _, foot, legs = setup
    e = engine(setup)
    e.start()
    e.command(0.04, 0.0, 0.3)
    for _ in range(150):
        e.tick()
    e.stop()
    while e.walking:
        e.tick()
    with pytest.raises(ConfigurationError, match="standing"):
        walking = engine(setup)
        walking.start()
        walking.tick()
        walking.finish_step(np.zeros(3), "left")
    error = np.asarray(error)
    at_stop, steps = e.commanded_frame(), e.steps_taken

    def off() -> tuple[float, float]:
        d = e.commanded_frame() - (e.mid_frame() + error)
        return float(np.hypot(*d[:2])), abs(wrap_angle(d[2]))

    before = off()
    assert before[0] > 0.005 or before[1] > math.radians(1.0)
    feet = (e.feet["left"], e.feet["right"])
    e.finish_step(error)  # (the side whose step ends nearer)
    assert e.starting and not e.walking
    while e.starting or e.walking:
        e.tick()
    after = off()
    assert np.allclose(e.commanded_frame(), at_stop)
    assert e.steps_taken == steps + 1
    assert after[1] < 0.4 * before[1]
    assert after[0] + 0.1 * after[1] < 0.5 * (before[0] + 0.1 * before[1])  # (1.75 mm a degree)
    FootstepPlan(*feet, (e.planned[-1],)).validate(foot, legs, e.height, 0.005)
