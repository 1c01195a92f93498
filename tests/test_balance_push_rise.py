"""The push's rise (:mod:`wbc.balance.push_rise`, ``Gains.push_rise``): the CoM target raised
after a push away from the swing foot, held while the push lasts, lowered after."""

import numpy as np
import pytest

from wbc import load_robot
from wbc.balance.push_rise import PushRise
from wbc.balance.stabilizer import Gains, Stabilizer
from wbc.exceptions import ConfigurationError
from wbc.walking.loop import TickTargets

DT = 0.01


def test_the_rise_ramps_up_holds_and_comes_back_at_its_rate():
    """``push_rise × min(t / rise_time, 1)`` while pushed, held, then down at
    ``push_rise / rise_back`` m/s; a push again while coming down never lowers it."""
    r = PushRise()
    assert r.update(False, DT, 0.012, 0.03, 0.3) == 0.0
    up = [r.update(True, DT, 0.012, 0.03, 0.3) for _ in range(5)]
    assert up == pytest.approx([0.004, 0.008, 0.012, 0.012, 0.012])
    down = [r.update(False, DT, 0.012, 0.03, 0.3) for _ in range(3)]
    assert down == pytest.approx([0.0116, 0.0112, 0.0108])
    assert r.update(True, DT, 0.012, 0.03, 0.3) == pytest.approx(0.0108)  # (not 0.004)
    assert r.update(True, DT, 0.012, 0.03, 0.3) == pytest.approx(0.0108)
    assert r.update(True, DT, 0.012, 0.03, 0.3) == pytest.approx(0.012)
    for _ in range(40):
        last = r.update(False, DT, 0.012, 0.03, 0.3)
    assert last == 0.0  # (back, not below)


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def _left_stance(robot):
    """Single support on the left sole, standing: (the tick's targets, the CoM target, a
    function ``tick(stab, offset, targets=None, q_cmd=None)``: one tick of ``stab``'s hip
    strategy with the estimated DCM ``offset`` m from the left sole's centre away from the
    right sole, then its :meth:`_push_rise` of the CoM target (``targets``: for the legs'
    room; ``q_cmd``: the commanded configuration, for ``rise_knee``))."""
    from wbc.balance.estimator import StateEstimate

    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    left = robot.frame_placement(q, "l_sole")
    right = robot.frame_placement(q, "r_sole")
    R0 = robot.frame_placement(q, "torso").rotation
    com = robot.com(q)
    t = TickTargets(0, 0.0, "single", "l_sole", "r_sole", com, left, right, 0.0, R0,
                    right.translation.copy(), right.rotation.copy())  # fmt: skip
    u = left.rotation[:2, 1] / np.linalg.norm(left.rotation[:2, 1])  # (away from the right)

    def tick(stab, offset, targets=None, q_cmd=None):
        values = np.zeros((8, 3))
        values[:3] = np.eye(3)
        values[6, :2] = left.translation[:2] + offset * u
        stab._hip_strategy(t, StateEstimate(values), DT)
        return stab._push_rise(com, DT, targets, q_cmd)

    return t, com, tick


@pytest.mark.parametrize("rise", [0.0, 0.015])
def test_the_com_target_rises_only_after_the_push_trigger(robot, rise):
    """Single support on the left sole: the estimated DCM still, the CoM target as given;
    the DCM jumping outward (the hip strategy's push trigger) raises it by ``rise`` /
    ``rise_time`` a second (only the height), held while the trigger is latched."""
    _, com, tick = _left_stance(robot)
    stab = Stabilizer(robot, 0.2, lambda: None, None, Gains(push_rise=rise, rise_time=0.03))

    for _ in range(3):
        assert tick(stab, -0.03) is com  # no push: the target itself
    heights = [tick(stab, 0.005)[2] - com[2] for _ in range(5)]  # the jump, then latched
    want = [rise * min(k / 3, 1.0) for k in (1, 2, 3, 4, 5)]
    assert heights == pytest.approx(want, abs=1e-12)
    assert np.array_equal(tick(stab, 0.005)[:2], com[:2])


@pytest.mark.parametrize(
    "kw",
    [
        {"push_rise": -0.01},
        {"rise_room": -0.5},
        {"rise_knee": -0.1},
        {"rise_hold": -1.0},
        {"rise_time": 0.0},
        {"rise_back": float("nan")},
    ],
)
def test_bad_rise_gains_are_refused(kw):
    with pytest.raises(
        ConfigurationError, match=r"push_rise|rise_room|rise_knee|rise_hold|rise_time|rise_back"
    ):
        Gains(**kw).check()


def test_the_rise_stops_at_its_cap_and_follows_it_down():
    """``cap`` (the legs' room): the offset never above it, lowered with it, never below 0."""
    r = PushRise()
    up = [r.update(True, DT, 0.012, 0.03, 0.3, cap=0.005) for _ in range(3)]
    assert up == pytest.approx([0.004, 0.005, 0.005])
    assert r.update(True, DT, 0.012, 0.03, 0.3, cap=0.002) == pytest.approx(0.002)
    assert r.update(True, DT, 0.012, 0.03, 0.3, cap=-0.001) == 0.0


@pytest.mark.parametrize("phase", ["single", "double"])
def test_the_legs_room_is_where_a_loaded_leg_is_straight(robot, phase):
    """The CoM target raised by :func:`leg_room` puts the nearest loaded leg at the model's
    ``max_reach`` (:meth:`LegGeometry.leg_lengths`), the other loaded leg within it; in single
    support the swing leg does not count."""
    from wbc.balance.push_rise import leg_room
    from wbc.walking.legs import LegGeometry

    legs = LegGeometry.from_robot(robot, robot.configuration("stand"))
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    left = robot.frame_placement(q, "l_sole")
    right = robot.frame_placement(q, "r_sole").copy()
    right.translation = right.translation + np.array([0.0, -0.04, 0.0])  # (further out)
    R0 = robot.frame_placement(q, "torso").rotation
    com = robot.com(q) + np.array([0.0, 0.01, 0.0])  # (toward the left sole)
    t = TickTargets(0, 0.0, phase, "l_sole", "r_sole", com, left, right, 0.0, R0,
                    right.translation.copy(), right.rotation.copy())  # fmt: skip
    room = leg_room(legs, t, com)
    assert 0.0 < room < 0.05
    up = com + np.array([0.0, 0.0, room])
    lengths = legs.leg_lengths(up, np.zeros(1), left.translation, right.translation)[0]
    if phase == "single":  # (the left leg straight, the swing leg's reach passed)
        assert lengths[0] == pytest.approx(legs.max_reach, abs=1e-9)
        assert lengths[1] > legs.max_reach
    else:  # (the right leg, further out, straight first)
        assert lengths[1] == pytest.approx(legs.max_reach, abs=1e-9)
        assert lengths[0] < legs.max_reach
        assert room < leg_room(legs, t.replace(phase="single"), com)


@pytest.mark.parametrize("swapped", [False, True])
def test_the_rise_is_clipped_to_a_share_of_the_legs_room(robot, swapped):
    """``rise_room`` 0.5: a push raises the CoM target by at most half the stance leg's room,
    not ``push_rise`` (which is more); also with the gains swapped in after the start (as
    ``Walker`` does)."""
    from wbc.balance.push_rise import leg_room
    from wbc.walking.legs import LegGeometry

    t, com, tick = _left_stance(robot)

    gains = Gains(push_rise=0.05, rise_time=0.03, rise_room=0.5)
    stab = Stabilizer(robot, 0.2, lambda: None, None, Gains() if swapped else gains)
    if swapped:
        stab.gains = gains
    room = leg_room(LegGeometry.from_robot(robot, robot.configuration("stand")), t, com)
    assert 0.5 * room < 0.05

    for _ in range(3):
        assert tick(stab, -0.03, t) is com
    for _ in range(6):
        out = tick(stab, 0.005, t)
    assert out[2] - com[2] == pytest.approx(0.5 * room, abs=1e-12)


def _knee(robot, side="left"):
    return robot.joint_index(robot.roles.joint(side, "knee"))


@pytest.mark.parametrize("name", ["bioloid", "op3"])
def test_the_knee_room_is_where_the_knee_is_bend_from_straight(name):
    """:class:`KneeRoom`'s reach is the hip-to-ankle distance with the knee ``bend`` from its
    straightest, bent as it stands; on a configuration, a loaded hip raised by its room is
    that reach from its ankle; a straighter knee has less room, one beyond the bend less than
    none."""
    import pinocchio as pin

    from wbc.balance.push_rise import KneeRoom
    from wbc.roles import leg_segments

    robot = load_robot() if name == "bioloid" else load_robot(name)
    k = _knee(robot)
    stand = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    straight, bent = KneeRoom(robot, 0.0), KneeRoom(robot, 0.3)
    assert bent.reach < straight.reach
    ids = [
        robot.model.getJointId(robot.roles.joint("left", r)) for r in ("hip_pitch", "ankle_pitch")
    ]
    data = pin.Data(robot.model)

    def hip_ankle(q):
        pin.forwardKinematics(robot.model, data, q)
        return [data.oMi[i].translation.copy() for i in ids]

    thigh, shin = leg_segments(robot)  # (hip pitch -> knee -> ankle pitch)
    assert straight.reach == pytest.approx(thigh + shin, abs=1e-5)
    assert bent.reach == pytest.approx(
        np.sqrt(thigh**2 + shin**2 + 2 * thigh * shin * np.cos(0.3)), abs=1e-5
    )
    com_z, up = bent.room(stand, ("l_sole",))
    assert com_z == pytest.approx(robot.com(stand)[2])
    hip, ankle = hip_ankle(stand)
    assert 0.0 < up < 0.05
    assert np.linalg.norm(hip + np.array([0.0, 0.0, up]) - ankle) == pytest.approx(bent.reach)
    straighter = stand.copy()
    straighter[7 + k] = 0.5 * stand[7 + k]
    assert bent.room(straighter, ("l_sole",))[1] < up
    reach = []  # (the knee at its straightest: beyond the bend)
    for v in np.linspace(robot.q_min[k], robot.q_max[k], 200):
        straighter[7 + k] = v
        reach.append((np.linalg.norm(np.subtract(*hip_ankle(straighter))), v))
    straighter[7 + k] = max(reach)[1]
    assert bent.room(straighter, ("l_sole",))[1] < 0.0
    assert bent.room(straighter, ("l_sole", "r_sole"))[1] == bent.room(straighter, ("l_sole",))[1]
    assert bent.room(straighter, ("r_sole",))[1] == pytest.approx(up, abs=2e-3)


def test_the_rise_stops_at_the_commanded_legs_room(robot):
    """``rise_knee``: a push raises the CoM target at most the commanded configuration's
    loaded legs' room (knees ``rise_knee`` from straight) above its CoM, re-read each tick:
    a straighter stance knee in ``q_cmd`` lowers it; without ``q_cmd``, no cap."""
    from wbc.balance.push_rise import KneeRoom

    t, com, tick = _left_stance(robot)
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    gains = Gains(push_rise=0.05, rise_time=0.03, rise_knee=0.2)
    stab = Stabilizer(robot, 0.2, lambda: None, None, gains)
    com_z, up = KneeRoom(robot, 0.2).room(q, ("l_sole",))
    cap = com_z + up - com[2]
    assert 0.0 < cap < 0.05
    for _ in range(3):
        assert tick(stab, -0.03, t, q) is com
    for _ in range(6):
        out = tick(stab, 0.005, t, q)
    assert out[2] - com[2] == pytest.approx(cap, abs=1e-12)
    k = _knee(robot)
    straighter = q.copy()
    straighter[7 + k] = 0.5 * q[7 + k]
    lower = tick(stab, 0.005, t, straighter)[2] - com[2]
    assert 0.0 <= lower < cap
    free = Stabilizer(robot, 0.2, lambda: None, None, gains)
    for _ in range(3):
        tick(free, -0.03, t)
    for _ in range(6):
        out = tick(free, 0.005, t)
    assert out[2] - com[2] == pytest.approx(0.05, abs=1e-12)


def test_the_rise_is_held_at_most_rise_hold_then_lowered_while_still_pushed():
    """``hold``: the offset comes down ``hold`` s after the trigger though the push lasts, is
    not raised again while it lasts, and rises again on the next trigger."""
    r = PushRise()
    up = [r.update(True, DT, 0.012, 0.03, 0.3, hold=0.05) for _ in range(7)]
    assert up == pytest.approx([0.004, 0.008, 0.012, 0.012, 0.012, 0.0116, 0.0112])
    assert r.update(True, DT, 0.012, 0.03, 0.3, hold=0.05) == pytest.approx(0.0108)
    assert r.update(False, DT, 0.012, 0.03, 0.3, hold=0.05) == pytest.approx(0.0104)
    assert r.update(True, DT, 0.012, 0.03, 0.3, hold=0.05) == pytest.approx(0.0104)
    r.update(True, DT, 0.012, 0.03, 0.3, hold=0.05)
    assert r.update(True, DT, 0.012, 0.03, 0.3, hold=0.05) == pytest.approx(0.012)


def test_rise_hold_reaches_the_stabilizer(robot):
    """``Gains.rise_hold`` 0.05: the stabilizer's rise comes down after 5 ticks of a latched
    push trigger (without it, held)."""
    _, com, tick = _left_stance(robot)
    held = Stabilizer(robot, 0.2, lambda: None, None, Gains(push_rise=0.012))
    short = Stabilizer(robot, 0.2, lambda: None, None, Gains(push_rise=0.012, rise_hold=0.05))
    for stab in (held, short):
        for _ in range(3):
            tick(stab, -0.03)
    last = [[tick(s, 0.005)[2] - com[2] for s in (held, short)] for _ in range(8)][-1]
    assert last == pytest.approx([0.012, 0.0108])


def test_rise_single_lowers_the_rise_in_double_support(robot):
    """``Gains.rise_single``: the rise held in single support comes down from the double
    support on (at ``push_rise / rise_back`` m/s) though the trigger is latched, and goes on
    down in the next single support; without it, held."""
    t, com, tick = _left_stance(robot)
    double = t.replace(phase="double")
    held = Stabilizer(robot, 0.2, lambda: None, None, Gains(push_rise=0.012))
    single = Stabilizer(robot, 0.2, lambda: None, None, Gains(push_rise=0.012, rise_single=1))
    for stab in (held, single):
        for _ in range(3):
            tick(stab, -0.03, t)
        for _ in range(4):
            up = tick(stab, 0.005, t)[2] - com[2]
        assert up == pytest.approx(0.012)
    out = [[tick(s, 0.005, double)[2] - com[2] for s in (held, single)] for _ in range(2)]
    assert np.ravel(out) == pytest.approx([0.012, 0.0116, 0.012, 0.0112])
    again = [tick(s, 0.005, t)[2] - com[2] for s in (held, single)]  # (single support again:
    assert again == pytest.approx([0.012, 0.0108])  # not raised again while still pushed)
