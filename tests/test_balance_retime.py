"""Re-timing after a push (wbc.balance.retime): the lift-off hold and the narrowed sway."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from wbc.balance.retime import HoldParams, PhaseHold, narrowed_sway
from wbc.bench.trajectories import build
from wbc.exceptions import WbcError
from wbc.recording import SUPPORT_DOUBLE


@pytest.fixture(scope="module")
def walk10(robot):
    return build("walk10", robot)


def first_lift_off(ref):
    """(last double-support tick, first single-support tick) of the first lift-off."""
    for a, _, code in ref.phases():
        if a > 0 and code != SUPPORT_DOUBLE and ref.support[a - 1] == SUPPORT_DOUBLE:
            return a - 1, a
    raise AssertionError("no lift-off")


def dcm_ref(ref, i):
    return ref.com[i, :2] + ref.com_vel[i, :2] / math.sqrt(ref.g / ref.com_height)


def toward_lift(ref, i):
    stance = ref.stance_side(i)
    lift = "right" if stance == "left" else "left"
    v = ref.sole(lift)[0][i, :2] - ref.sole(stance)[0][i, :2]
    return v / np.linalg.norm(v)


def test_a_lift_off_waits_while_the_dcm_is_toward_the_lifting_sole(walk10):
    last, i = first_lift_off(walk10)
    v = toward_lift(walk10, i)
    hold = PhaseHold(HoldParams(band=0.02, max_hold=0.05))
    assert hold.error(walk10, i, dcm_ref(walk10, i) + 0.03 * v) == pytest.approx(0.03)
    away = dcm_ref(walk10, i) + 0.03 * v
    waits = [hold.wait(walk10, last, i, away, 0.01) for _ in range(7)]
    # held 5 ticks (50 ms, max_hold), then it lifts off; one hold counted
    assert waits == [True] * 5 + [False, True]
    assert hold.holds == 2 and hold.held == pytest.approx(0.06)
    assert hold.worst == pytest.approx(0.03)
    ready = PhaseHold(HoldParams(band=0.02))
    # on its plan, beside it, or toward the stance sole: no wait
    for dcm in (dcm_ref(walk10, i), dcm_ref(walk10, i) + 0.019 * v, dcm_ref(walk10, i) - 0.1 * v):
        assert not ready.wait(walk10, last, i, dcm, 0.01)
    assert ready.holds == 0
    # only a double support's last tick followed by a single support's tick may wait
    assert not ready.wait(walk10, i, i + 1, away, 0.01)
    assert not ready.wait(walk10, last - 1, last, away, 0.01)


def test_bad_hold_parameters_are_refused():
    with pytest.raises(WbcError, match="band"):
        HoldParams(band=-0.01).check()
    with pytest.raises(WbcError, match="max_hold"):
        PhaseHold(HoldParams(max_hold=math.nan))


def test_narrowed_sway_moves_the_com_toward_the_swing_sole_smoothly(walk10):
    shift = 0.004
    out = narrowed_sway(walk10, shift)
    d = out.com - walk10.com
    assert np.all(d[:, 2] == 0)
    for a, b, code in walk10.phases():
        if code == SUPPORT_DOUBLE:
            assert np.all(d[a:b] == 0)
            continue
        mid = (a + b) // 2
        yaw = walk10.sole(walk10.stance_side(a))[1][a]
        v = np.array([-math.sin(yaw), math.cos(yaw)])
        v = v if toward_lift(walk10, a) @ v > 0 else -v
        # at mid single support: the CoM and the DCM moved `shift` toward the other sole
        assert d[mid, :2] @ v == pytest.approx(shift, rel=0.02)
        assert (dcm_ref(out, mid) - dcm_ref(walk10, mid)) @ v == pytest.approx(shift, rel=0.05)
        assert np.all(np.linalg.norm(d[a:b, :2], axis=1) <= shift + 1e-12)
    # inside each phase, the added velocity and acceleration are the added position's
    # derivatives (central differences, O(dt²))
    dv = out.com_vel - walk10.com_vel
    da = out.com_acc - walk10.com_acc
    dt = walk10.dt
    inner = np.concatenate([np.arange(a + 1, b - 1) for a, b, _ in walk10.phases()])
    fd_v = (d[inner + 1, :2] - d[inner - 1, :2]) / (2 * dt)
    fd_a = (d[inner + 1, :2] - 2 * d[inner, :2] + d[inner - 1, :2]) / dt**2
    assert np.allclose(fd_v, dv[inner, :2], atol=2e-3)
    assert np.allclose(fd_a, da[inner, :2], atol=0.05)
    assert np.max(np.abs(dv)) > 0.02  # (not vacuous)
    # the position stays continuous (no jump at a support change)
    assert np.max(np.abs(np.diff(d[:, :2], axis=0))) < 2.0 * shift * math.pi * dt / 0.2


def test_narrowed_sway_leaves_static_gaits_long_supports_and_zero_alone(robot, walk10):
    static = build("static_walk", robot)
    assert narrowed_sway(static, 0.004) is static
    fast = build("fast_wb", robot)  # 0.4 s single supports: longer than SWAY_LONGEST
    assert np.array_equal(narrowed_sway(fast, 0.004).com, fast.com)
    assert not np.array_equal(narrowed_sway(fast, 0.004, longest=0.5).com, fast.com)
    assert narrowed_sway(walk10, 0.0) is walk10
    with pytest.raises(WbcError, match="sway"):
        narrowed_sway(walk10, -0.001)


class _FixedDcm:
    """A stand-in stabilizer: always enabled, its last estimate's DCM at ``dcm``."""

    def __init__(self, dcm) -> None:
        self.enabled = True
        self.dcm = np.asarray(dcm, float)

    @property
    def last(self):
        return self

    def adjust(self, targets, com_vel_ref, q, dt):
        return targets


def test_a_session_replays_the_double_support_while_the_lift_off_waits(robot, walk10):
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    last, i = first_lift_off(walk10)
    v = toward_lift(walk10, i)
    stab = _FixedDcm(dcm_ref(walk10, i) + 0.05 * v)
    hold = PhaseHold(HoldParams(band=0.02, max_hold=1.0))
    session = Session(StackController(load_stack("walk", robot)), robot, walk10, stabilizer=stab,
                      hold=hold)  # fmt: skip
    dt = walk10.dt
    for k in range(last + 1):
        session.at_time(k * dt)
    assert session.index == last
    for k in range(last + 1, last + 6):  # the DCM is not ready: the double support goes on
        q = session.at_time(k * dt)
        assert session.index == last and robot.within_limits(q)
    assert session.delay == pytest.approx(5 * dt)
    assert hold.holds == 1
    stab.dcm = dcm_ref(walk10, i)  # ready: the walk resumes where it stopped, 50 ms late
    session.at_time((last + 6) * dt)
    assert session.index == i
    # both soles stayed on their double-support targets meanwhile
    for side in ("l_sole", "r_sole"):
        placed = robot.frame_placement(session.q, side).translation
        planned = walk10.sole("left" if side == "l_sole" else "right")[0][last]
        assert np.linalg.norm(placed - planned) < 1e-3
    assert session.at_time(walk10.duration + 5 * dt - 1e-6) is not None  # ends 50 ms late
    assert session.at_time(walk10.duration + 5 * dt + 0.02) is None


def test_the_retimed_closed_loop_catches_a_push_the_closed_loop_before_it_cannot(robot):
    """walk10 closed loop (wqp-daqp, compliance ×0.5, as benchmarks/pushes.py), a 0.9375 N·s
    push sideways away from the swing foot at mid first single support (the bisection's
    probe above the open loop's 0.914): the closed loop before (no sway narrowing, no hold)
    falls ~0.7 s later; with the defaults (``Gains().sway``, ``HoldParams()``) it is up
    2.0 s into the walk."""
    from wbc.balance.stabilizer import Gains
    from wbc.bench.physics import PUSH_DURATION, ClosedLoopSpec, play_closed_loop
    from wbc.bench.solvers import select

    ref = build("walk10", robot)
    a, b, _ = next(p for p in ref.phases() if ref.stance_side(p[0]) is not None)
    t_push = 0.5 * (ref.t[a] + ref.t[b - 1]) - ref.t[0]
    side = 1.0 if ref.stance_side(a) == "left" else -1.0
    force = np.array([0.0, side * 0.9375 / PUSH_DURATION, 0.0])
    entry = next(e for e in select(["wqp-daqp"], None, "tick")[0] if e.name == "wqp-daqp")
    tilt = {}
    for name, spec in (
        ("before", ClosedLoopSpec(entry.make, ref, Gains(sway=0.0), True, True, None, None)),
        ("now", ClosedLoopSpec(entry.make, ref, Gains(), True, True)),
    ):
        result, loop = play_closed_loop(spec, robot, push=(t_push, force, PUSH_DURATION),
                                        settle=0.0, compensate=0.5, duration=2.0)  # fmt: skip
        R = pin.Quaternion(result.log["q"][-1, 3:7]).toRotationMatrix()
        tilt[name] = float(np.degrees(np.arccos(np.clip(R[2, 2], -1.0, 1.0))))
        if name == "now":
            assert loop.hold is not None and loop.hold.holds >= 1  # the lift-off waited
    assert tilt["before"] > 45.0  # fallen
    assert tilt["now"] < 40.0  # up
