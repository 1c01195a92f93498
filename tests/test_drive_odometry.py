"""wbc.drive.odometry: the IMU-aided pose odometry of driven walks."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc import load_robot
from wbc.compiled.rows import log3
from wbc.drive.odometry import (
    DRIVE_HEADING_BAND,
    BaseHold,
    LandingMean,
    LiftGain,
    PlayInverse,
    PoseOdometry,
    StrideGain,
)
from wbc.exceptions import ConfigurationError
from wbc.geometry import yaw_of
from wbc.walking import StandingState


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


@settings(max_examples=20, deadline=None)
@given(
    st.floats(0.0, 0.3),  # lean (pitch, rad)
    st.floats(0.02, 0.15),  # roll amplitude
    st.floats(0.0, 0.08),  # pitch amplitude
    st.floats(-0.6, 0.6),  # turning rate (rad/s)
    st.floats(0.0, 2 * math.pi),  # phase
)
def test_heading_of_a_leaning_rocking_torso(robot, lean, roll, pitch, rate, phase) -> None:
    """The heading integrated from the body rates is the torso's heading (the yaw of its
    rotation), however the torso leans and rocks meanwhile: 10 s of a walk's rocking (1 Hz
    roll, pitch out of phase) at 100 Hz, within 0.3°. (The vertical rate's integral,
    ``Σ (R ω)_z dt``, is not: it drifts by the rocking's enclosed area per cycle, ~20° over
    30 s on the randomised Bioloids.)"""
    dt, w = 0.01, 2 * math.pi
    t = np.arange(1001) * dt

    def R(tk: float) -> np.ndarray:
        return pin.rpy.rpyToMatrix(roll * math.sin(w * tk),
                                   lean + pitch * math.sin(w * tk + phase), rate * tk)  # fmt: skip

    odo = PoseOdometry(robot)
    v = np.empty(3)
    for a, b in itertools.pairwise(t):
        Ra, Rb = R(a), R(b)
        log3(np.ascontiguousarray(Ra.T @ Rb), v)
        odo.turn(Ra, v / dt, dt)
    assert odo.heading == pytest.approx(rate * t[-1], abs=math.radians(0.3))


def test_a_stance_sole_turned_on_the_floor_is_seen(robot) -> None:
    """The robot standing, its stance (right) sole turned by 0.2 rad on the floor — the IMU
    sees the torso's heading turned, the encoders nothing: the landed left sole is placed
    turned about the right one, and the walking frame measured heads 0.2 rad left of the
    plan (the engine's own leg odometry would see no offset at all)."""
    q = robot.configuration("stand")
    start = StandingState.from_robot(robot, q)
    feet = {"left": start.left, "right": start.right}
    torso = yaw_of(robot.frame_placement(q, "torso").rotation)
    odo = PoseOdometry(robot)
    odo.start(feet, torso)
    still = odo.landed("left", q)
    mid = 0.5 * (start.left.xy + start.right.xy)
    assert still[:2] == pytest.approx(mid, abs=1e-5)  # (the stand pose's soles not quite flat)
    assert still[2] == pytest.approx(0.5 * (start.left.yaw + start.right.yaw), abs=1e-3)
    odo.start(feet, torso + 0.2)
    turned = odo.landed("left", q)
    assert turned[2] == pytest.approx(still[2] + 0.2, abs=1e-6)
    c, s = math.cos(0.2), math.sin(0.2)
    left = start.right.xy + np.array([[c, -s], [s, c]]) @ (start.left.xy - start.right.xy)
    assert odo.soles["left"][:2] == pytest.approx(left, abs=1e-5)
    assert odo.soles["right"][:2] == pytest.approx(start.right.xy)  # (a sole does not slide)


@pytest.mark.parametrize("gain", [0.25, 0.5, 1.0])
def test_a_heading_gain_blends_the_gyros_stance_heading_with_the_encoders_chain(
    robot, gain: float
) -> None:
    """``heading_gain`` k: at each landing the stance sole's heading moves the share k of
    the way from the encoders' chain (where the last landing placed it) to the gyro's; a
    turn the gyro keeps seeing is followed within (1 − k)^n after n landings, and a reading
    that flips sign from one landing to the next is damped (k = 1: the gyro's at once)."""
    q = robot.configuration("stand")
    start = StandingState.from_robot(robot, q)
    feet = {"left": start.left, "right": start.right}
    torso = yaw_of(robot.frame_placement(q, "torso").rotation)
    plain = PoseOdometry(robot)
    plain.start(feet, torso)
    planned = {side: plain.landed(side, q)[2] for side in ("left", "right")}
    odo = PoseOdometry(robot, heading_gain=gain, heading_band=math.inf)
    odo.start(feet, torso + 0.2)  # the gyro's heading 0.2 rad off the planned soles'
    for n, side in enumerate(("left", "right", "left", "right"), start=1):
        frame = odo.landed(side, q)
        # (abs: the stand pose's soles are not quite flat: its planned soles and its joints'
        # turn differ by 4e-4 rad)
        assert frame[2] - planned[side] == pytest.approx(0.2 * (1 - (1 - gain) ** n), abs=1e-3)
    banded = PoseOdometry(robot, heading_gain=gain)  # (DRIVE_HEADING_BAND: 1°)
    banded.start(feet, torso + 0.2)  # a turn beyond the band: followed at once
    frame = banded.landed("left", q)
    assert frame[2] - planned["left"] == pytest.approx(
        0.2 - (1 - gain) * DRIVE_HEADING_BAND, abs=1e-3
    )
    flip = PoseOdometry(robot, heading_gain=gain)
    flip.start(feet, torso)
    seen = []
    for n, side in enumerate(("left", "right") * 4):
        flip.heading = torso + (0.01 if n % 2 else -0.01)  # alternating ±0.01 rad
        seen.append(flip.landed(side, q)[2] - planned[side])
    assert max(abs(v) for v in seen[-4:]) == pytest.approx(0.01 * gain / (2 - gain), abs=1e-3)
    with pytest.raises(ConfigurationError, match="heading_gain"):
        PoseOdometry(robot, heading_gain=0.0)
    with pytest.raises(ConfigurationError, match="heading_band"):
        PoseOdometry(robot, heading_band=-1.0)


@settings(max_examples=15, deadline=None)
@given(
    st.floats(0.05, 0.3),  # lean (pitch, rad)
    st.floats(0.0, 0.08),  # roll amplitude at rest
    st.floats(0.0, 0.08),  # pitch amplitude at rest
    st.floats(0.0, 2 * math.pi),  # phase
    st.lists(st.floats(-0.03, 0.03), min_size=3, max_size=3),  # the gyro's bias (torso frame)
    st.floats(-0.6, 0.6),  # turning rate afterwards (rad/s)
)
def test_the_gyros_vertical_bias_is_learnt_at_rest(
    robot, lean, roll, pitch, phase, bias, rate
) -> None:
    """A constant gyro bias ``b`` (torso frame) drifts the heading by its vertical part,
    which the accelerometer cannot level. Standing 2 s (the torso rocking in roll and pitch
    out of phase at 1 Hz, its heading still), :meth:`PoseOdometry.rest` learns it: the
    heading then integrates 10 s of turning within 0.3° (without the rest: off by the
    bias's vertical part × 10 s, up to 17°). Learnt from the heading's mean rate, not the
    vertical rate's mean, which the out-of-phase rocking biases by its enclosed area."""
    dt, w = 0.01, 2 * math.pi
    b = np.asarray(bias)

    def R(tk: float, turning: float) -> np.ndarray:
        pitch_t = lean + pitch * math.sin(w * tk + phase)
        return pin.rpy.rpyToMatrix(roll * math.sin(w * tk), pitch_t, turning * tk)

    def feed(odo: PoseOdometry, t: np.ndarray, turning: float, at_rest: bool) -> None:
        v = np.empty(3)
        for a, c in itertools.pairwise(t):
            Ra, Rc = R(a, turning), R(c, turning)
            log3(np.ascontiguousarray(Ra.T @ Rc), v)
            (odo.rest if at_rest else odo.turn)(Ra, v / dt + b, dt)

    rest, walk = np.arange(201) * dt, np.arange(1001) * dt
    odo, plain = PoseOdometry(robot), PoseOdometry(robot)
    feed(odo, rest, 0.0, True)
    assert odo.rest_time == pytest.approx(2.0)
    # the heading's (ZYX yaw's) rate the bias makes: (b_y sin φ + b_z cos φ) / cos θ
    rp = [(roll * math.sin(w * t), lean + pitch * math.sin(w * t + phase)) for t in rest]
    vertical = float(np.mean([(b[1] * math.sin(r) + b[2] * math.cos(r)) / math.cos(p)
                              for r, p in rp]))  # fmt: skip
    assert odo.yaw_bias == pytest.approx(vertical, abs=3e-4)
    for o in (odo, plain):
        o.heading = 0.0
        feed(o, walk, rate, False)
    assert odo.heading == pytest.approx(rate * walk[-1], abs=math.radians(0.3))
    drift = plain.heading - rate * walk[-1]
    assert drift == pytest.approx(vertical * walk[-1], abs=math.radians(0.5))


@pytest.mark.parametrize("walk_gain", [0.0, 0.1])
def test_the_gyros_vertical_bias_is_learnt_while_walking(robot, walk_gain: float) -> None:
    """The robot stepping in place (the stand pose's joints at every landing, soles not
    turning on the floor), the gyro reading a vertical bias of 0.01 rad/s that the rest did
    not learn: with ``walk_gain`` the stance sole's heading by the gyro against the
    encoders' learns it within 10 % over 40 steps (0.5 s each) and the heading stops
    drifting; without it the heading drifts by the bias × the time (20 s: 11°)."""
    q = robot.configuration("stand")
    start = StandingState.from_robot(robot, q)
    R = robot.frame_placement(q, "torso").rotation
    odo = PoseOdometry(robot, walk_gain=walk_gain)
    odo.start({"left": start.left, "right": start.right}, yaw_of(R))
    heading0 = odo.heading
    bias, dt = 0.01, 0.01
    for k in range(40):
        for _ in range(50):
            odo.turn(R, np.array([0.0, 0.0, bias]), dt)
        odo.landed("left" if k % 2 == 0 else "right", q)
    drift = odo.heading - heading0
    if walk_gain:
        assert odo.yaw_bias == pytest.approx(bias, rel=0.1)
        assert abs(drift) < 0.5 * bias * 20.0
    else:
        assert odo.yaw_bias == 0.0
        assert drift == pytest.approx(bias * 20.0, rel=0.02)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.4, 1.0), st.floats(-0.6, 0.6), st.floats(1.0, 2.0))
def test_a_stride_gain_makes_up_short_steps(efficiency: float, turn: float, most: float) -> None:
    """Steps measured at ``efficiency`` × their plan forward (sideways and turning as
    planned): the gain on the forward stride tends to ``1 / efficiency`` (within the
    largest, ``most``), the other axes' stay 1 (never shorter)."""
    gain = StrideGain(most)
    planned, measured = np.zeros(3), np.zeros(3)
    stride = np.array([0.03, 0.004, 0.1])
    for _ in range(60):
        gain.landed(planned, measured)
        for frame, scale in ((planned, 1.0), (measured, efficiency)):
            c, s = math.cos(frame[2]), math.sin(frame[2])
            frame[:2] += np.array([[c, -s], [s, c]]) @ (stride[:2] * [scale, 1.0])
            frame[2] += stride[2] * turn
    g = gain.landed(planned, measured)
    assert g[0] == pytest.approx(min(1.0 / efficiency, most), rel=0.02)
    assert g[1:] == pytest.approx([1.0, 1.0], abs=0.02)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.2, 1.0), st.floats(0.0, 0.004), st.floats(1.0, 2.5))
def test_a_lift_gain_raises_a_low_swing_to_its_apex(efficiency: float, sag: float,
                                                    most: float) -> None:  # fmt: skip
    """A swing sole that reaches ``efficiency`` × its planned apex less ``sag`` (a lagging,
    sagging leg): the gain on the apex settles where the measured apex is the height wanted
    (``want`` × the apex; within the largest, ``most``: there it stays at ``most``), never
    below 1."""
    apex = 0.01
    lift = LiftGain(most)
    for _ in range(80):
        lift.landed(apex, efficiency * apex * lift.gain - sag)
    want = (lift.want * apex + sag) / (efficiency * apex)
    assert lift.gain == pytest.approx(min(max(want, 1.0), most), rel=0.01)
    assert 1.0 <= lift.gain <= most


def test_a_lift_gain_ignores_an_unread_swing() -> None:
    lift = LiftGain(2.0)
    assert lift.landed(0.01, 0.005) > 1.0
    g = lift.gain
    assert lift.landed(0.01, math.nan) == g
    assert lift.landed(0.01, -math.inf) == g


@pytest.mark.parametrize("encoder_rest", [True, False])
def test_a_torso_turning_at_rest_over_its_soles_is_not_bias(robot, encoder_rest: bool) -> None:
    """Standing 1.5 s, the torso settles 0.6° about the vertical over its soles (a twist
    in the hips the encoders see: the rotation :meth:`PoseOdometry.rest` gets is the
    torso's over the stance sole, its heading included) while the gyro, biased 0.005 rad/s
    about the vertical, sees the twist too: the bias learnt is the gyro's alone; without
    the encoders' turn (``encoder_rest=False``) the twist is taken for bias (0.6° / 1.5 s
    = 0.007 rad/s more)."""
    dt, lean, bias, twist = 0.01, 0.17, 0.005, math.radians(0.6)
    odo = PoseOdometry(robot, encoder_rest=encoder_rest)
    psi = lambda t: twist * min(t / 0.5, 1.0)  # noqa: E731
    v = np.empty(3)
    for k in range(150):
        Ra = pin.rpy.rpyToMatrix(0.0, lean, psi(k * dt))
        Rc = pin.rpy.rpyToMatrix(0.0, lean, psi((k + 1) * dt))
        log3(np.ascontiguousarray(Ra.T @ Rc), v)
        odo.rest(Ra, v / dt + Ra.T @ np.array([0.0, 0.0, bias]), dt)
    want = bias if encoder_rest else bias + twist / 1.5
    assert odo.yaw_bias == pytest.approx(want, abs=3e-4)


@pytest.mark.parametrize("rest_rotation", [True, False])
def test_the_rest_learns_the_gyros_whole_bias_less_the_torsos_rotation(
    robot, rest_rotation: bool
) -> None:
    """Standing 1.5 s the torso settles 2° forward and twists 0.6° over its soles (the
    encoders see both) while the gyro is biased about all three axes (0.05 rad/s about the
    torso's pitch axis); then 10 s of walking leaning 17° forward, rolled 2° on average and
    rocking, its heading unchanged. With ``rest_rotation`` the bias learnt is the gyro's (to
    3e-4 rad/s) and the heading stays within 0.15°; without it the twist is taken for bias
    and the rest's lean projects the rest: the heading drifts more than 2°."""
    dt, bias = 0.01, np.array([0.003, -0.05, 0.005])
    odo = PoseOdometry(robot, rest_rotation=rest_rotation)
    twist, settle = math.radians(0.6), math.radians(2.0)

    def rest_pose(t: float) -> np.ndarray:
        return pin.rpy.rpyToMatrix(
            0.0, 0.17 + settle * min(t / 1.5, 1.0), twist * min(t / 0.5, 1.0)
        )

    def walk_pose(t: float) -> np.ndarray:
        roll = math.radians(2.0) + 0.1 * math.sin(2 * math.pi * t)
        return pin.rpy.rpyToMatrix(roll, 0.3 + 0.03 * math.sin(4 * math.pi * t), twist)

    v = np.empty(3)

    def tick(pose, k: int, call) -> None:
        Ra, Rc = pose(k * dt), pose((k + 1) * dt)
        log3(np.ascontiguousarray(Ra.T @ Rc), v)
        call(Ra, v / dt + bias, dt)

    for k in range(150):
        tick(rest_pose, k, odo.rest)
    if rest_rotation:
        np.testing.assert_allclose(odo.rate_bias, bias, atol=3e-4)
    start = odo.heading
    for k in range(1000):
        tick(walk_pose, k, odo.turn)
    drift = abs(math.degrees(odo.heading - start))
    assert drift < 0.15 if rest_rotation else drift > 2.0


@pytest.mark.parametrize("play_deg", [0.6, 1.0])
def test_the_play_inverse_reads_the_links_through_the_simulated_gears_play(
    robot, play_deg: float
) -> None:
    """The simulator's servos (:class:`~wbc.sim.actuator.ServoArray`, its backlash) read a
    leg's links moving back and forth (each joint a sum of two sines, 3 s at 100 Hz, the
    present positions quantised): while a joint moves the raw reading lags its link by half
    the play (mean error 0.29° and 0.48° for 0.6° and 1° of play); :class:`PlayInverse` with
    the servos' play reads the links to within the quantisation and the reversals (0.09°,
    0.12°; under half a tick), and with no play it returns the reading itself."""
    from wbc.sim.actuator import ServoArray, nominal_servo

    play = math.radians(play_deg)
    servos = ServoArray(robot.servo_map, replace(nominal_servo(robot), backlash=play))
    n = robot.n_joints
    rng = np.random.default_rng(3)
    amp, freq, phase = (
        rng.uniform(0.05, 0.3, (2, n)),
        rng.uniform(0.3, 2.0, (2, n)),
        rng.uniform(0, 2 * math.pi, (2, n)),
    )
    link = lambda t: (amp * np.sin(2 * math.pi * freq * t + phase)).sum(axis=0)  # noqa: E731
    servos.reset(link(0.0))
    inverse, none = PlayInverse(play, n), PlayInverse(0.0, n)
    raw_err, err = [], []
    for k in range(1, 300):
        q = link(0.01 * k)
        present = servos.angles(servos.present(q))
        assert np.array_equal(none.update(present), present)
        links = inverse.update(present)
        if k > 50:
            raw_err.append(np.abs(present - q))
            err.append(np.abs(links - q))
    raw, fixed = np.mean(raw_err), np.mean(err)
    assert raw > 0.35 * play  # (the play is there to take out)
    assert fixed < raw / 2.5
    assert fixed < 0.5 * servos.rad_per_tick  # (what the quantisation leaves: ~0.25 tick)


def test_the_play_inverse_refuses_a_bad_play_and_keeps_an_unread_joint() -> None:
    with pytest.raises(ConfigurationError, match="play"):
        PlayInverse(-0.01, 3)
    with pytest.raises(ConfigurationError, match="play"):
        PlayInverse([0.01, math.nan, 0.0], 3)
    with pytest.raises(ConfigurationError, match="one per joint"):
        PlayInverse([0.01, 0.01], 3)
    inverse = PlayInverse(0.02, 2)
    inverse.update(np.array([0.0, 0.0]))
    assert inverse.update(np.array([0.1, -0.1])) == pytest.approx([0.11, -0.11])
    out = inverse.update(np.array([math.nan, -0.05]))  # joint 0 unread: NaN, its side kept
    assert math.isnan(out[0]) and out[1] == pytest.approx(-0.04)
    assert inverse.update(np.array([0.1, -0.05])) == pytest.approx([0.11, -0.04])


def test_a_still_reading_is_taken_at_the_middle_of_the_play_after_the_hold() -> None:
    """A reading that stood still longer than ``hold`` is taken at the middle of the play
    (its link may have turned back inside it); while it moves, at the side it moved to."""
    inverse = PlayInverse(0.02, 1, hold=0.1)
    inverse.update(np.array([0.0]), 0.01)
    assert inverse.update(np.array([0.005]), 0.01) == pytest.approx([0.015])
    for _ in range(10):  # 0.1 s still: the side kept
        assert inverse.update(np.array([0.005]), 0.01) == pytest.approx([0.015])
    assert inverse.update(np.array([0.005]), 0.01) == pytest.approx([0.005])
    assert inverse.update(np.array([0.0]), 0.01) == pytest.approx([-0.01])
    with pytest.raises(ConfigurationError, match="hold"):
        PlayInverse(0.02, 1, hold=0.0)


def test_a_loaded_link_is_read_on_the_flank_its_load_pushes_it_to() -> None:
    """``load="still"``: a reading standing still past the hold is taken at the load's flank
    (not the middle), a moving one at its motion's side; ``"always"``: the load's flank
    wherever the load is known (0 or NaN: unknown, the motion's side); ``""`` ignores it."""
    load = np.array([-1.0, 1.0, 0.0, math.nan])
    out = {}
    for mode in ("", "still", "always"):
        inverse = PlayInverse(0.02, 4, hold=0.1, load=mode)
        inverse.update(np.zeros(4), 0.01, load)
        moved = inverse.update(np.full(4, 0.005), 0.01, load)  # all moved up
        for _ in range(11):  # 0.11 s still: past the hold
            still = inverse.update(np.full(4, 0.005), 0.01, load)
        out[mode] = (moved, still)
    assert out[""][0] == pytest.approx([0.015] * 4)
    assert out[""][1] == pytest.approx([0.005] * 4)  # (the middle)
    assert out["still"][0] == pytest.approx([0.015] * 4)
    assert out["still"][1] == pytest.approx([-0.005, 0.015, 0.005, 0.005])
    assert out["always"][0] == pytest.approx([-0.005, 0.015, 0.015, 0.015])
    assert out["always"][1] == pytest.approx([-0.005, 0.015, 0.005, 0.005])
    with pytest.raises(ConfigurationError, match="load"):
        PlayInverse(0.02, 1, load="motor")


def test_the_base_hold_moves_the_com_target_against_the_error_within_its_bounds() -> None:
    """Holding (after :meth:`BaseHold.begin`), the CoM target's shift moves against the
    base's error at ``rate`` and no further than ``reach``; it stops when the error is
    within the tolerance, or after ``seconds``; standing it is kept; walking it returns to
    none at ``rate``; before any :meth:`begin` nothing moves."""
    dt = 0.01
    hold = BaseHold(reach=0.02, rate=0.02, seconds=1.0)
    assert not hold.update(np.array([0.01, 0.0]), dt, walking=False).any()  # (no walk ended)
    hold.begin()
    assert hold.active
    error = np.array([0.006, -0.008])  # 10 mm
    out = hold.update(error, dt, walking=False)
    assert np.hypot(*out) == pytest.approx(0.02 * dt)
    assert out / np.hypot(*out) == pytest.approx(error / 0.01)
    for _ in range(200):  # a base that does not follow: the shift stops at the reach
        out = hold.update(error, dt, walking=False)
    assert np.hypot(*out) == pytest.approx(0.02) and not hold.active  # (1 s is over)
    kept = out.copy()
    assert hold.update(np.array([0.005, 0.0]), dt, walking=False) == pytest.approx(kept)
    hold.begin()
    hold.update(np.array([0.0002, 0.0]), dt, walking=False)  # within the tolerance: done
    assert not hold.active
    for k in range(1, 5):
        out = hold.update(None, dt, walking=True)
        assert np.hypot(*out) == pytest.approx(0.02 - k * 0.02 * dt, abs=1e-4)
    with pytest.raises(ConfigurationError, match="rate"):
        BaseHold(0.02, -1.0, 1.0)


def test_a_landing_is_placed_by_the_mean_over_its_double_support(robot) -> None:
    """Readings dithering ±δ about the standing joints through a double support: the mean
    placement of either landed sole is the still one's within δ² terms, the last tick's
    alone is δ off; the share takes the last ticks only; a tick out of the double support
    restarts; PoseOdometry places the landed sole by the placement given (the walking frame, the
    soles' midpoint, by half of it)."""
    q = robot.configuration("stand")
    (still,) = robot.placements_in(q, "l_sole", ["r_sole"])
    right = np.r_[still.translation[:2], yaw_of(still.rotation)]
    left = np.r_[still.inverse().translation[:2], yaw_of(still.inverse().rotation)]
    delta = 0.02  # rad, on every joint
    dither = [robot.with_joints(q[7:] + (delta if k % 2 else -delta)) for k in range(8)]
    mean = LandingMean(robot, 1.0)
    assert mean.placed("left") is None
    mean.sample(robot.with_joints(q[7:] + 0.3), double=False)  # (forgotten at the next)
    for k, qk in enumerate(dither):
        mean.sample(qk, double=k > 0)
    last = LandingMean(robot, 0.0)
    last.sample(dither[-1], double=True)
    for side, want in (("right", right), ("left", left)):
        assert np.abs(mean.placed(side) - want).max() < 2e-4  # type: ignore[operator]
        assert np.abs(last.placed(side) - want).max() > 1e-3  # type: ignore[operator]
    half = LandingMean(robot, 0.5)
    for qk in [robot.with_joints(q[7:] + 0.3)] * 4 + dither[:4]:  # (the first four: outside)
        half.sample(qk, double=True)
    assert np.abs(half.placed("right") - right).max() < 2e-4  # type: ignore[operator]
    start = StandingState.from_robot(robot, q)
    feet = {"left": start.left, "right": start.right}
    torso = yaw_of(robot.frame_placement(q, "torso").rotation)
    odo, plain = PoseOdometry(robot), PoseOdometry(robot)
    odo.start(feet, torso)
    plain.start(feet, torso)
    assert odo.landed("right", q, mean.placed("right")) == pytest.approx(
        plain.landed("right", q), abs=2e-4
    )
    shifted = odo.landed("right", q, right + np.array([0.01, 0.0, 0.0]))  # 1 cm forward
    assert np.hypot(*(shifted[:2] - plain.landed("right", q)[:2])) == pytest.approx(0.005)
    with pytest.raises(ConfigurationError, match="share"):
        LandingMean(robot, 1.5)
