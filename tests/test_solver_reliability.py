"""Solver reliability (issue 17): one regression test per finding of the stress run.

Every test goes through the public API (load_robot, tasks, TaskStack, the solvers'
step/solve_pose, stacks.load_stack), so that it keeps its meaning whatever the solvers' inside,
except one that pins the cascade (the level solver every solver path goes through).
"""

from __future__ import annotations

import itertools
import time

import numpy as np
import pinocchio as pin
import pytest

from wbc import ConfigurationError, InfeasibleError, Kinematics, TaskError, WbcError, load_robot
from wbc.limits import GroundClearanceConstraint
from wbc.limits.self_collision import RECOVERY_TICKS, RECOVERY_TOL
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP, make_backend
from wbc.stacks import load_stack
from wbc.tasks import ComTask, ContactTask, FrameOrientationTask, FramePoseTask, PostureTask

SOLVERS = {"hierarchical": HierarchicalQP, "weighted": WeightedQP}
PATHS = [None, False]  # compiled (default), numpy path


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


@pytest.fixture(scope="module")
def stress(stress_script):
    """benchmarks/stress.py, whose draws the stress trials below replay."""
    return stress_script


def assert_no_joint_further_out(robot, q: np.ndarray, q_next: np.ndarray) -> None:
    """Every joint of ``q_next`` is within its limits or no further out than in ``q``."""
    j, j0 = q_next[7:], q[7:]
    assert (j >= np.minimum(robot.q_min, j0) - 1e-12).all()
    assert (j <= np.maximum(robot.q_max, j0) + 1e-12).all()


def stress_problem(robot, stress, trial: int) -> tuple:
    """A walk-stack stress trial (seed 2024, DAQP) as stress.py sets it up: (its solver, its
    active contacts, its start)."""
    p = stress.draw(robot, np.random.default_rng([2024, trial]), ["daqp"])
    q = stress.start(robot, p)
    compiled = None if p["compiled"] else False
    solver, contacts, com, swing, torso = stress.walk_stack(
        robot, q, p["kind"], "daqp", compiled, p["double"]
    )
    stress.move_targets(p, com, swing, torso)
    return solver, contacts, q


def replay_ticks(robot, stress, trial: int, ticks: int) -> list[np.ndarray]:
    """The ticks of a stress trial (seed 2024, DAQP) as stress.py runs them: the
    configurations from the start on (raises what a tick raises)."""
    solver, _, q = stress_problem(robot, stress, trial)
    qs = [q]
    for _ in range(ticks):
        qs.append(solver.step(qs[-1], 0.01))
    return qs


def pair_distances(solver, q: np.ndarray) -> np.ndarray:
    """Every pair's distance at q (the solver's self-collision limit)."""
    collision = solver.stack.constraint("self_collision")
    return collision.witness(Kinematics(solver.robot, q), below=np.inf).distance


def pinned(exc: InfeasibleError, collision, pairs) -> bool:
    """True if ``exc`` is the self-collision limit's error for pairs held inside its margin
    (issue 29: a hard pair that the contacts keep inside raises, naming it, after
    RECOVERY_TICKS ticks) and names one of ``pairs`` (pair indices)."""
    message = str(exc)
    return "stayed inside the" in message and any(
        f"{a} / {b}" in message for k in pairs for a, b in [collision.pair_links[k]]
    )


def readme_stack(robot, q, solver="hierarchical", backend="daqp", compiled=None, **options):
    """The README's stack: hard left contact; CoM + swing pose; torso + posture."""
    kin = Kinematics(robot, q)
    stack = TaskStack(robot)
    contact = stack.add(ContactTask(robot, "l_sole"), level=0, hard=True)
    contact.make_contact(kin)
    com = stack.add(ComTask(robot, kin.com), level=1, weight=1000)
    swing = stack.add(FramePoseTask(robot, "r_sole", name="swing"), level=1, weight=100)
    swing.set_target_from(kin)
    torso_rotation = kin.placement(robot.frame_id("torso")).rotation
    torso = stack.add(FrameOrientationTask(robot, "torso", torso_rotation), level=2)
    stack.add(PostureTask(robot, q), level=2, weight=0.01)
    solver = SOLVERS[solver](stack, backend=backend, compiled=compiled, **options)
    return solver, contact, com, swing, torso


def contact_error(robot, q, contact) -> float:
    """Largest component of a contact's 6-D error at q (m and rad)."""
    return float(abs(contact.compute(Kinematics(robot, q))[1]).max())


# ---------------------------------------------------------------- 1. hard tasks, converged
@pytest.mark.parametrize("kind", SOLVERS)
@pytest.mark.parametrize("compiled", PATHS)
@pytest.mark.parametrize("target", ["upside_down_torso", "com_out_of_reach"])
def test_converged_pose_holds_the_hard_contact(robot, kind, compiled, target):
    q = robot.configuration("walk_ready")
    solver, contact, com, _, torso = readme_stack(robot, q, kind, compiled=compiled)
    if target == "upside_down_torso":
        torso.set_target(pin.utils.rotate("x", np.pi) @ torso.target)
    else:
        com.set_target(com.target + [0.3, 0.2, -0.1])
    result = solver.solve_pose(q, max_iterations=50)
    assert contact_error(robot, result.q, contact) <= 1e-6
    # the last QP's answer within that solve's box (the joint limits: result.q is within
    # them by the clip after each solve, which would hide a miss)
    last = solver.last
    assert np.all(last.dq >= last.lower - 1e-9) and np.all(last.dq <= last.upper + 1e-9)


def test_converged_pose_holds_the_contact_from_a_random_start(robot):
    rng = np.random.default_rng([2024, 17])
    for _ in range(3):
        q = robot.configuration("walk_ready")
        q[7:] = np.clip(q[7:] + rng.uniform(-0.3, 0.3, robot.n_joints), robot.q_min, robot.q_max)
        solver, contact, com, swing, _ = readme_stack(robot, q)
        com.set_target(com.target + rng.uniform(-0.02, 0.02, 3))
        swing.set_position_target(swing.target_position + rng.uniform(-0.02, 0.02, 3))
        result = solver.solve_pose(q, max_iterations=50)
        assert contact_error(robot, result.q, contact) <= 1e-6


# ---------------------------------------------------------------- 2. relax keeps higher levels
def double_support_hard_com(robot, backend, compiled, kind="hierarchical"):
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    stack = TaskStack(robot)
    contacts = []
    for sole in ("l_sole", "r_sole"):
        c = stack.add(ContactTask(robot, sole), level=0, hard=True)
        c.make_contact(kin)
        contacts.append(c)
    com = ComTask(robot, kin.com + [0.2, 0.0, 0.0])  # out of reach
    stack.add(com, level=1, hard=True, weight=1000.0)
    stack.add(PostureTask(robot, q), level=2, weight=0.01)
    solver = SOLVERS[kind](stack, backend=backend, compiled=compiled, on_infeasible="relax")
    return q, solver, contacts


@pytest.mark.parametrize("kind", SOLVERS)
@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_relaxed_level_never_degrades_a_higher_one(robot, kind, backend):
    q, solver, contacts = double_support_hard_com(robot, backend, None, kind)
    result = solver.solve_pose(q, max_iterations=30)
    for c in contacts:
        assert contact_error(robot, result.q, c) <= 1e-6
    q, solver, contacts = double_support_hard_com(robot, backend, None, kind)
    for _ in range(20):  # tick mode: the linearisation's second order only, never accumulated
        q = solver.step(q, 0.01)
        assert solver.relaxed
        for c in contacts:
            assert contact_error(robot, q, c) <= 2e-3


# ---------------------------------------------------------------- 3. non-finite targets
@pytest.mark.parametrize("kind", SOLVERS)
@pytest.mark.parametrize("compiled", PATHS)
def test_target_written_in_place_with_nan_never_reaches_the_output(robot, kind, compiled):
    q = robot.configuration("walk_ready")
    solver, _, com, _, _ = readme_stack(robot, q, kind, compiled=compiled)
    solver.step(q, 0.01)
    com.target[0] = np.nan
    with pytest.raises(TaskError, match="'com'"):
        solver.step(q, 0.01)
    with pytest.raises(TaskError, match="'com'"):
        solver.solve_pose(q, max_iterations=5)


# ---------------------------------------------------------------- 4. quaternions
@pytest.mark.parametrize("compiled", PATHS)
@pytest.mark.parametrize("quaternion", [[0, 0, 0, 0], [0, 0, 0, 3], [0.1, 0, 0, 1]])
def test_non_unit_base_quaternion_is_one_typed_error_on_every_path(robot, compiled, quaternion):
    q = robot.configuration("walk_ready")
    solver, *_ = readme_stack(robot, q, compiled=compiled)
    q[3:7] = quaternion
    with pytest.raises(ConfigurationError, match="quaternion"):
        solver.step(q, 0.01)


# ---------------------------------------------------------------- 5. bounded time
def test_proxqp_hierarchy_numpy_path_has_bounded_time_per_tick(robot):
    """A degenerate level used to keep ProxQP for 140 s in one tick (default caps)."""
    rng = np.random.default_rng(1)
    offset = [rng.uniform(-0.03, 0.03, 3) for _ in range(3)][2]
    q = robot.configuration("walk_ready")
    solver, _, com, _, _ = readme_stack(robot, q, backend="proxqp", compiled=False)
    com.set_target(com.target + offset)
    for _ in range(30):
        start = time.perf_counter()
        try:
            q = solver.step(list(q), 0.01)
        except WbcError:  # a capped solve may fail, with a typed error
            q = np.asarray(q)
        assert time.perf_counter() - start < 10.0  # a bound, not a speed figure


@pytest.mark.parametrize("seed", range(4))
def test_many_rows_in_least_squares_have_the_optimum_of_a_slack_per_row(seed, monkeypatch):
    """A level whose inequality rows are soft (in least squares of their violation) solved
    with a slack per row made QPs of 400-850 variables for a self-collision level (16 rows
    per pair), most of a 40-70 s converged pose (stress trials 4875, 9547). Such a level is
    now solved over Δq alone (a damped Newton method on the piecewise quadratic, each step
    a QP of the level's own size): the same optimum as with a slack per row, on random
    levels of 60 rows most of them violated, below a hard level with its own rows."""
    from wbc.solvers import cascade  # no public entry point

    rng = np.random.default_rng(seed)
    n = 10
    hard = cascade.LevelProblem(
        0, rng.normal(size=(3, n)), rng.normal(size=3), rng.normal(size=(8, n)),
        rng.uniform(0.0, 1.0, 8), True,
    )  # fmt: skip
    soft = cascade.LevelProblem(
        1, rng.normal(size=(4, n)), rng.normal(size=4), rng.normal(size=(60, n)),
        rng.uniform(-1.0, 0.5, 60),
    )  # fmt: skip
    last = cascade.LevelProblem(2, np.eye(n), np.zeros(n), np.zeros((0, n)), np.zeros(0))
    lower, upper = np.full(n, -2.0), np.full(n, 2.0)

    def solve():
        backends = [make_backend("daqp") for _ in range(3)]
        return cascade.solve_cascade([hard, soft, last], lower, upper, backends)

    found = []
    hinge = cascade._solve_hinge
    monkeypatch.setattr(cascade, "_solve_hinge", lambda *a: found.append(hinge(*a)) or found[-1])
    dq, sols = solve()
    assert found and found[0] is not None  # the level went through it
    monkeypatch.setattr(cascade, "HINGE_ROWS", 10**9)  # a slack per row
    dq_ref, sols_ref = solve()
    assert (sols_ref[1].slack > 1e-3).sum() >= 5  # rows the optimum leaves violated

    def value(sols):  # the soft level's optimum: its residual and its rows' violation
        return float(sols[1].residual @ sols[1].residual + sols[1].slack @ sols[1].slack)

    assert value(sols) == pytest.approx(value(sols_ref), rel=1e-7, abs=1e-9)
    np.testing.assert_allclose(dq, dq_ref, atol=1e-5)


# ---------------------------------------------------------------- 6. the cascade meets contacts
@pytest.mark.parametrize("compiled", PATHS)
def test_cascade_meets_the_contact_with_a_com_target_ahead(robot, compiled):
    """DAQP's native hierarchical mode called this feasible problem infeasible."""
    q = robot.configuration("walk_ready")
    solver, contact, com, _, _ = readme_stack(robot, q, compiled=compiled)
    com.set_target(com.target + [0.03, 0.0, 0.0])
    for _ in range(5):  # tick mode: met in the linearisation (second-order error only)
        q = solver.step(q, 0.01)
        assert contact_error(robot, q, contact) <= 1e-2
    result = solver.solve_pose(q, max_iterations=50)
    assert contact_error(robot, result.q, contact) <= 1e-6


# ---------------------------------------------------------------- 7. the log's branch at π
def test_torso_target_exactly_pi_away_takes_one_branch_on_every_path(robot):
    """A target π away (about a random axis) gave opposite errors on the two paths."""
    rng = np.random.default_rng(3)
    for _ in range(70):  # the 70th draw is one that split the paths
        noise, axis = rng.uniform(-0.2, 0.2, robot.n_joints), rng.normal(size=3)
    q = robot.configuration("walk_ready")
    q[7:] = np.clip(q[7:] + noise, robot.q_min, robot.q_max)
    axis /= np.linalg.norm(axis)
    dqs, errors = [], []
    for compiled in PATHS:
        solver, _, _, _, torso = readme_stack(robot, q, compiled=compiled)
        torso.set_target(pin.exp3(np.pi * axis) @ torso.target)
        dqs.append(solver.solve(q, 0.01))
        errors.append(torso.last_error.copy())
    np.testing.assert_allclose(errors[0], errors[1], atol=1e-9)
    assert errors[0][np.argmax(abs(errors[0]))] > 0  # the rule: largest component positive
    np.testing.assert_allclose(dqs[0], dqs[1], atol=1e-8)


# ---------------------------------------------------------------- 8. feasible, reported failing
@pytest.mark.parametrize("backend", ["daqp", "quadprog"])
def test_hard_level_is_met_exactly_when_a_row_couples_its_null_space(backend):
    """A hard level a = 1 with the row a - κ b <= 0 (κ = 1e-3): met exactly at (1, 1/κ). As
    least squares with the cascade's ridge ρ on the level's null space (b) the optimum
    trades a residual ρ/κ² = 1e-4 for it, and a solver called the hard level infeasible
    (stress trial 1529: a contact 5e-6 m off behind the rows of a start with many pairs
    inside the self-collision margin). The cascade is the solvers' level solver (one
    definition: every path's hierarchy, recovery and projection goes through it)."""
    from wbc.solvers.cascade import LevelProblem, solve_cascade  # no public entry point

    hard = LevelProblem(
        0, np.array([[1.0, 0.0]]), np.array([1.0]), np.array([[1.0, -1e-3]]), np.zeros(1), True
    )
    last = LevelProblem(1, np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2)), np.zeros(0))
    backends = [make_backend(backend) for _ in range(2)]
    dq, sols = solve_cascade([hard, last], np.full(2, -np.inf), np.full(2, np.inf), backends)
    assert abs(sols[0].residual).max() <= 1e-9
    assert dq[0] - 1e-3 * dq[1] <= 1e-9


# ---------------------------------------------------------------- 8. feasible, reported failed
@pytest.mark.parametrize(("trial", "ticks"), [(4888, 6), (5101, 8)])
def test_feet_pair_the_contacts_fix_never_blocks_their_restoration(robot, stress, trial, ticks):
    """Stress trials 4888, 5101 (walk stack, weighted QP, numpy path, double support, a start
    inside the limits, targets far or upside down): the feet start 4.99 mm apart, a hair
    inside the self-collision margin, a distance the two hard contacts fix. A tick's
    second-order drift carried the pair to 5.01 / 5.15 mm, outside the margin, where the
    restoration held it; the contacts' way back needs it at 4.99 mm, and the tick raised
    "hard level 0 is infeasible" at tick 5 / 7. The restoration may now take a pair at its
    margin inside it by the drift it undoes (at most 0.5 mm). No error; the contacts held to
    a tick's second order; no joint further out; the other pairs that start outside the
    margin stay there (to that second order)."""
    qs = replay_ticks(robot, stress, trial, ticks)
    control = load_stack("walk", robot, qs[0])
    contacts = [t for t in control.stack.tasks() if isinstance(t, ContactTask) and t.active]
    collision = control.stack.constraint("self_collision")
    feet = {"l_foot", "r_foot"}

    def others(q):  # the distances of the pairs not between the two feet
        w = collision.witness(Kinematics(robot, q), below=np.inf)
        return {
            k: d
            for k, d in zip(w.index.tolist(), w.distance.tolist(), strict=True)
            if set(collision.pair_links[k]) != feet
        }

    start = others(qs[0])
    outside = [k for k, d in start.items() if d >= collision.margin]
    for q_next in qs[1:]:
        assert robot.within_limits(q_next)
        for c in contacts:
            assert contact_error(robot, q_next, c) <= 1e-2
        d = others(q_next)
        assert min(d[k] for k in outside) >= collision.margin - 5e-4


def test_restoration_may_take_a_pair_at_its_margin_in_by_the_drift_it_undoes(robot, stress):
    """Stress trial 436 (walk stack, weighted QP, double support, two joints 0.035 rad
    outside at the start, targets far): at tick 24 the contacts are 6e-5 m off (a tick's
    second order) and a foot and the other ankle sit 5.001 mm apart, at their margin; with
    the pair held there the way back onto the contacts is a 0.075 rad detour that no tick's
    box allows, and the tick raised "hard level 0 is infeasible". The restoration may now
    take such a pair inside its margin by the drift it undoes (at most 0.5 mm). Over the
    ticks: contacts held to a tick's second order; no joint further out; no pair that is at
    or outside its margin before a tick ends more than 0.5 mm inside it. The start has the
    feet 2-17 mm into each other, pinned there by both soles: after RECOVERY_TICKS ticks
    the error naming them (issue 29: never a silent result), not before."""
    solver, _, q = stress_problem(robot, stress, 436)
    qs = [q]
    inside = np.flatnonzero(
        pair_distances(solver, q) < solver.stack.constraint("self_collision").margin
    )
    # a pair the contacts pin inside its margin: the error naming it, after RECOVERY_TICKS
    with pytest.raises(InfeasibleError) as error:
        for _ in range(30):
            qs.append(solver.step(qs[-1], 0.01))
    assert len(qs) == RECOVERY_TICKS + 1
    assert pinned(error.value, solver.stack.constraint("self_collision"), inside)
    control = load_stack("walk", robot, qs[0])
    contacts = [t for t in control.stack.tasks() if isinstance(t, ContactTask) and t.active]
    collision = control.stack.constraint("self_collision")

    def distances(q):
        w = collision.witness(Kinematics(robot, q), below=np.inf)
        return w.distance

    for q, q_next in itertools.pairwise(qs):
        assert_no_joint_further_out(robot, q, q_next)
        for c in contacts:
            assert contact_error(robot, q_next, c) <= 1e-2
        d, d_next = distances(q), distances(q_next)
        held = d >= collision.margin
        assert (d_next[held] >= collision.margin - 5e-4).all()


#: stress trial 4875's last iterate (walk stack, weighted QP, numpy path, single support, two
#: joints 0.007 rad outside at the start, targets far), 1.53e-6 m off its contact
LAST_ITERATE_4875 = [
    -0.1947407530815951, 0.04638122034021264, 0.204296840524681, 0.07819508430786365,
    -0.44096679574146663, -0.22039262475252638, 0.8665223048475336, 0.9319857104958177,
    -0.06498986867364412, 0.06124479152910393, 0.6101742798038765, 0.213946634837165,
    0.4414201325407827, 0.2985789379368775, -1.406735377, 1.472185224, 0.382728185,
    0.097214839, 0.04165367582464182, 0.14955620239837222, -0.4619680881616588,
    0.4869059905621083, 1.047197551, 1.3757074453683436, 0.639663171,
]  # fmt: skip


def test_last_projection_survives_daqp_cycling_on_the_held_pairs(robot, stress):
    """Stress trial 4875: its converged pose ended 1.28e-6 m off its contact (the guard
    raised). The last projection's step held the 340 rows of the pairs inside their margin
    no closer, in least squares after the contact; DAQP cycled on them (exit flag -2) and
    the projection took no step at all. It now steps with the hard levels alone when that
    happens: from the trial's last iterate, the projection ends on the contact, no joint
    further out. (The whole pose takes tens of seconds: `stress.py --trials 4875`.)"""
    p = stress.draw(robot, np.random.default_rng([2024, 4875]), ["daqp"])
    q0 = stress.start(robot, p)
    solver, contacts, *_ = stress.walk_stack(robot, q0, p["kind"], "daqp", False, p["double"])
    q = np.array(LAST_ITERATE_4875)
    assert max(contact_error(robot, q, c) for c in contacts) > 1.5e-6
    q_end = solver.solve_pose(q, max_iterations=0).q
    for c in contacts:
        assert contact_error(robot, q_end, c) <= 1e-6
    assert_no_joint_further_out(robot, q, q_end)


#: stress trial 4169's iterate at its last projection (walk stack, hierarchical QP, numpy
#: path, double support, one joint 0.018 rad outside at the start, targets far), its
#: contacts 2.4e-4 m off
LAST_ITERATE_4169 = [
    0.2538324831277032, -0.006830374088642327, 0.08020793596114982, 0.12512114166710517,
    0.5766930586734959, 0.1988676165077609, 0.7824458365217686, -0.382728185,
    0.011328720784264938, -0.02553825412215019, 0.2777284325416619, -1.5144986984043858,
    -0.07948610331249385, -4.188790205, 1.319275928302877, 1.4603670046755712,
    -0.2630917684181437, 0.097214839, 0.217965894786344, 0.0,
    -1.6054313390685573, 0.19502710761615713, -3.4536600723887974, -1.4384269510984706,
    -1.4721851238227983,
]  # fmt: skip


def test_last_projection_may_take_a_pair_at_its_margin_in_by_the_drift(robot, stress):
    """Stress trial 4169: its converged pose ended 1.7e-6 m off its contacts (the guard
    raised). From its last iterate, 2.4e-4 m off, the projection onto the contacts met a
    self-collision pair at its margin and crept (steps of 0.1 rad accepted at 1/256) to
    1.85e-6. As a tick's restoration, the pose's last projection may now, as a last resort,
    take such a pair inside its margin by the drift it undoes (at most 0.5 mm). A pose of
    no iteration from that iterate (its last projection only): it ends on the contacts; no
    joint further out; no pair at or outside its margin ends more than that inside it.
    (The whole pose: `stress.py --trials 4169`.)"""
    p = stress.draw(robot, np.random.default_rng([2024, 4169]), ["daqp"])
    q0 = stress.start(robot, p)
    solver, contacts, *_ = stress.walk_stack(robot, q0, p["kind"], "daqp", False, p["double"])
    collision = solver.stack.constraint("self_collision")
    q = np.array(LAST_ITERATE_4169)
    drift = max(contact_error(robot, q, c) for c in contacts)
    assert drift > 2e-4
    q_end = solver.solve_pose(q, max_iterations=0).q
    for c in contacts:
        assert contact_error(robot, q_end, c) <= 1e-6
    assert_no_joint_further_out(robot, q, q_end)
    d = collision.witness(Kinematics(robot, q), below=np.inf).distance
    d_end = collision.witness(Kinematics(robot, q_end), below=np.inf).distance
    held = d >= collision.margin
    assert (d_end[held] >= collision.margin - min(drift, 5e-4) - 1e-5).all()


# ---------------------------------------------------------------- 9. starts outside the limits
def start_outside_in_double_support(robot, seed: int = 9):
    """Walk Ready with 3-6 leg joints 0.05 rad outside their limits (both soles down). Most
    such draws also start with links inside the walk stack's self-collision margin (seeds
    0-8, 10, 11: shin and foot boxes overlap by up to 11 mm); seed 9 does not."""
    legs = [
        i for i, n in enumerate(robot.joint_names) if ("hip" in n or "knee" in n or "ankle" in n)
    ]
    rng = np.random.default_rng(seed)
    q = robot.configuration("walk_ready")
    for i in rng.choice(legs, rng.integers(3, 7), replace=False):
        q[7 + i] = robot.q_max[i] + 0.05 if rng.random() < 0.5 else robot.q_min[i] - 0.05
    return robot.place_on_ground(q, "l_sole")


@pytest.mark.parametrize("kind", SOLVERS)
@pytest.mark.parametrize("compiled", PATHS)
def test_start_outside_the_limits_in_double_support_recovers(robot, kind, compiled):
    """Recovery at full servo speed and both hard contacts were incompatible at tick 0: the
    recovery now yields to the contacts (as fast as they allow) instead of raising."""
    q = start_outside_in_double_support(robot)
    assert not robot.within_limits(q)
    control = load_stack("walk", robot, q, solver=kind, compiled=compiled)
    contacts = [t for t in control.stack.tasks() if isinstance(t, ContactTask) and t.active]
    assert len(contacts) == 2
    j0 = q[7:].copy()
    for _ in range(40):
        q_next = control.solver.step(q, 0.01)
        assert_no_joint_further_out(robot, q, q_next)
        for c in contacts:
            assert contact_error(robot, q_next, c) <= 1e-2
        q = q_next
    assert robot.within_limits(q), q[7:] - j0


@pytest.mark.parametrize("kind", SOLVERS)
@pytest.mark.parametrize("seed", [0, 2, 8])
def test_start_outside_the_limits_and_inside_a_collision_margin_recovers(robot, kind, seed):
    """The same starts with links inside the self-collision margin too raised "hard level 0
    is infeasible" at tick 0 (the rows asked the pairs inside to separate at once, which the
    contacts and the joints' way back did not allow). Now: no joint further out; both
    contacts held to a tick's second order; the pairs that start outside the margin stay
    there (up to that second order); the joints come back within their limits; once they
    are, no pair inside gets deeper (it separates); a pair the soles pin inside raises the
    error naming it after RECOVERY_TICKS ticks (issue 29: never a silent result), not
    before."""
    q = start_outside_in_double_support(robot, seed)
    assert not robot.within_limits(q)
    control = load_stack("walk", robot, q, solver=kind, compiled=False)
    collision = control.stack.constraint("self_collision")

    def distances(q):
        w = collision.witness(Kinematics(robot, q), below=np.inf)
        return dict(zip(w.index.tolist(), w.distance.tolist(), strict=True))

    d = distances(q)
    outside = [k for k, v in d.items() if v >= collision.margin]
    inside = [k for k, v in d.items() if v < collision.margin]
    assert inside
    contacts = [t for t in control.stack.tasks() if isinstance(t, ContactTask) and t.active]
    error = None
    for tick in range(40):
        try:
            q_next = control.solver.step(q, 0.01)
        except InfeasibleError as exc:  # pairs the contacts pin inside: named, not before
            assert tick >= RECOVERY_TICKS and pinned(exc, collision, inside), exc
            error = exc
            break
        assert_no_joint_further_out(robot, q, q_next)
        for c in contacts:
            assert contact_error(robot, q_next, c) <= 1e-2
        d_next = distances(q_next)
        assert min(d_next[k] for k in outside) >= collision.margin - 5e-4
        if robot.within_limits(q):
            assert all(d_next[k] >= min(d[k], collision.margin) - 5e-4 for k in inside)
        q, d = q_next, d_next
    if error is None:
        assert robot.within_limits(q)
    # the converged pose from that start: contacts held to 1e-6 (the final guard), no joint
    # further out; or the same error naming the pinned pairs
    q0 = start_outside_in_double_support(robot, seed)
    control = load_stack("walk", robot, q0, solver=kind)
    try:
        result = control.solver.solve_pose(q0, max_iterations=30)
    except InfeasibleError as exc:
        assert pinned(exc, collision, inside), exc
        return
    contacts = [t for t in control.stack.tasks() if isinstance(t, ContactTask) and t.active]
    for c in contacts:
        assert contact_error(robot, result.q, c) <= 1e-6
    assert_no_joint_further_out(robot, q0, result.q)


@pytest.mark.parametrize("kind", SOLVERS)
def test_start_with_the_legs_crossed_recovers_as_far_as_the_held_pairs_allow(robot, kind):
    """Seed 3: six leg joints 2.9° outside, the legs crossed through each other (boxes 8.5 mm
    into each other), pinned so by both soles: the error naming the crossed pairs after
    RECOVERY_TICKS ticks (issue 29), not before; until then no joint further out; the joints
    come back as far as the hard contacts and the pairs held at the margin allow: the right knee and
    ankle pitch stop 0.5° and 1° outside, where any motion with both soles fixed that brings
    one in takes the other further out or the right thigh into the left ankle's margin
    (benchmarks/stress.md). Holding every pair at the margin itself (not at the damper's
    rate) parked pairs there and raised at tick 11."""
    q = start_outside_in_double_support(robot, 3)
    control = load_stack("walk", robot, q, solver=kind, compiled=False)
    contacts = [t for t in control.stack.tasks() if isinstance(t, ContactTask) and t.active]

    def outside(q):
        j = q[7:]
        return np.maximum(robot.q_min - j, 0.0) + np.maximum(j - robot.q_max, 0.0)

    start = outside(q).sum()
    collision = control.stack.constraint("self_collision")
    crossed = np.flatnonzero(pair_distances(control.solver, q) < collision.margin)
    for tick in range(60):
        try:
            q_next = control.solver.step(q, 0.01)
        except InfeasibleError as exc:  # the crossed legs, pinned by the soles: named
            assert tick >= RECOVERY_TICKS and pinned(exc, collision, crossed), exc
            break
        assert (outside(q_next) <= outside(q) + 1e-12).all()
        for c in contacts:
            assert contact_error(robot, q_next, c) <= 1e-2
        q = q_next
    assert outside(q).sum() < 0.1 * start


def outside_limits(robot, q: np.ndarray) -> np.ndarray:
    """How far (rad) each joint of q is outside its range (0 inside)."""
    j = q[7:]
    return np.maximum(robot.q_min - j, 0.0) + np.maximum(j - robot.q_max, 0.0)


@pytest.mark.parametrize(("trial", "ticks"), [(1567, 30), (8832, 15)])
def test_way_back_stops_at_the_contacts_without_drifting_off(robot, stress, trial, ticks):
    """Stress trials 1567 (weighted) and 8832 (hierarchical): walk stack, double support,
    both ankle rolls 0.044 / 0.026 rad outside their limits at the start (and a hip pitch /
    a knee). The contacts, made at that start, fix the soles' relative pose, which no
    configuration meets with the ankle rolls back inside: the joints' way back (below the
    hard contacts) stops about 0.02 rad outside, at a fold of the contact manifold where
    the ticks' first-order steps drifted the contacts 1-3 mm per tick; the drift could not
    be undone without taking the joints back out, and tick 17 / 8 raised "hard level 0 is
    infeasible" (so did the converged pose). A tick from a start outside the limits now
    ends on its hard levels: no error; the contacts held to 1e-6 after every tick; no joint
    further out; the joints come back as far as the contacts allow (a third of the way at
    least). The converged pose from that start ends on the contacts, no joint further out."""
    solver, contacts, q0 = stress_problem(robot, stress, trial)
    start = outside_limits(robot, q0)
    assert (start > 0.02).sum() >= 2
    q = q0
    for _ in range(ticks):
        q_next = solver.step(q, 0.01)
        assert_no_joint_further_out(robot, q, q_next)
        for c in contacts:
            assert contact_error(robot, q_next, c) <= 1e-6
        q = q_next
    assert outside_limits(robot, q).sum() < 0.67 * start.sum()
    result = solver.solve_pose(q0, max_iterations=20)
    for c in contacts:
        assert contact_error(robot, result.q, c) <= 1e-6
    assert_no_joint_further_out(robot, q0, result.q)


def start_with_the_swing_sole_below_the_ground(robot):
    """Walk Ready with the right knee 0.3 rad straighter, the left sole on the ground: the
    right sole's lowest corner starts 20 mm below the ground."""
    q = robot.configuration("walk_ready")
    i = robot.joint_names.index("r_knee")
    q[7 + i] -= np.sign(q[7 + i]) * 0.3
    return robot.place_on_ground(q, "l_sole")


@pytest.mark.parametrize("compiled", PATHS)
def test_start_with_the_swing_sole_below_the_ground_comes_back_up(robot, compiled):
    """The walk stack's weighted QP (every constraint row hard) raised "ground_clearance
    infeasible" at tick 0 from such a start (321 ticks in the 10,000-trial stress run): the
    rows asked every corner back above the ground in one tick. Now, as a joint outside its
    range: no tick takes a corner further down, and the sole rises at the bounded rate
    (`max_rise` per tick) until it is above the ground."""
    q = start_with_the_swing_sole_below_the_ground(robot)
    control = load_stack("walk", robot, q, solver="weighted", compiled=compiled)
    control.set_phase("single", "l_sole", "r_sole", Kinematics(robot, q))
    clearance = control.stack.constraint("ground_clearance_swing")
    contact = control.stack.task("contact_support")
    z = clearance.lowest_point(Kinematics(robot, q))
    assert z < -0.019
    for _ in range(40):
        q = control.solver.step(q, 0.01)
        z_next = clearance.lowest_point(Kinematics(robot, q))
        assert z_next >= z - 1e-6  # no further down (a tick's second order)
        assert z_next <= max(z, 0.0) + clearance.max_rise + 1e-4  # bounded rate
        assert contact_error(robot, q, contact) <= 1e-2
        z = z_next
    assert z >= -1e-5
    assert robot.within_limits(q)


@pytest.mark.parametrize("kind", SOLVERS)
@pytest.mark.parametrize("compiled", PATHS)
def test_hard_ground_clearance_from_below_the_ground_comes_back_up(robot, kind, compiled):
    """The README's stack with the swing sole's ground clearance at the hard level, from a
    start 20 mm below the ground: every solver and path brings the sole up at the bounded
    rate, never lower, and no error (the rows asked all of it in one tick)."""
    q = start_with_the_swing_sole_below_the_ground(robot)
    solver, *_ = readme_stack(robot, q, kind, compiled=compiled)
    clearance = solver.stack.add_constraint(GroundClearanceConstraint(robot, "r_sole"), level=0)
    z = clearance.lowest_point(Kinematics(robot, q))
    for _ in range(30):
        q = solver.step(q, 0.01)
        z_next = clearance.lowest_point(Kinematics(robot, q))
        assert z - 1e-6 <= z_next <= max(z, 0.0) + clearance.max_rise + 1e-4
        z = z_next
    assert z >= -1e-5


# ---------------------------------------------------------------- 10. bad inputs
def test_string_target_is_a_one_line_task_error(robot):
    with pytest.raises(TaskError, match=r"'com'.*3 numbers"):
        ComTask(robot, target="abc")
    with pytest.raises(TaskError, match="3x3"):
        FrameOrientationTask(robot, "torso", target="abc")


@pytest.mark.parametrize("compiled", PATHS)
def test_com_task_without_target_refuses_to_solve(robot, compiled):
    """target=None is unset, not the world origin: a solve names the task."""
    q = robot.configuration("walk_ready")
    stack = TaskStack(robot)
    contact = stack.add(ContactTask(robot, "l_sole"), level=0, hard=True)
    contact.make_contact(Kinematics(robot, q))
    com = stack.add(ComTask(robot, target=None), level=1)
    solver = HierarchicalQP(stack, compiled=compiled)
    with pytest.raises(TaskError, match="'com'"):
        solver.step(q, 0.01)
    com.set_target_from(Kinematics(robot, q))
    assert np.isfinite(solver.step(q, 0.01)).all()


def test_infeasible_residuals_are_on_the_same_scale_on_every_path(robot):
    """The same infeasible hard CoM: the message's residual (m) agrees across solvers."""
    residuals = []
    for kind in SOLVERS:
        for compiled in PATHS:
            q, solver, _ = double_support_hard_com(robot, "daqp", compiled, kind)
            solver.on_infeasible = "raise"
            with pytest.raises(InfeasibleError, match="com") as info:
                solver.step(q, 0.01)
            text = str(info.value)
            residuals.append(float(text.split("com (residual ")[1].split(")")[0]))
    assert max(residuals) <= 1.5 * min(residuals), residuals


def test_a_pair_closing_at_full_speed_from_above_13_mm_ends_the_tick_outside_it(robot, stress):
    """Stress trial 5101 (walk stack as shipped, its rows in the pairs' common frame; weighted
    QP, numpy path, double support, targets far): at tick 3 r_thigh / r_forearm sit 15.56 mm
    apart and the tick turns every joint at full speed towards each other. The damper's
    allowance was h = 1.35 (d − m) there (→ +∞ at the trigger: its margin held only below
    14 mm) and the tick ended at 2.97 mm, 2 mm inside the margin, with the rows met to 0.3 mm.
    Capped at MAX_CLOSURE (d − m), no tick that starts outside the margin ends more than a
    tick's second order (RECOVERY_TOL) inside it, and that pair, closing more than 5 mm from
    above 13 mm, ends outside it (6.58 mm)."""
    p = stress.draw(robot, np.random.default_rng([2024, 5101]), ["daqp"])
    q = stress.start(robot, p)
    control = load_stack("walk", robot, q, backend="daqp", solver=p["kind"])
    assert p["double"] and not p["compiled"]
    stack = control.stack
    stress.move_targets(p, stack.task("com"), stack.task("frame_pose_swing"), stack.task("torso"))
    collision = stack.constraint("self_collision")
    assert collision.common_frame
    fast = []
    for _ in range(8):
        q_next = control.solver.step(q, 0.01)
        before, after = pair_distances(control.solver, q), pair_distances(control.solver, q_next)
        outside = before >= collision.margin
        assert after[outside].min() >= collision.margin - RECOVERY_TOL
        closing = (before > 0.013) & (before < collision.trigger) & (before - after > 0.005)
        fast += after[closing].tolist()
        q = q_next
    assert fast and min(fast) >= collision.margin
