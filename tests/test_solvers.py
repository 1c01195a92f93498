"""Weighted and hierarchical QP solvers: laws that must hold for any configuration/target."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from proxsuite import proxqp

from wbc import ConfigurationError, InfeasibleError, Kinematics, TaskError
from wbc.limits import ComPolygonConstraint
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.solvers.backends import make_backend
from wbc.solvers.cascade import solve_cascade_or_daqp
from wbc.tasks import (
    ComTask,
    ContactTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
)

BACKENDS = ["daqp", "proxqp", "quadprog", "osqp"]


def walking_stack(
    robot, q, rng=None, com_shift=(0.0, 0.0, 0.0), lift=0.0, polygon=False, velocity_limits=True
):
    """Contact (hard), swing foot 6-D + CoM, torso + posture: the walking stack."""
    stack = TaskStack(robot, velocity_limits=velocity_limits)
    kin = Kinematics(robot, q)
    contact = stack.add(ContactTask(robot, "l_sole"), level=0, hard=True)
    contact.make_contact(kin)
    swing = stack.add(FramePoseTask(robot, "r_sole", name="swing"), level=1, weight=10.0)
    swing.set_target_from(kin)
    swing.set_position_target(swing.target_position + [0.0, 0.0, lift])
    com = stack.add(ComTask(robot), level=1, weight=100.0)
    com.set_target(kin.com + np.asarray(com_shift))
    torso = stack.add(FrameOrientationTask(robot, "torso", name="torso"), level=2)
    torso.set_target_from(kin)
    stack.add(PostureTask(robot, robot.configuration("walk_ready")), level=2, weight=1e-2)
    if polygon:
        stack.add_constraint(
            ComPolygonConstraint(robot, ["l_sole", "r_sole"], margin=0.02), level=1
        )
    return stack


def random_start(robot, seed, outside=0.0):
    """Walk Ready with joint noise; with ``outside`` > 0 some joints start outside limits."""
    rng = np.random.default_rng(seed)
    q = robot.configuration("walk_ready")
    q[7:] += rng.uniform(-0.05, 0.05, robot.n_joints)
    q[7:] = np.clip(q[7:], robot.q_min, robot.q_max)
    if outside:
        idx = rng.choice(robot.n_joints, 3, replace=False)
        for i in idx:
            q[7 + i] = robot.q_max[i] + outside if rng.random() < 0.5 else robot.q_min[i] - outside
    return robot.place_on_ground(q, "l_sole"), rng


targets = st.tuples(st.floats(-0.03, 0.03), st.floats(-0.03, 0.03), st.floats(-0.02, 0.01))


# ---------------------------------------------------------------------------- limits
@given(
    seed=st.integers(0, 10_000), shift=targets, lift=st.floats(0, 0.04), hierarchical=st.booleans()
)
def test_joint_limits_never_violated(robot, seed, shift, lift, hierarchical):
    q, _ = random_start(robot, seed)
    stack = walking_stack(robot, q, com_shift=shift, lift=lift)
    solver = (HierarchicalQP if hierarchical else WeightedQP)(stack, "daqp")
    for _ in range(3):
        # the QP's own answer (step() then clips onto the limits, which would hide a miss)
        dq = solver.solve(q, dt=0.01)
        joints = q[7:] + dq[6:]
        assert np.all(joints >= robot.q_min - 1e-9) and np.all(joints <= robot.q_max + 1e-9)
        # velocity limits: |Δq_j| <= v_max dt
        assert np.all(np.abs(dq[6:]) <= robot.v_max * 0.01 + 1e-9)
        q = solver.step(q, dt=0.01)
    solver.solve_pose(q, max_iterations=30)
    # its last QP's answer within that solve's box (the joint limits; solve_pose then clips
    # the pose onto them, which would hide a miss)
    last = solver.last
    assert np.all(last.dq >= last.lower - 1e-9) and np.all(last.dq <= last.upper + 1e-9)


@given(seed=st.integers(0, 10_000), outside=st.floats(0.001, 0.2), hierarchical=st.booleans())
def test_start_outside_limits_moves_back_inside(robot, seed, outside, hierarchical):
    """Servo readings can sit outside the URDF limits: the QP must not fail (pink #206)."""
    q, _ = random_start(robot, seed, outside=outside)
    stack = walking_stack(robot, q)
    solver = (HierarchicalQP if hierarchical else WeightedQP)(stack, "daqp")
    dt = 0.01
    step = robot.v_max * dt
    before = np.maximum(robot.q_min - q[7:], 0) + np.maximum(q[7:] - robot.q_max, 0)
    q_next = solver.step(q, dt)
    after = np.maximum(robot.q_min - q_next[7:], 0) + np.maximum(q_next[7:] - robot.q_max, 0)
    # outside joints come back by a full servo step (or all the way in); none goes out
    assert np.all(after <= np.maximum(before - step, 0) + 1e-9)


# ---------------------------------------------------------------------------- weighted QP law
@given(seed=st.integers(0, 10_000), shift=targets)
def test_weighted_qp_without_active_bound_is_weighted_damped_least_squares(robot, seed, shift):
    q, _ = random_start(robot, seed)
    stack = TaskStack(robot)  # soft tasks only
    kin = Kinematics(robot, q)
    com = stack.add(ComTask(robot, kin.com + 0.1 * np.asarray(shift)), level=0, weight=3.0)
    foot = stack.add(FramePositionTask(robot, "r_sole"), level=0, weight=[1.0, 2.0, 0.5])
    foot.set_target(kin.placement(robot.frame_id("r_sole")).translation + 0.1 * np.asarray(shift))
    post = stack.add(PostureTask(robot, q, gain=0.5), level=1, weight=1e-2)
    mu = 1e-3
    solver = WeightedQP(stack, "daqp", regularization=mu)
    dq = solver.solve(q)  # no time step: position limits only, far from active here
    assert robot.within_limits(robot.integrate(q, dq), tol=-1e-6)
    H = mu * np.eye(robot.nv)
    g = np.zeros(robot.nv)
    for task in (com, foot, post):
        J, e = task.compute(kin)
        W = np.diag(task.weight)
        H += J.T @ W @ J
        g += J.T @ W @ (task.gain * e)
    assert np.allclose(dq, np.linalg.solve(H, g), atol=1e-9)


# ---------------------------------------------------------------------------- backends agree
@given(seed=st.integers(0, 10_000), shift=targets, lift=st.floats(0, 0.03), polygon=st.booleans())
def test_all_backends_agree_on_the_weighted_qp(robot, seed, shift, lift, polygon):
    q, _ = random_start(robot, seed)
    results = {}
    for backend in BACKENDS:
        stack = walking_stack(robot, q, com_shift=shift, lift=lift, polygon=polygon)
        results[backend] = WeightedQP(stack, backend).solve(q, dt=0.01)
    for backend in BACKENDS[1:]:
        assert np.allclose(results[backend], results["daqp"], atol=1e-6), backend


@given(seed=st.integers(0, 10_000), shift=targets, lift=st.floats(0, 0.03), polygon=st.booleans())
@example(seed=0, shift=(0.0, 0.0, 2.0**-9), lift=0.0, polygon=True)
@example(seed=8, shift=(0.0, 0.0, 2.0**-9), lift=0.0, polygon=True)
def test_backends_agree_on_the_hierarchical_qp(robot, seed, shift, lift, polygon):
    """The backends' cascade (:func:`wbc.solvers.cascade.solve_cascade_or_daqp`: what a
    hierarchy runs on a tick the kernels' level algorithm cannot finish, DAQP's again where
    another backend fails a level), each backend on the same levels and box. (A
    HierarchicalQP solves every tick with the kernels' level algorithm whatever its backend:
    comparing solvers built on different backends compared that algorithm with itself,
    bitwise.) The examples: ProxQP reported a level "solved" at a duality gap of 4e-3, Δq
    0.12 rad off (seed 0); the compiled DAQP and the numpy quadprog differed by 1e-3 (seed 8).

    The active-set solvers (DAQP, quadprog) agree to 1e-6 and ProxQP to 1e-4. OSQP (ADMM,
    eps 1e-6) meets each level's optimum to its tolerance, but not Δq: its polishing fails on
    the degenerate lower levels of a hierarchy (many active bounds), and a bound met to 1e-6
    instead of exactly moves Δq by up to ~1e-2 along the nearly flat directions of the last
    level. So for OSQP the test compares what ADMM guarantees: every level's residual (1e-4,
    lexicographically: a level above met less well may leave a level below a better residual)
    and the bounds (1e-5). It may also stop at its iteration limit there (DAQP's cascade
    then answers, never a silently wrong answer)."""
    q, _ = random_start(robot, seed)
    stack = walking_stack(robot, q, com_shift=shift, lift=lift, polygon=polygon)
    solver = HierarchicalQP(stack, "daqp", compiled=False)
    solver.solve(q, dt=0.01)  # (its levels and box at q)
    problems, lower, upper = solver.problems, solver.last.lower, solver.last.upper
    results, residuals = {}, {}
    for backend in BACKENDS:
        backends = [make_backend(backend) for _ in range(len(problems) + 1)]
        results[backend], levels = solve_cascade_or_daqp(
            problems, lower.copy(), upper.copy(), backends, final_regularization=1e-6
        )
        residuals[backend] = [np.linalg.norm(s.residual) for s in levels]
        assert np.all(results[backend] >= lower - 1e-5) and np.all(results[backend] <= upper + 1e-5)
    assert np.allclose(results["quadprog"], results["daqp"], atol=1e-6)
    assert np.allclose(results["proxqp"], results["daqp"], atol=1e-4)
    if "osqp" in results:  # lexicographic: never worse than ADMM's accuracy on any level, and
        # better on a level only by giving up some of a level above (within that accuracy)
        osqp, daqp = residuals["osqp"], residuals["daqp"]
        for k in range(len(daqp)):
            assert osqp[k] <= daqp[k] + 1e-4, (k, osqp, daqp)
            if osqp[k] < daqp[k] - 1e-4:
                assert any(osqp[j] > daqp[j] + 1e-9 for j in range(k)), (k, osqp, daqp)


# ---------------------------------------------------------------------------- hierarchy laws
def _level_alone_residual(problems, k, dq_star, lower, upper):
    """min ‖J_k Δq − b_k‖² s.t. J_j Δq = J_j Δq* (j < k), G_j Δq <= h_j + s_j*, bounds —
    solved directly over Δq with explicit equalities (an independent formulation)."""
    nv = lower.size
    J, b = problems[k].J, problems[k].b
    A = np.vstack([p.J for p in problems[:k]] or [np.zeros((0, nv))])
    beq = A @ dq_star
    G = np.vstack([p.G for p in problems[: k + 1]] or [np.zeros((0, nv))])
    h = np.concatenate([p.h for p in problems[: k + 1]] or [np.zeros(0)])
    # higher levels' inequalities keep the slack they needed; level k's own are soft: give
    # them the slack at the cascade's optimum (the ε-regularised ‖s‖² is part of its cost)
    h = np.maximum(h, G @ dq_star)
    tol = 1e-12
    qp = proxqp.dense.QP(nv, A.shape[0], G.shape[0], True)
    qp.settings.eps_abs = 1e-12
    qp.settings.eps_rel = 0.0
    qp.settings.eps_primal_inf = 1e-14
    qp.settings.max_iter = 100_000
    qp.init(
        J.T @ J + 1e-12 * np.eye(nv),
        -(J.T @ b),
        A,
        beq,
        G,
        np.full(len(h), -1e20),
        h + tol,
        lower - tol,
        upper + tol,
    )
    qp.solve()
    assert qp.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
    return np.linalg.norm(J @ qp.results.x - b)


@given(seed=st.integers(0, 10_000), shift=targets, lift=st.floats(0, 0.03), polygon=st.booleans())
def test_each_level_optimal_given_the_levels_above(robot, seed, shift, lift, polygon):
    q, _ = random_start(robot, seed)
    stack = walking_stack(robot, q, com_shift=shift, lift=lift, polygon=polygon)
    solver = HierarchicalQP(stack, "daqp", regularization=1e-12)
    dq = solver.solve(q, dt=0.01)
    problems, sols = solver.problems, solver.solutions
    lower, upper = np.full(robot.nv, -np.inf), np.full(robot.nv, np.inf)
    solver.compute_bounds(solver.kin, 0.01, lower, upper)
    for k in range(len(problems)):
        alone = _level_alone_residual(problems, k, dq, lower, upper)
        assert np.linalg.norm(sols[k].residual) == pytest.approx(alone, abs=1e-8), k


@given(seed=st.integers(0, 10_000), shift=targets, lift=st.floats(0, 0.03))
def test_lower_levels_never_degrade_higher_ones(robot, seed, shift, lift):
    q, _ = random_start(robot, seed)
    full = walking_stack(robot, q, com_shift=shift, lift=lift)
    solver = HierarchicalQP(full, "daqp")
    solver.solve(q, dt=0.01)
    with_low = [np.linalg.norm(s.residual) for s in solver.solutions]
    top = walking_stack(robot, q, com_shift=shift, lift=lift)
    top.set_active(["torso", "posture"], False)
    solver_top = HierarchicalQP(top, "daqp")
    solver_top.solve(q, dt=0.01)
    without_low = [np.linalg.norm(s.residual) for s in solver_top.solutions]
    assert np.allclose(with_low[:2], without_low, atol=1e-8)


def test_hierarchy_puts_the_top_level_first(robot):
    """Conflicting CoM and swing targets: whichever is higher is met exactly."""
    q = robot.configuration("walk_ready")
    for first in ("com", "swing"):
        stack = walking_stack(
            robot, q, com_shift=(0.0, 0.03, -0.01), lift=0.03, velocity_limits=False
        )
        stack.task(first).active = True
        # move the other task one level down
        other = "swing" if first == "com" else "com"
        task = stack.task(other)
        stack.level(1).tasks.remove(task)
        stack.add(task, level=2)
        solver = HierarchicalQP(stack, "daqp")
        solver.solve(q)
        residual = {
            name: np.linalg.norm(sol.residual[sl])
            for prob, sol in zip(solver.problems, solver.solutions, strict=True)
            for name, sl in prob.task_rows
        }
        assert residual[first] < 1e-9
        assert residual[other] > 1e-4


# ---------------------------------------------------------------------------- modes
def test_constraints_holding_only_met_rows_never_show_a_violation(robot):
    """solve_pose's hard-level error skips the constraints that declare ``held_rows_met``
    (self-collision, ground clearance: a row violated at q is a request, never held): their
    held rows must meet Δq = 0 (h >= 0) wherever q is — legs through each other, a sole below
    the ground, joints outside their limits — while the requests do occur there."""
    from wbc.stacks import load_stack

    rng = np.random.default_rng(7)
    requests = 0
    for _ in range(20):
        q = robot.configuration("walk_ready")
        q[7:] += rng.uniform(-0.6, 0.6, robot.n_joints)  # not clipped: outside the limits too
        q = robot.place_on_ground(q, "l_sole")
        q[2] -= rng.uniform(0.0, 0.03)  # the soles up to 3 cm below the ground
        control = load_stack("walk", robot, q, solver="weighted")
        kin = Kinematics(robot, q)
        control.set_phase("single", "l_sole", "r_sole", kin)  # the swing's ground clearance
        checked = [c for c in control.stack.constraints() if c.held_rows_met]
        assert {type(c).__name__ for c in checked} == {
            "SelfCollisionConstraint",
            "GroundClearanceConstraint",
        }
        for c in checked:
            held, asked = c.split(kin)
            assert (held.h >= 0.0).all(), c.name
            requests += asked.h.size
    assert requests > 0  # the draws do violate them


def test_targets_update_in_place_without_replanning(robot):
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q)
    solver = WeightedQP(stack, "daqp")
    solver.step(q, 0.01)
    ws = solver.ws
    com = stack.task("com")
    for _ in range(5):
        com.set_target(com.target + [0.001, 0, 0])
        q = solver.step(q, 0.01)
        assert solver.ws is ws  # same preallocated workspace
    errors = stack.errors()
    assert set(errors) == {"contact_l_sole", "swing", "com", "torso", "posture"}
    assert errors["com"].shape == (3,)


@pytest.mark.parametrize("solver_class", [WeightedQP, HierarchicalQP])
@pytest.mark.parametrize("compiled", [None, False])
def test_a_target_handle_taken_before_the_first_solve_is_honoured(robot, solver_class, compiled):
    """Tasks own their target arrays on every path: nothing re-binds them."""
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q)
    com, swing = stack.task("com"), stack.task("swing")
    handles = com.target, swing.target_position, swing.target_rotation
    solver = solver_class(stack, compiled=compiled)
    before = solver.solve(q, 0.01)  # the first solve builds the layout
    handles[0][:] += [0.004, -0.002, 0.0]
    handles[1][:] += [0.0, 0.0, 0.01]
    dq = solver.solve(q, 0.01)
    assert (solver.fast is not None) == (compiled is None)
    reference = walking_stack(robot, q)  # the same targets, set before any solve
    reference.task("com").set_target(handles[0])
    reference.task("swing").set_position_target(handles[1])
    expected = solver_class(reference, compiled=False).solve(q, 0.01)
    assert np.abs(dq - before).max() > 1e-3  # the handles moved the answer ...
    # ... to the one of the new targets (rtol=0: allclose's default 1e-5 of |dq| would
    # dominate 1e-9)
    assert np.abs(dq - expected).max() < 1e-9, np.abs(dq - expected).max()
    assert com.target is handles[0] and swing.target_position is handles[1]
    assert swing.target_rotation is handles[2]


@pytest.mark.parametrize("solver_class", [WeightedQP, HierarchicalQP])
@pytest.mark.parametrize("compiled", [None, False])
def test_a_target_assigned_after_the_first_solve_is_honoured(robot, solver_class, compiled):
    """``task.target = new`` writes into the task's own array (the compiled plan reads that
    array by address: a re-bound attribute was silently ignored there, honoured on the numpy
    path); a wrong shape is refused."""
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q)
    com, swing = stack.task("com"), stack.task("swing")
    arrays = com.target, swing.target_position, swing.target_rotation
    solver = solver_class(stack, compiled=compiled)
    before = solver.solve(q, 0.01)
    com.target = com.target + [0.004, -0.002, 0.0]
    swing.target_position = swing.target_position + [0.0, 0.0, 0.01]
    dq = solver.solve(q, 0.01)
    assert (solver.fast is not None) == (compiled is None)
    reference = walking_stack(robot, q)
    reference.task("com").set_target(com.target)
    reference.task("swing").set_position_target(swing.target_position)
    expected = solver_class(reference, compiled=False).solve(q, 0.01)
    assert np.abs(dq - before).max() > 1e-3
    assert np.abs(dq - expected).max() < 1e-9, np.abs(dq - expected).max()
    assert com.target is arrays[0] and swing.target_position is arrays[1]
    assert swing.target_rotation is arrays[2]
    kept = com.target.copy(), swing.target_rotation.copy()
    with pytest.raises(TaskError, match=r"com.*shape"):
        com.target = [0.0, 0.1]
    with pytest.raises(TaskError, match=r"com.*non-finite"):
        com.target = [0.0, np.nan, 0.2]
    with pytest.raises(TaskError, match=r"swing.*not a rotation"):
        swing.target_rotation = 2.0 * np.eye(3)
    assert np.array_equal(com.target, kept[0]) and np.array_equal(swing.target_rotation, kept[1])


def test_support_switch_replans(robot):
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q)
    right = stack.add(ContactTask(robot, "r_sole"), level=0)
    right.make_contact(Kinematics(robot, q))
    solver = WeightedQP(stack, "daqp")
    solver.step(q, 0.01)
    assert solver.ws.A.shape[0] == 12  # double support: two hard contacts
    stack.set_active(["contact_r_sole"], False)
    solver.step(q, 0.01)
    assert solver.ws.A.shape[0] == 6


# ---------------------------------------------------------------------------- diagnostics
def test_infeasible_hard_level_names_the_tasks(robot):
    q = robot.configuration("walk_ready")
    for cls in (WeightedQP, HierarchicalQP):
        stack = walking_stack(robot, q)
        far = stack.add(FramePositionTask(robot, "r_hand", name="reach_far"), level=3, hard=True)
        far.set_target([1.0, -0.5, 0.3])  # a metre away: impossible within one servo step
        with pytest.raises(InfeasibleError, match="reach_far"):
            cls(stack, "daqp").step(q, 0.01)
        relaxed = cls(stack, "daqp", on_infeasible="relax")
        dq = relaxed.solve(q, 0.01)
        assert relaxed.relaxed
        assert robot.within_limits(relaxed.integrate(q, dq))
        assert "reach_far" in relaxed.diagnosis
        # the relaxed solution still meets the feasible hard level above (the contact)
        J, e = stack.task("contact_l_sole").compute(Kinematics(robot, q))
        assert np.linalg.norm(J @ dq - e) < 1e-8


def test_infeasible_hard_inequality_is_named(robot):
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q)
    # the CoM can't reach a polygon 10 cm away within one step
    from wbc.limits import LinearInequality

    G = np.zeros((1, robot.nv))
    G[0] = -robot.com_jacobian(q)[0]
    stack.add_constraint(LinearInequality(G, np.array([-0.1]), name="com_far_forward"), level=0)
    with pytest.raises(InfeasibleError, match="com_far_forward"):
        HierarchicalQP(stack, "daqp").step(q, 0.01)
    with pytest.raises(InfeasibleError, match="com_far_forward"):
        WeightedQP(stack, "daqp").step(q, 0.01)


def test_bad_input_is_rejected(robot):
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q)
    solver = WeightedQP(stack, "daqp")
    bad = q.copy()
    bad[10] = np.nan
    with pytest.raises(ConfigurationError, match="non-finite"):
        solver.step(bad, 0.01)
    with pytest.raises(ConfigurationError, match="size nq"):
        solver.step(q[:-1], 0.01)
    with pytest.raises(ConfigurationError, match="dt"):
        solver.step(q, -0.01)
    with pytest.raises(TaskError, match="non-finite"):
        stack.task("com").set_target([0, np.inf, 0])
    with pytest.raises(TaskError, match="already in the stack"):
        stack.add(ComTask(robot))
    with pytest.raises(ConfigurationError, match="unknown QP backend"):
        WeightedQP(stack, "cplex")
    with pytest.raises(ConfigurationError, match="unknown hierarchical method"):
        HierarchicalQP(stack, method="magic")
    with pytest.raises(ConfigurationError, match="unknown hierarchical method"):
        HierarchicalQP(stack, method="daqp")  # DAQP's native hierarchy was dropped (issue 17)
    with pytest.raises(ConfigurationError, match="on_infeasible"):
        WeightedQP(stack, on_infeasible="ignore")


@pytest.mark.parametrize("dt", [None, True, "0.01", 0.0, -0.01, float("nan"), float("inf")])
def test_a_control_tick_needs_a_time_step_in_seconds(robot, dt):
    """``step`` without a time step would have no servo speed limit (issue 28): None, a
    bool, a string and a non-positive or non-finite number are one ConfigurationError line
    naming ``dt``; ``solve`` takes None (no velocity limits) but nothing else of those."""
    q = robot.configuration("walk_ready")
    solver = WeightedQP(walking_stack(robot, q), compiled=False)
    with pytest.raises(ConfigurationError, match=r"step: dt must be a time step in seconds"):
        solver.step(q, dt)
    if dt is not None:
        with pytest.raises(ConfigurationError, match=r"dt must be a time step in seconds"):
            solver.solve(q, dt)
    assert np.isfinite(solver.step(q, np.float64(0.01))).all()
