"""A support switch carried continuously (wbc.walking.handover, a stack's [support_switch])."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc.bench.trajectories import build
from wbc.exceptions import TaskError
from wbc.paths import read_toml, stacks_dir
from wbc.stacks import SupportSwitch, build_stack, load_stack
from wbc.walking.loop import Session, StackController, run


def _walk_spec() -> dict:
    return read_toml(stacks_dir() / "walk.toml", "task stack", TaskError)


def _switch_speed(robot, rec, ref) -> float:
    speed = np.abs(np.diff(rec.q[:, 7:], axis=0)) / ref.dt / robot.v_max
    switches = np.flatnonzero(np.diff(rec.channels["support"]))
    near = np.concatenate([np.arange(s - 1, min(s + 4, len(speed))) for s in switches])
    return float(speed[near].max())


def test_without_the_handover_every_switch_asks_the_full_servo_speed(robot):
    """The defect the walk stack's [support_switch] removes (benchmarks/balance.md): the same
    stack without the table takes static_walk's switches to the servo's full speed (1.00; the
    reference asks 0.54), with it they stay at half of it."""
    ref = build("static_walk", robot)
    spec = _walk_spec()
    assert spec["support_switch"] == {
        "posture_lag": 0.1,
        "landing_time": 0.1,
        "landing_band": 0.005,
        "brace": True,
    }
    without = {k: v for k, v in spec.items() if k != "support_switch"}
    rec = run(StackController(build_stack(without, robot)), robot, ref)
    assert _switch_speed(robot, rec, ref) > 0.95
    rec = run(StackController(build_stack(spec, robot)), robot, ref)
    assert _switch_speed(robot, rec, ref) < 0.6


@pytest.mark.parametrize("walk", ["walk10_wb", "fast_wb"])
def test_kokones_own_stack_asks_no_joint_for_more_than_its_speed_share(walk):
    """Kokone's stack (robots/kokone/stack.toml: its own [support_switch]) tracks its walks
    within the sized references' share of the BMS-380MAX's speed (0.8, wbc.walking.sizing) at
    every tick, switches included; without the table a knee reached 1.00 of it at walk10_wb's
    switches (benchmarks/kokone_sim.md section 000000; fast_wb's 0.98 there was at its sized
    32.8 mm steps: with its 22 mm steps, section 00000000, 0.44 without the table)."""
    from wbc.model import load_robot
    from wbc.stacks import robot_stack
    from wbc.walking.sizing import SPEED_FRACTION

    kokone = load_robot("kokone")
    ref = build(walk, kokone)
    path, _ = robot_stack(kokone, None)
    spec = read_toml(path, "task stack", TaskError)
    assert "support_switch" in spec
    rec = run(StackController(build_stack(spec, kokone)), kokone, ref)
    speed = np.abs(np.diff(rec.q[:, 7:], axis=0)) / ref.dt / kokone.v_max
    assert speed.max() < SPEED_FRACTION
    if walk == "walk10_wb":  # the table is what keeps it within the share
        without = {k: v for k, v in spec.items() if k != "support_switch"}
        rec = run(StackController(build_stack(without, kokone)), kokone, ref)
        assert _switch_speed(kokone, rec, ref) > 0.95


@pytest.mark.parametrize(("carry", "second"), [(True, False), (False, False), (True, True)])
def test_a_switch_moves_the_set_point_never_the_target(robot, carry, second):
    """At every tick a swinging leg's posture target moves (1 - e^(-dt/τ)) of the way to Walk
    Ready (``second_order_swing``: of the way to a middle stage that moves so toward Walk Ready
    from the target at the lift-off); a leg in contact carries its target with its joints, the
    offset decaying by e^(-dt/τ) a tick (``carry_contact_targets``), or (false) its target
    moves the same share of the way to its joints (a lag); continuous across a switch by
    construction; the arms' targets stay Walk Ready."""
    ref = build("static_walk", robot)
    spec = _walk_spec()
    spec["support_switch"] = {
        **spec["support_switch"],
        "carry_contact_targets": carry,
        "second_order_swing": second,
    }
    control = build_stack(spec, robot)
    assert control.support_switch.carry_contact_targets is carry
    assert control.support_switch.second_order_swing is second
    posture = control.stack.task("posture")
    session = Session(StackController(control), robot, ref)
    handover = session.controller.handover
    walk_ready = posture.target.copy()
    legs = {f: handover._joints[handover._sides == k] for k, f in enumerate(("l_sole", "r_sole"))}
    arms = np.setdiff1d(np.arange(robot.n_joints), np.concatenate(list(legs.values())))
    a = 1.0 - math.exp(-ref.dt / 0.1)
    held = session.q[7:].copy()  # the joints at the last tick (the first: its own)
    mid: dict[str, np.ndarray | None] = {f: None for f in legs}  # the middle stage
    swung = 0
    for i in range(ref.n):
        before, q = posture.target.copy(), session.q[7:].copy()
        session.tick(i)
        t = session.targets(i)
        for frame, idx in legs.items():
            if t.phase == "single" and frame == t.swing and second:
                start = before[idx] if mid[frame] is None else mid[frame]
                mid[frame] = start + a * (walk_ready[idx] - start)
                expected = before[idx] + a * (mid[frame] - before[idx])
                swung += 1
            elif t.phase == "single" and frame == t.swing:
                expected = before[idx] + a * (walk_ready[idx] - before[idx])
            elif carry:
                expected = q[idx] + (1.0 - a) * (before[idx] - held[idx])
            else:
                expected = before[idx] + a * (q[idx] - before[idx])
            if not (t.phase == "single" and frame == t.swing):
                mid[frame] = None
            np.testing.assert_allclose(posture.target[idx], expected, atol=1e-12)
        assert np.array_equal(posture.target[arms], walk_ready[arms])
        held = q
    assert swung > 0 or not second


def test_a_landing_contact_is_anchored_where_the_sole_touches_down(robot):
    """At a touch-down the new contact holds the sole where it is (one share dt / T of the
    way toward the reference placement), reaches the reference in ``landing_time``; the hard
    row meets the anchor each tick."""
    ref = build("static_walk", robot)
    control = load_stack("walk", robot)
    session = Session(StackController(control), robot, ref)
    settings = control.support_switch
    ticks = round(settings.landing_time / ref.dt)
    seen = 0
    for i in range(ref.n):
        t = session.targets(i)
        prev = session.targets(i - 1) if i else t
        q = session.q.copy()
        session.tick(i)
        if t.phase == "double" and prev.phase == "single":
            frame = prev.swing
            sole = robot.frame_placement(q, frame).translation
            goal = (t.l_sole if frame == "l_sole" else t.r_sole).translation
            contact = next(c for c in control.stack.tasks() if c.active and c.frame == frame)
            miss = np.linalg.norm(goal - sole)
            assert 1e-3 < miss < settings.landing_band  # the swing ended off its target
            expected = sole + (goal - sole) / ticks
            np.testing.assert_allclose(contact.target_position, expected, atol=1e-12)
            landed = robot.frame_placement(session.q, frame).translation
            assert np.linalg.norm(landed - contact.target_position) < 1e-5
            for k in range(i + 1, i + ticks):
                session.tick(k)
            np.testing.assert_allclose(contact.target_position, goal, atol=1e-12)
            seen += 1
            if seen == 3:
                break
    assert seen == 3


def test_a_catch_step_miss_beyond_the_band_is_asked_at_once(robot):
    """A touch-down 25 mm off its reference placement (a push's catch step) anchors the
    contact ``landing_band`` from the reference, not where the sole is."""
    from types import SimpleNamespace

    import pinocchio as pin

    control = load_stack("walk", robot)
    handover = StackController(control).handover
    handover.start()
    q = start = robot.configuration("stand")
    sole = robot.frame_placement(start, "l_sole")
    goal = pin.SE3(sole.rotation, sole.translation + np.array([0.0, 0.025, 0.0]))
    handover._swing = "l_sole"
    t = SimpleNamespace(phase="double", swing="r_sole", l_sole=goal, r_sole=goal)
    t.sole = lambda frame: t.l_sole if frame == "l_sole" else t.r_sole  # (TickTargets.sole)
    anchor = handover._touch_down(q, t)
    band = control.support_switch.landing_band
    assert np.linalg.norm(anchor.translation - goal.translation) == pytest.approx(band)
    assert np.linalg.norm(anchor.translation - sole.translation) == pytest.approx(0.025 - band)


def _missed_landing(robot, table: dict):
    """The walk stack with ``[support_switch]`` ``table`` along static_walk to its first
    landing, and that landing's targets moved 50 mm and 0.4 rad off the reference (a catch's
    miss): (controller, control, ref, land, q, frame, sole at q, goal, targets, moved)."""
    import pinocchio as pin

    ref = build("static_walk", robot)
    s = ref.support
    land = int(np.flatnonzero((s[1:] == 0) & (s[:-1] != 0))[0]) + 1
    spec = _walk_spec()
    control = build_stack({**spec, "support_switch": {**spec["support_switch"], **table}}, robot)
    controller = StackController(control)
    session = Session(controller, robot, ref)
    for i in range(land):
        session.tick(i)
    frame = session.targets(land - 1).swing
    q = session.q.copy()
    sole = robot.frame_placement(q, frame)
    t = session.targets(land)
    turn = pin.exp3(np.array([0.0, 0.4, 0.0]))
    goal = pin.SE3(t.sole(frame).rotation @ turn,
                   t.sole(frame).translation + np.array([0.05, 0.0, 0.0]))  # fmt: skip
    return controller, control, ref, land, q, frame, sole, goal, t, t.replace(**{frame: goal})


def test_a_landing_the_hard_row_cannot_meet_falls_back_to_the_sole(robot):
    """A touch-down 50 mm and 0.4 rad off its reference (a catch's miss, more than the servos
    move in a tick): the tick fails without ``landing_fallback`` and ``brace`` (the controller
    holds its last configuration); with it the landing is re-anchored where the sole is, one share
    ``dt / landing_time`` of the way to the reference this tick, the tick solves, the hard row
    meets the anchor, the fallback is counted, and the later ticks walk the rest (at the
    reference after ``landing_time``, failing again only to fall back again)."""
    from wbc.exceptions import InfeasibleError

    answers = {}
    for fallback in (False, True):
        table = {"landing_fallback": fallback, "brace": False}
        controller, control, ref, land, q, frame, sole, goal, t, moved = _missed_landing(
            robot, table
        )
        if not fallback:
            with pytest.raises(InfeasibleError, match="contact"):
                controller.track(q, moved, ref.dt, True)
            assert controller.handover.fallbacks == 0
            continue
        q_next = controller.track(q, moved, ref.dt, True)
        handover = controller.handover
        assert handover.fallbacks == 1
        share = ref.dt / control.support_switch.landing_time
        contact = next(c for c in control.stack.tasks() if c.active and c.frame == frame)
        expected = sole.translation + share * (goal.translation - sole.translation)
        np.testing.assert_allclose(contact.target_position, expected, atol=1e-12)
        landed = robot.frame_placement(q_next, frame)  # (first order: a 5 mm, 0.04 rad share)
        assert np.linalg.norm(landed.translation - contact.target_position) < 5e-4
        for k in range(land + 1, land + 40):
            q_next = controller.track(q_next, t.replace(i=k, **{frame: goal}), ref.dt, False)
        answers[fallback] = robot.frame_placement(q_next, frame)
        np.testing.assert_allclose(answers[True].translation, goal.translation, atol=1e-4)
        assert handover.fallbacks >= 1


@pytest.mark.parametrize("speed", [None, 0.1])
def test_a_landing_the_hard_row_cannot_meet_is_braced_where_it_stands(robot, speed):
    """``brace`` (issue 30): the touch-down 50 mm and 0.4 rad off its reference that fails
    without it (the test above) is solved braced: the landed contact anchored where the sole
    is (with ``brace_speed`` one step of speed·dt toward the landing's anchor), the other
    contact, the CoM, torso and posture targets where they are: the solve holds the pose (the
    landed sole where it was, the CoM within 1 mm, no joint moving 1e-3 rad), counted; the
    targets are put back after it (the next tick tries the landing again, braced again)."""
    table = {"brace": True} | ({"brace_speed": speed} if speed else {})
    controller, control, ref, _, q, frame, sole, _, _, moved = _missed_landing(robot, table)
    q_next = controller.track(q, moved, ref.dt, True)  # (raises without the brace: above)
    handover = controller.handover
    assert handover.braced == 1 and handover.fallbacks == 0
    contact = next(c for c in control.stack.tasks() if c.active and c.frame == frame)
    anchor = contact.target_position.copy()  # (the landing's, put back)
    assert np.linalg.norm(anchor - sole.translation) > 0.04
    com = next(c for c in control.stack.tasks() if type(c).__name__ == "ComTask")
    np.testing.assert_array_equal(com.target, moved.com)
    step = 0.0 if speed is None else speed * ref.dt
    landed = robot.frame_placement(q_next, frame).translation
    assert abs(np.linalg.norm(landed - sole.translation) - step) < 1e-4
    if speed:  # (toward the landing's anchor)
        assert np.linalg.norm(landed - anchor) < np.linalg.norm(sole.translation - anchor)
    assert np.linalg.norm(robot.com(q_next) - robot.com(q)) < 1e-3
    # the pose held (every target at q: no joint moves 1e-3 rad), or moved by the anchor's step
    assert np.max(np.abs(q_next[7:] - q[7:])) < (1e-3 if speed is None else 0.03)
    controller.track(q_next, moved, ref.dt, False)  # (the lift-off hold's replay of the tick)
    assert handover.braced == 2


def test_the_support_switch_table_is_checked_and_scaled():
    """Positive numbers only, known keys only, one line naming the key; a robot λ times the
    design leg gets both values times √λ."""
    from wbc.model import load_robot

    kokone = load_robot("kokone")
    spec = _walk_spec()
    for bad, match in (
        ({"posture_lag": 0}, r"support_switch\.posture_lag must be a positive number"),
        ({"landing_time": True}, r"support_switch\.landing_time must be a positive number"),
        ({"lag": 0.1}, r"support_switch has unknown keys \['lag'\]"),
        ({"carry_contact_targets": 1}, r"carry_contact_targets must be true or false"),
        (0.1, "support_switch must be a table"),
    ):
        with pytest.raises(TaskError, match=match):
            build_stack({**spec, "support_switch": bad}, kokone)
    from wbc.stacks import _stack_length_unit

    unit = _stack_length_unit(spec["design_leg"], kokone, "")
    got = build_stack(spec, kokone).support_switch
    root = math.sqrt(unit)
    assert got == SupportSwitch(0.1 * root, 0.1 * root, 0.005 * unit, brace=True)
    assert build_stack({k: v for k, v in spec.items() if k != "support_switch"}, kokone)


def test_a_landing_is_made_in_the_idle_part_before_its_ticks(robot):
    """With the support switch made ahead (Session.prepare_next), a landing's work is made
    there too (SwitchHandover.prepare: at the touch-down where the sole is, a forward
    kinematics pass, then each tick's share of the way, an SE(3) log and exp): no tick of
    the landing computes it, each takes what was made ahead — the same answers as a walk
    that makes nothing ahead, and as one whose touch-down tick gets another q object (then
    the touch-down is made in its tick, the landing's next shares ahead)."""
    ref = build("walk10", robot)
    s = ref.support
    land = int(np.flatnonzero((s[1:] == 0) & (s[:-1] != 0))[0]) + 1
    answers = []
    for ahead, other_q in ((True, False), (True, True), (False, False)):
        controller = StackController(load_stack("walk", robot))
        handover = controller.handover
        track, ticking = controller.track, [False]
        inside: dict[str, list[bool]] = {"_touch_down": [], "_step": []}

        def counted(name, f, ticking=ticking, inside=inside):
            def call(*a):
                inside[name].append(ticking[0])
                return f(*a)

            return call

        def tick(*a, track=track, ticking=ticking):
            ticking[0] = True
            try:
                return track(*a)
            finally:
                ticking[0] = False

        for name in inside:
            setattr(handover, name, counted(name, getattr(handover, name)))
        controller.track = tick
        session = Session(controller, robot, ref)
        qs = []
        for i in range(land + 15):
            qs.append(session.tick(i).copy())
            if ahead:
                session.prepare_next()
            if other_q and i == land - 1:
                session.q = session.q.copy()  # (the same values: not the q it was made for)
        answers.append(np.array(qs))
        steps = inside["_step"]
        assert len(steps) >= 5 + ahead and inside["_touch_down"].count(False) == ahead
        assert inside["_touch_down"].count(True) == (other_q or not ahead)
        assert steps.count(True) == (len(steps) if not ahead else 1 if other_q else 0), steps
    assert np.array_equal(answers[0], answers[1]) and np.array_equal(answers[0], answers[2])


@pytest.mark.parametrize("second", [False, True])
def test_a_freed_legs_lag_is_fitted_to_its_servos_speed(robot, second):
    """At a lift-off the freed leg's share per tick toward Walk Ready is the table's
    ``a = 1 - e^(-dt/τ)`` while its first step ``a·gap`` asks no joint for more than the sized
    share (0.8) of its no-load speed in ``dt`` (``second_order_swing``: the two lags' peak,
    ~1/e of it); a larger gap gets a smaller share (a longer lag), never a larger one; the
    table's ``fit_speed = false`` keeps ``a``."""
    from wbc.walking.sizing import SPEED_FRACTION

    ref = build("static_walk", robot)
    spec = _walk_spec()
    spec["support_switch"] = {**spec["support_switch"], "second_order_swing": second}
    control = build_stack(spec, robot)
    handover = Session(StackController(control), robot, ref).controller.handover
    posture = control.stack.task("posture")
    walk_ready = posture.target.copy()
    dt, peak = ref.dt, math.e if second else 1.0
    a = 1.0 - math.exp(-dt / 0.1)
    left = handover._joints[handover._sides == 0]
    assert handover.swing_share(0, a, dt) == a  # at Walk Ready: nothing to absorb
    for gap in (0.05, 0.5, 1.5):
        posture.target[left] = walk_ready[left] + gap
        share = handover.swing_share(0, a, dt)
        asked = share * gap / dt / robot.v_max[left] / peak
        assert share <= a and asked.max() <= SPEED_FRACTION + 1e-12
        assert share == a or math.isclose(asked.max(), SPEED_FRACTION)
    assert share < a  # 1.5 rad in one lag of 0.1 s: beyond any servo here
    handover.fit_speed = False
    assert handover.swing_share(0, a, dt) == a


def test_the_swing_gap_kernel_is_the_numpy_form():
    """``swing_gap`` (one compiled call at a lift-off) gives the numpy form's gap bit for
    bit: the largest |walk_ready − target| / speed over the joints of one side, 0 with none
    of that side; NaN where a term is (Python's max then keeps the gap before it)."""
    from wbc.walking.handover import swing_gap

    rng = np.random.default_rng(0)
    for trial in range(200):
        n, k = 20, int(rng.integers(0, 13))
        joints = rng.choice(n, size=k, replace=False).astype(np.int64)
        sides = rng.integers(0, 2, k).astype(np.int64)
        speed = rng.uniform(0.5, 8.0, k)
        target, walk_ready = rng.normal(size=n), rng.normal(size=n)
        if trial % 17 == 0 and k:
            target[joints[0]] = np.nan
        for side in (0, 1):
            legs = sides == side
            share = np.abs(walk_ready[joints[legs]] - target[joints[legs]]) / speed[legs]
            expected = max(0.0, float(share.max(initial=0.0)))
            got = max(0.0, swing_gap(target, walk_ready, joints, sides, speed, side))
            assert got == expected


def test_closed_loop_figures_read_the_controllers_handover_and_relaxing(robot):
    """``closed_loop_figures`` reads any controller's ``handover`` and ``relaxes`` (the
    :class:`~wbc.walking.controller.Controller` defaults: None, False): the walk stack's
    handover counts (its brace on, no fallback) and the relaxed solves only where the solver
    relaxes; a pseudo-inverse controller has neither."""
    from types import SimpleNamespace

    from wbc.bench.closed_loop import closed_loop_figures
    from wbc.bench.solvers import PinvController

    def figures(controller):
        source = SimpleNamespace(cost_share=lambda: 0.5, limit_excess=0.0, failed_ticks=2,
                                 relaxed_ticks=3)  # fmt: skip
        loop = SimpleNamespace(source=source, session=SimpleNamespace(controller=controller),
                               stabilizer=SimpleNamespace(max_tilt_error=0.0), stepping=None,
                               hold=None)  # fmt: skip
        return closed_loop_figures(loop)

    relaxing = StackController(load_stack("walk", robot, on_infeasible="relax"))
    assert relaxing.relaxes and relaxing.handover is not None
    relaxing.handover.braced = 4
    out = figures(relaxing)
    assert (out["braced_ticks"], out["relaxed_solves"]) == (4, 3)
    assert "landing_fallbacks" not in out
    walk = StackController(load_stack("walk", robot))
    assert not walk.relaxes and "relaxed_solves" not in figures(walk)
    pinv = PinvController("vat")
    assert pinv.handover is None and not pinv.relaxes
    out = figures(pinv)
    assert not {"braced_ticks", "relaxed_solves", "landing_fallbacks"} & set(out)
    assert out["failed_solves"] == 2


def test_the_braced_posture_tasks_are_the_lagged_ones(robot):
    """One list of the stack's posture tasks: a braced tick sets them all (``_posed``); with
    a ``posture_lag`` the same tasks follow the legs (``_postures``), without one none."""
    spec = _walk_spec()
    handover = StackController(build_stack(spec, robot)).handover
    assert handover._posed and handover._postures == handover._posed
    spec["support_switch"] = {k: v for k, v in spec["support_switch"].items() if k != "posture_lag"}
    unlagged = StackController(build_stack(spec, robot)).handover
    assert unlagged._posed and unlagged._postures == []


@pytest.mark.parametrize("change", ["none", "nudged q", "skipped tick"])
def test_a_landing_anchor_placed_ahead_is_the_ticks_own_or_rewritten(robot, change):
    """The landing's anchor made ahead is written into its contact in the idle part
    (SwitchHandover.place_ahead, so that the idle part's rehearsals solve the tick's own
    contact target): at the touch-down and on the landing's way the contacts hold, before
    each tick, the targets the tick then sets (a walk without the idle part moves them in the
    tick). Where the tick is not the one prepared — its q nudged after the idle part (the
    touch-down made in the tick), or the prepared tick skipped (the switch made ahead taken
    back) — the tick writes its own: every walk bit for bit the one without the idle part."""
    ref = build("walk10", robot)
    s = ref.support
    land = int(np.flatnonzero((s[1:] == 0) & (s[:-1] != 0))[0]) + 1
    runs = []
    for idle in (False, True):
        controller = StackController(load_stack("walk", robot))
        contacts = controller.handover._contacts
        session = Session(controller, robot, ref)
        qs, moved = [], []
        for i in range(land + 8):
            if change == "skipped tick" and i == land:
                continue
            before = [t.target_packed.copy() for t in contacts]
            qs.append(session.tick(i).copy())
            assert not session.failed
            if land <= i < land + 6:
                after = [t.target_packed for t in contacts]
                moved.append(not all(map(np.array_equal, before, after)))
            if idle:
                session.prepare_next()
                session.warm_next()
            if change == "nudged q" and i == land - 1:
                session.q = session.q.copy()
                session.q[7:] += 1e-5  # (after the idle part: not the q it was made for)
        runs.append((np.array(qs), moved))
    (without, moved_in_tick), (with_idle, moved_ahead) = runs
    assert all(moved_in_tick), moved_in_tick
    # (the tick made its own; after the skip the idle part prepares the last tick plus a gap
    # of 2, and the next tick played is 1 on: made in the tick once more)
    made_in_tick = {"none": 0, "nudged q": 1, "skipped tick": 2}[change]
    assert all(moved_ahead[:made_in_tick]) and not any(moved_ahead[made_in_tick:]), moved_ahead
    assert np.array_equal(without, with_idle)
