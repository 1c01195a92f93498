"""The merged compiled calls around a tick (wbc.compiled.prelude): the configuration's check and
its joints' range in one call, and the warm sets forgotten in one call, each the same verdict
or the same arrays as the calls they replace."""

from __future__ import annotations

import numpy as np
import pytest

from wbc import Kinematics
from wbc.bench.trajectories import build
from wbc.compiled.checks import outside, quaternion_defect
from wbc.compiled.prelude import configuration_check, forget_sets, gather_forget
from wbc.stacks import load_stack
from wbc.walking.loop import Session, StackController


@pytest.mark.parametrize("seed", range(20))
def test_the_configuration_check_is_both_checks(robot, random_configuration, seed):
    lo, hi = robot.q_min, robot.q_max
    q = random_configuration(seed)
    q[3:7] *= 1.0 + (seed % 3) * 1e-3  # (a scaled quaternion: a defect)
    defect, out = configuration_check(q, lo, hi)
    assert (defect, out) == (quaternion_defect(q), outside(q, lo, hi))
    if seed % 5 and seed % 3 == 0:  # (a valid q: the Kinematics keeps the second)
        kin = Kinematics(robot, q)
        assert kin.outside == outside(q, lo, hi)


def test_the_solver_reads_the_kinematics_verdict_only_for_its_own_limits(robot):
    """A robot whose limits were re-assigned after the solver was built: the solver asks
    again with its own (the verdicts differ here), as before the merge."""
    controller = StackController(load_stack("walk", robot))
    solver = controller.solver
    q = robot.configuration("walk_ready").copy()
    solver.kin.update(q)
    assert solver._outside_kin() == solver._outside_limits(q) is False
    kept = robot.checked_limits
    try:
        robot.checked_limits = (kept[0] + 10.0, kept[1] + 20.0)  # every joint below
        solver.kin.update(q)
        assert solver.kin.outside is True
        assert solver._outside_kin() is False  # (its own limits: inside)
    finally:
        robot.checked_limits = kept


def test_forget_sets_is_the_fills_it_replaces():
    rng = np.random.default_rng(0)
    for upto in (0, 2, 5, 9):
        states = rng.integers(-1, 2, (5, 24)).astype(np.int8)
        working = rng.random((4, 60)) < 0.3
        expected = states.copy()
        expected[:upto] = 0
        forget_sets(states, upto, working)
        assert np.array_equal(states, expected) and not working.any()


def test_gather_forget_is_the_gather_then_the_fills():
    rng = np.random.default_rng(1)
    sources = [rng.random(3), rng.random(5), rng.random(1)]
    addresses = np.array([a.ctypes.data for a in sources], dtype=np.int64)
    sizes = np.array([a.size for a in sources], dtype=np.int64)
    for upto in (0, 2, 9):
        out = np.full(12, np.nan)
        states = rng.integers(-1, 2, (5, 24)).astype(np.int8)
        working = rng.random((4, 60)) < 0.3
        expected = states.copy()
        expected[:upto] = 0
        gather_forget(addresses, sizes, out, states, upto, working)
        assert np.array_equal(out[:9], np.concatenate(sources)) and np.isnan(out[9:]).all()
        assert np.array_equal(states, expected) and not working.any()


@pytest.mark.parametrize("stack", ["walk_strict", "walk"])
def test_a_walks_ticks_forget_what_they_forgot(robot, stack):
    """Along walk10 (inequality rows from self-collision, their counts changing from tick to
    tick): before each tick's solve the plan's warm sets are those of numpy's fills — every
    level's bounds' set above the damped level zero, the damped level's and the memo kept, no
    inequality row working — whatever the tick before left (the plans' arrays filled with
    garbage first)."""
    ref = build("walk10", robot)
    controller = StackController(load_stack(stack, robot))
    session = Session(controller, robot, ref)
    solver = controller.solver
    seen = gathers = 0
    for i in range(120):
        session.tick(i)
        plan = solver.fast
        if plan is None or i < 20:
            continue
        rng = np.random.default_rng(i)
        g = plan.inequalities
        kept = plan.states.copy(), g.working.copy()
        plan.states[:] = rng.integers(-1, 2, plan.states.shape)
        g.working[:] = rng.random(g.working.shape) < 0.5
        expected = plan.states.copy()
        expected[: plan.damped_level] = 0
        plan.forget_warm_start(keep_damped=True)
        assert np.array_equal(plan.states, expected) and not g.working.any()
        plan.states[:] = 1
        plan.forget_warm_start()
        assert not plan.states.any()
        rows = plan.constraints  # (its parameters gathered with the reset, as the tick does)
        if rows.gather_args() is not None:
            gathered = rows.cparams.copy()
            rows.cparams[:] = np.nan
            plan.forget_warm_start(keep_damped=True, rows=rows)
            assert np.array_equal(rows.cparams, gathered) and not g.working.any()
            gathers += 1
        plan.states[:], g.working[:] = kept  # (the walk goes on from its own sets)
        seen += g.total > 0
    assert seen > 50  # (ticks with inequality rows)
    assert gathers > 20  # (a layout with the ground clearance: single support)
