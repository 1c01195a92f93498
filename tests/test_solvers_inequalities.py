"""The constraints of a compiled plan (wbc.solvers.inequalities): the tick calls the constraint
kernels itself, and their rows land where the numpy path stacks them, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from test_solvers import walking_stack

from wbc import Kinematics
from wbc.compiled import dispatch as D
from wbc.limits import GroundClearanceConstraint, LinearInequality
from wbc.solvers import HierarchicalQP, WeightedQP
from wbc.solvers.assembly import stack_constraints

SOLVERS = {"weighted": WeightedQP, "hierarchical": HierarchicalQP}


def _stack(robot, q):
    stack = walking_stack(robot, q, polygon=True, lift=0.01)
    stack.add_constraint(GroundClearanceConstraint(robot, "r_sole", clearance=0.005), level=0)
    G = np.zeros((1, robot.nv))
    G[0, 8] = 1.0
    stack.add_constraint(LinearInequality(G, np.array([0.01]), name="cap"), level=1)
    return stack


def _expected(solver, kin):
    """Each level's (G, h) as the numpy path stacks them."""
    levels = solver.stack.levels
    if isinstance(solver, WeightedQP):
        cons = [[c for lv in levels for c in lv.active_constraints()]]
    else:
        cons = [lv.active_constraints() for lv in levels]
    return [stack_constraints(c, kin, solver.robot.nv)[:2] for c in cons]


@pytest.mark.parametrize("kind", sorted(SOLVERS))
def test_the_tick_writes_the_constraint_rows(robot, kind):
    """The kernel constraints' rows are written by the compiled tick (rows in ``cspec``), the
    others copied, in their place; after a support switch (the polygon's row count changes)
    and a swing switch (the clearance's frame) the layout follows."""
    q = robot.configuration("walk_ready")
    solver = SOLVERS[kind](_stack(robot, q), compiled=True)
    clearance = solver.stack.constraint("ground_clearance_r_sole")
    polygon = solver.stack.constraint("com_polygon")
    counts = []
    for step in range(3):
        if step == 1:
            polygon.foot = (polygon.foot[0], 0.3)  # (a sole wide enough for the CoM)
            polygon.set_support(["l_sole"])  # a rectangle: another row count
        if step == 2:
            clearance.set_frame("l_sole")  # (the stance sole: 1 cm below it may go)
            clearance.clearance = -0.01
        dq = solver.solve(q, 0.01)
        assert solver.compiled_ticks == step + 1 and solver.handed_back_ticks == 0
        plan = solver.fast
        cspec = plan.constraints.cspec
        assert cspec.shape[0] == 2 and np.all(cspec[:, D.C_ROWS] > 0)  # both in the tick
        g = plan.inequalities
        kin = Kinematics(robot, q)
        for k, (G, h) in enumerate(_expected(solver, kin)):
            g0, g1 = g.g_rows[k], g.g_rows[k + 1]
            assert np.array_equal(g.G[g0:g1], G) and np.array_equal(g.h[g0:g1], h)
        counts.append(polygon.rows)
        numpy_solver = SOLVERS[kind](solver.stack, compiled=False)
        assert np.abs(numpy_solver.solve(q, 0.01) - dq).max() < 1e-9
    assert counts[1] != counts[0]  # (the one-sole polygon has other edges)


class _OwnClearance(GroundClearanceConstraint):
    """A subclass: it does not inherit the layout token (its plan checks by value)."""


@pytest.mark.parametrize("cls", [GroundClearanceConstraint, _OwnClearance])
def test_a_swing_sole_alternating_lays_the_rows_out_again(robot, cls):
    """The clearance's frame alternating (a walk's swing sole) re-lays its rows out each time
    (its layout token, one per frame; a subclass's rows checked by value) and the tick's rows
    are the numpy path's, bit for bit; the same frame again is the same token."""
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q, polygon=False, lift=0.01)
    clearance = cls(robot, "r_sole", clearance=-0.01)
    stack.add_constraint(clearance, level=0)
    solver = HierarchicalQP(stack, compiled=True)
    rows = solver.fast.constraints if solver.fast is not None else None
    tokens = []
    for frame in ("r_sole", "l_sole", "r_sole", "l_sole", "l_sole"):
        clearance.set_frame(frame)
        tokens.append(clearance.layout_token)
        solver.solve(q, 0.01)
        assert solver.compiled_ticks > 0 and solver.handed_back_ticks == 0
        plan = solver.fast
        rows = plan.constraints
        assert rows._tokened == [cls is GroundClearanceConstraint]
        g = plan.inequalities
        (G, h) = _expected(solver, Kinematics(robot, q))[0]
        assert np.array_equal(g.G[g.g_rows[0] : g.g_rows[1]], G)
        assert np.array_equal(g.h[g.g_rows[0] : g.g_rows[1]], h)
        slot = rows.cslots[rows.cspec[0, D.C_SLOT]]
        assert slot == rows.slot[clearance.frame_id]
    assert tokens[0] is tokens[2] and tokens[1] is tokens[3] is tokens[4]
    assert tokens[0] is not tokens[1]
