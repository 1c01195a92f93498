"""Self-collision limit: pair selection, distances and their Jacobians, damper rows, and the
limit at every level of the hierarchy and in the weighted QP (wbc.limits.self_collision)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from wbc import Kinematics
from wbc.bench.trajectories import build
from wbc.exceptions import ConfigurationError, InfeasibleError, TaskError
from wbc.limits import Inequality, SelfCollisionConstraint
from wbc.limits.collision_kernels import MAX_CLOSURE
from wbc.limits.collision_reference import distance_jacobian, joint_masks, separating_plane_rows
from wbc.limits.self_collision import (
    RECOVERY_TICKS,
    RECOVERY_TOL,
    PairDistances,
    damper_bound,
)
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.stacks import build_stack, load_stack
from wbc.tasks import ComTask, ContactTask, FrameOrientationTask, FramePositionTask, PostureTask
from wbc.walking.loop import StackController, run

MARGIN, TRIGGER, DAMPING = 0.005, 0.02, 0.4
#: second-order error of a linearised tick (the row holds Δq's first-order gap; turning
#: boxes add ~|Δq|² x lever): how far under the margin a pulled pair may dip for a tick
LINEARISATION = 5e-4


@pytest.fixture(scope="module")
def limit(robot):
    return SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING)


def test_pairs_skip_rigid_and_adjacent_links_and_keep_the_ones_that_meet(robot, limit):
    model = robot.model
    links = {lk for pair in limit.pair_links for lk in pair}
    assert {"torso", "l_upper_arm", "r_thigh", "l_shin", "r_foot"} <= links
    for a, b in limit.pair_links:
        ja = model.frames[model.getFrameId(a)].parentJoint
        jb = model.frames[model.getFrameId(b)].parentJoint
        assert ja != jb and model.parents[ja] != jb and model.parents[jb] != ja, (a, b)
    kept = {frozenset(p) for p in limit.pair_links}
    for wanted in (("torso", "l_upper_arm"), ("l_thigh", "r_thigh"), ("r_foot", "l_shin")):
        assert frozenset(wanted) in kept
    # a hand cannot reach its own foot within the limits: never closer than the trigger
    assert frozenset(("l_forearm", "r_forearm")) not in kept


def test_include_exclude_and_explicit_pairs(robot):
    ex = SelfCollisionConstraint(robot, exclude=[["l_foot", "r_foot"]], samples=50)
    assert frozenset(("l_foot", "r_foot")) not in {frozenset(p) for p in ex.pair_links}
    only = SelfCollisionConstraint(robot, pairs=[["torso", "l_upper_arm"]])
    assert set(only.pair_links) == {("torso", "l_upper_arm")}
    assert only.n_pairs == 2 * 3  # 3 torso boxes x 2 upper-arm boxes
    with pytest.raises(ConfigurationError, match=r"unknown link.*'l_toe'"):
        SelfCollisionConstraint(robot, pairs=[["torso", "l_toe"]])
    with pytest.raises(ConfigurationError, match=r"trigger .* must be larger than the margin"):
        SelfCollisionConstraint(robot, margin=0.02, trigger=0.01)
    with pytest.raises(ConfigurationError, match="damping must be in"):
        SelfCollisionConstraint(robot, damping=0.0)


@given(seed=st.integers(0, 10_000))
def test_distance_jacobian_matches_finite_differences(robot, limit, seed):
    """J_d = nᵀ(J_p2 − J_p1) for separated and for penetrating pairs (signed distance)."""
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.5, 0.5, 3))).coeffs()
    kin = Kinematics(robot, q)
    w = limit.distances.below(kin, np.inf)
    masks = joint_masks(robot)
    J = distance_jacobian(
        kin.data.J,
        masks[limit.distances.joint_1[w.index]],
        masks[limit.distances.joint_2[w.index]],
        w.p1,
        w.p2,
        w.normal,
    )
    dq = rng.normal(size=robot.nv) * 1e-4
    d = []
    for sign in (1, -1):
        kin.update(robot.integrate(q, sign * dq))
        d.append(limit.distances.below(kin, np.inf).distance)
    fd = (d[0] - d[1]) / 2
    # GJK/EPA's own accuracy is ~1e-7 m; a pair whose witness jumps between features
    # (nearly parallel faces) has no derivative: those are the few outliers allowed
    good = np.abs(fd - J @ dq) < 2e-6 + 1e-3 * np.abs(fd)
    assert good.mean() > 0.9
    assert good[w.distance < 0].all() or (w.distance < 0).sum() <= 1


def test_lipschitz_bounds_hold_along_random_motions(robot, limit):
    rng = np.random.default_rng(3)
    pd = limit.distances
    for _ in range(20):
        q0, q1 = robot.random_configuration(rng), robot.random_configuration(rng)
        d0 = pd.below(Kinematics(robot, q0), np.inf).distance
        d1 = pd.below(Kinematics(robot, q1), np.inf).distance
        step = np.abs(q1[7:] - q0[7:])
        assert np.all(np.abs(d1 - d0) <= pd.L @ step + 1e-7)


def test_cached_distances_equal_the_exact_ones_along_a_motion(robot):
    """The conservative cache skips pairs, never a pair below the query distance."""
    lim = SelfCollisionConstraint(robot, samples=100)
    fresh = PairDistances(robot, *_model_and_pairs(robot, lim))
    rng = np.random.default_rng(4)
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    for _ in range(60):
        q = robot.clip_to_limits(robot.integrate(q, np.r_[np.zeros(6), rng.normal(0, 0.03, 18)]))
        kin.update(q)
        w = lim.distances.below(kin, TRIGGER)
        exact = fresh.below(kin, np.inf)
        want = exact.index[exact.distance < TRIGGER]
        assert np.array_equal(np.sort(w.index), np.sort(want))
        fresh._bound[:] = -np.inf  # recompute everything every time
    assert lim.distances.exact_computations < fresh.exact_computations


def test_the_kernels_lever_arms_move_the_bounds_as_the_whole_matrix_does(robot):
    """The lever arms the kernel reads (each joint's non-zero ones, :func:`sparse_arms`) are L
    without its zeros, and move every pair's bound, bit for bit, as the whole of L does joint
    by joint (a query below every bound: the bounds are the arms' alone)."""
    from wbc.limits.collision_kernels import sparse_arms

    lim = SelfCollisionConstraint(robot, samples=100)
    pd = lim.distances
    start, pair, arm = sparse_arms(pd.L)
    assert np.array_equal(start, pd._L_start) and np.array_equal(arm, pd._L_arm)
    dense = np.zeros_like(pd.L.T)
    for i in range(dense.shape[0]):
        e = slice(start[i], start[i + 1])
        assert np.all(np.diff(pair[e]) > 0) and np.all(arm[e] != 0.0)
        dense[i, pair[e]] = arm[e]
    assert np.array_equal(dense, pd.L.T) and 0 < arm.size < pd.L.size
    rng = np.random.default_rng(5)
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    pd.close(kin, -np.inf)
    pd._bound[:] = rng.uniform(0.01, 0.2, pd._bound.size)
    want, last = pd._bound.copy(), q[7:].copy()
    for _ in range(30):
        q = robot.clip_to_limits(robot.integrate(q, np.r_[np.zeros(6), rng.normal(0, 0.03, 18)]))
        kin.update(q)
        assert pd.close(kin, -np.inf) == 0
        for i, step in enumerate(np.abs(q[7:] - last)):
            if step != 0.0:
                for k in range(want.size):
                    want[k] -= pd.L[k, i] * step
        last = q[7:].copy()
        assert np.array_equal(pd._bound, want)


def test_the_bound_kernel_call_follows_its_kinematics_and_buffers(robot):
    """``rows_into`` keeps the kernel's arguments for one Kinematics and its compiled entry
    point (no dispatch) per G, h: with two buffers taken in turn, then another Kinematics,
    every call's rows are those of a fresh limit at that call's configuration."""
    limit = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING)
    rng = np.random.default_rng(6)
    kins = [Kinematics(robot, robot.configuration("walk_ready")) for _ in range(2)]
    most = limit.max_rows
    buffers = [(np.zeros((most + 2, robot.nv)), np.zeros(most + 2)) for _ in range(2)]
    q = robot.configuration("walk_ready")
    seen = 0
    for t in range(12):
        q = robot.clip_to_limits(robot.integrate(q, np.r_[np.zeros(6), rng.normal(0, 0.05, 18)]))
        kin = kins[t // 6]
        kin.update(q)
        G, h = buffers[t % 2]
        m = limit.rows_into(kin, G, h, 1)
        want = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING).compute(
            Kinematics(robot, q)
        )
        assert m == want.h.size
        assert np.array_equal(G[1 : 1 + m], want.G) and np.array_equal(h[1 : 1 + m], want.h)
        seen += m
    assert seen > 0
    from wbc.limits.collision_packed import packed_rows

    entries = list(limit._entries.values())
    assert len(entries) == 2 and all(e[0] is not packed_rows for e in entries)  # (entry points)


def _model_and_pairs(robot, lim):
    from wbc.limits.self_collision import _cached_collision_model

    cm = _cached_collision_model(robot)
    return cm, lim.distances.pairs


@given(d=st.floats(-0.01, 0.0199), eps=st.floats(1e-7, 1e-4))
@example(d=0.01556, eps=1e-6)  # stress trial 5101's pair with common_frame (uncapped: 1.35)
def test_damper_bound_is_continuous_monotone_and_keeps_the_margin(d, eps):
    """h is increasing and Lipschitz (constant max(ξ, c²/ξ), c = MAX_CLOSURE) everywhere
    below the trigger, and never allows a tick to close more than c of the gap to the margin
    (h(d) <= c (d − m) for m <= d < T: the linearised margin holds wherever the pair starts,
    not only below T − ξ (T − m)); at the trigger the row appears with h = c (T − m), finite,
    and no row at or beyond it. The uncapped damper (→ +∞ at T) fails all three."""
    h = damper_bound(np.array([d, d + eps]), MARGIN, TRIGGER, DAMPING)
    assert h[1] >= h[0]  # monotone
    if d + eps < TRIGGER:  # continuous: Lipschitz up to the trigger
        slope = max(DAMPING, MAX_CLOSURE**2 / DAMPING)
        assert h[1] - h[0] <= slope * eps * (1 + 1e-6) + 1e-15
    if MARGIN <= d < TRIGGER:  # the linearised margin holds, with room to spare
        assert h[0] <= MAX_CLOSURE * (d - MARGIN) * (1 + 1e-12) + 1e-15
    assert damper_bound(np.array([TRIGGER]), MARGIN, TRIGGER, DAMPING)[0] == np.inf
    below = damper_bound(np.array([TRIGGER - 1e-9]), MARGIN, TRIGGER, DAMPING)[0]
    assert below == pytest.approx(MAX_CLOSURE * (TRIGGER - 1e-9 - MARGIN), rel=1e-12)


# ---------------------------------------------------------------------- in the solvers
SCENARIOS = {  # the moving frame, pulled towards the other link's origin
    "arm_into_torso": ("l_hand", "torso"),
    # (was r_thigh onto l_thigh's origin: reached by shifting the pelvis, the thigh boxes 37
    # mm apart; only the hip bracket / thigh pair bound there, adjacent through the
    # zero-length link of the hip roll and no longer checked)
    "knees_together": ("r_shin", "l_shin"),
    "foot_into_other_shin": ("r_sole", "l_shin"),
}


def _pull(robot, limit, scenario, level, weighted, seed, ticks=130):
    """Left sole held; the collision rows at ``level``; a target moving at <= 0.1 m/s from
    the moving frame into the other link at the level below (CoM held above at level 1 when
    the rows are at level 2). Returns (smallest distance over the run, final distance)."""
    rng = np.random.default_rng(seed)
    q = robot.configuration("walk_ready")
    q[7:] += rng.uniform(-0.02, 0.02, robot.n_joints)
    q = robot.place_on_ground(robot.clip_to_limits(q), "l_sole")
    kin = Kinematics(robot, q)
    assert limit.min_distance(kin) > MARGIN
    stack = TaskStack(robot)
    stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
    if level >= 2:
        # the CoM held, and the free sole's orientation (as a walk stack's swing-foot task at
        # the CoM's level): alone, the CoM level swings the free leg at servo speed (0.06
        # rad per tick) to balance the pull, and a foot turning that fast dips up to 0.3 mm
        # per tick below its first-order row (the second order of a linearised tick)
        stack.add(ComTask(robot, kin.com.copy()), level=1)
        sole = stack.add(FrameOrientationTask(robot, "r_sole"), level=1)
        sole.set_target(kin.rotation(robot.frame_id("r_sole")))
    stack.add_constraint(limit, level=level)
    mover, other = SCENARIOS[scenario]
    task = stack.add(FramePositionTask(robot, mover), level=level + 1)
    start = kin.translation(robot.frame_id(mover)).copy()
    goal = kin.translation(robot.frame_id(other)) + rng.uniform(-0.01, 0.01, 3)
    stack.add(PostureTask(robot, q), level=level + 1, weight=1e-4)
    solver = (WeightedQP if weighted else HierarchicalQP)(stack)
    smallest = np.inf
    active = 0
    for k in range(ticks):
        task.set_target(start + min(1.0, k / 100) * (goal - start))
        q = solver.step(q, dt=0.01)
        active += bool(solver.fast.inequalities.working.any())
        kin.update(q)
        smallest = min(smallest, limit.min_distance(kin))
    assert active > 0  # the rows were active (in the compiled active set)
    return smallest, limit.min_distance(kin)


@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
@pytest.mark.parametrize("level,weighted", [(0, False), (1, False), (2, False), (1, True)])
def test_pulled_links_never_come_closer_than_the_margin(robot, limit, scenario, level, weighted):
    smallest, final = _pull(robot, limit, scenario, level, weighted, seed=level)
    assert smallest > MARGIN - LINEARISATION
    assert final > MARGIN - 1e-4


@pytest.mark.parametrize("seed", [7, 9, 10])
def test_pulled_knees_keep_the_margin_on_other_seeds(robot, limit, seed):
    """The pull above with other seeds (the same law), the feet (l_foot_0 / r_foot_0) with
    parallel faces. The corner rows once paired each corner with the witness point on the
    other foot (the plane held still about it): a tick turning that foot's face let a far
    corner through, 0.73-0.86 mm inside the margin on these seeds (strict xfail until
    2026-12-05). Each corner's row is now the derivative of its gap to the other box's face
    (paired with its own projection there): they keep the margin."""
    smallest, _ = _pull(robot, limit, "knees_together", 0, False, seed=seed)
    assert smallest > MARGIN - LINEARISATION


def test_without_the_limit_the_same_pulls_collide(robot, limit):
    """The scenarios do drive links into each other (the test above can fail)."""
    for scenario in SCENARIOS:
        rng = np.random.default_rng(0)
        q = robot.configuration("walk_ready")
        q[7:] += rng.uniform(-0.02, 0.02, robot.n_joints)
        q = robot.place_on_ground(robot.clip_to_limits(q), "l_sole")
        kin = Kinematics(robot, q)
        stack = TaskStack(robot)
        stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
        mover, other = SCENARIOS[scenario]
        task = stack.add(FramePositionTask(robot, mover), level=1)
        start = kin.translation(robot.frame_id(mover)).copy()
        goal = kin.translation(robot.frame_id(other)) + rng.uniform(-0.01, 0.01, 3)
        stack.add(PostureTask(robot, q), level=1, weight=1e-4)
        solver = HierarchicalQP(stack)
        for k in range(130):
            task.set_target(start + min(1.0, k / 100) * (goal - start))
            q = solver.step(q, dt=0.01)
        assert limit.min_distance(Kinematics(robot, q)) < 0.0, scenario


@pytest.mark.parametrize("kind", ["hierarchical", "weighted"])
def test_inactive_when_every_pair_is_far(robot, kind):
    """No rows, no cost: the same Δq, bit for bit, as without the limit. (q = 0: legs
    straight, arms sideways; the hip blocks stay 13 mm under the torso whatever the pose, so
    this limit's trigger is 8 mm.)"""
    limit = SelfCollisionConstraint(robot, margin=0.002, trigger=0.008)
    q = robot.configuration("zero")
    kin = Kinematics(robot, q)
    assert limit.min_distance(kin) > limit.trigger
    dqs = []
    for with_limit in (True, False):
        stack = TaskStack(robot)
        stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
        if with_limit:
            stack.add_constraint(limit, level=0)
        stack.add(
            FramePositionTask(
                robot, "r_sole", kin.translation(robot.frame_id("r_sole")) + [0.0, 0.01, 0.01]
            ),
            level=1,
        )
        stack.add(PostureTask(robot, robot.configuration("walk_ready")), level=2, weight=1e-2)
        solver = (HierarchicalQP if kind == "hierarchical" else WeightedQP)(stack)
        dqs.append(solver.solve(q, dt=0.01))
        assert solver.handed_back_ticks == 0
    assert limit.compute(kin).h.size == 0
    assert np.array_equal(dqs[0], dqs[1])


def _solve(robot, limit, q, kind):
    kin = Kinematics(robot, q)
    stack = TaskStack(robot)
    stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
    stack.add(ContactTask(robot, "r_sole"), level=0).make_contact(kin)
    if limit is not None:
        stack.add_constraint(limit, level=0)
    hand = stack.add(FramePositionTask(robot, "l_hand"), level=1)
    hand.set_target(kin.translation(robot.frame_id("l_hand")) + [0.0, -0.1, 0.0])
    stack.add(PostureTask(robot, q), level=2, weight=1e-3)
    solver = (HierarchicalQP if kind == "hierarchical" else WeightedQP)(stack)
    return solver.solve(q)  # no time step: the hand asks for a 10 cm step


def _onset_jump(robot, limit, kind) -> float:
    """Lower the left arm towards the torso; ‖Δq_limit − Δq_free‖ at the first configuration
    where the limit changes Δq, after bisecting the onset to 1e-7 rad of shoulder roll."""
    base = robot.configuration("walk_ready")
    roll = robot.q_index("l_shoulder_roll")

    def effect(a):
        q = base.copy()
        q[roll] = a
        return np.linalg.norm(_solve(robot, limit, q, kind) - _solve(robot, None, q, kind))

    angles = base[roll] + np.linspace(1.3, 0.2, 45)
    q0 = base.copy()
    q0[roll] = angles[0]
    assert limit.min_distance(Kinematics(robot, q0)) > TRIGGER  # no rows at the start
    effects = [effect(a) for a in angles]
    assert effects[0] == 0.0 and max(effects) > 0.01  # the limit ends up binding
    i = next(k for k, e in enumerate(effects) if e > 0)
    lo, hi = angles[i - 1], angles[i]
    while abs(hi - lo) > 1e-7:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if effect(mid) > 0 else (mid, hi)
    return effect(hi)


@pytest.mark.parametrize("kind", ["weighted", "hierarchical"])
def test_solution_is_continuous_as_a_pair_crosses_the_trigger(robot, kind):
    """The smooth activation changes Δq continuously from zero where the arm–torso rows
    start to bind; a plain on/off damper (same rows, h = ξ (gap − m) below the trigger)
    jumps where the pair crosses the trigger."""
    pair = [["torso", "l_upper_arm"]]
    smooth = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING, pairs=pair)
    switch = _OnOff(robot, MARGIN, TRIGGER, DAMPING, pairs=pair)
    assert _onset_jump(robot, smooth, kind) < 1e-4
    assert _onset_jump(robot, switch, kind) > 1e-2


class _OnOff(SelfCollisionConstraint):
    """The textbook damper with a hard switch at the trigger: −J Δq <= ξ (gap − m)."""

    def compute(self, kin):
        w = self.last = self.witness(kin)
        pr = separating_plane_rows(w, self.distances.vertices(kin, w.index.tolist()), 1.0)
        k = w.index[pr.pair]
        masks = joint_masks(self.robot)
        J = distance_jacobian(
            kin.data.J,
            masks[self.distances.joint_1[k]],
            masks[self.distances.joint_2[k]],
            pr.a,
            pr.b,
            pr.normal,
        )
        keep = pr.gap < self.trigger
        return Inequality(-J[keep], self.damping * (pr.gap[keep] - self.margin))


# ---------------------------------------------------------------------- stack files
def _spec(level):
    levels = [
        {"hard": True, "tasks": [{"type": "contact", "frame": "support"}]},
        {"tasks": [{"type": "com"}]},
        {"tasks": [{"type": "posture", "weight": 0.01}]},
    ]
    levels[level].setdefault("constraints", []).append(
        {"type": "self_collision", "margin": 0.004, "trigger": 0.015, "damping": 0.5}
    )
    return {"name": "sc", "solver": "hierarchical", "levels": levels}


@pytest.mark.parametrize("level", [0, 1, 2])
def test_stack_file_type_at_any_level(robot, level):
    control = build_stack(_spec(level), robot)
    c = control.stack.constraint("self_collision")
    assert isinstance(c, SelfCollisionConstraint)
    assert (c.margin, c.trigger, c.damping) == (0.004, 0.015, 0.5)
    assert c in control.stack.level(level).constraints
    q = robot.configuration("walk_ready")
    control.solver.step(q, 0.01)


def test_stack_file_bad_keys_and_values(robot):
    spec = _spec(0)
    spec["levels"][0]["constraints"][0]["radius"] = 1.0
    with pytest.raises(TaskError, match=r"self_collision.*unknown keys \['radius'\]"):
        build_stack(spec, robot)
    spec = _spec(0)
    spec["levels"][0]["constraints"][0]["trigger"] = 0.001
    with pytest.raises(TaskError, match=r"trigger .* must be larger than the margin"):
        build_stack(spec, robot)
    spec = _spec(0)
    spec["levels"][0]["constraints"][0]["common_frame"] = "yes"
    with pytest.raises(TaskError, match=r"common_frame must be true or false, got 'yes'"):
        build_stack(spec, robot)
    spec["levels"][0]["constraints"][0]["common_frame"] = True
    assert build_stack(spec, robot).stack.constraint("self_collision")._params[4] == 1.0


def test_walk_with_the_limit_is_the_same_compiled_or_not(robot):
    """Ticks with binding collision rows are solved by the compiled cascade too; the walk is
    the same on the numpy path (the same algorithm)."""
    ref = build("walk10", robot)
    recordings, back = {}, {}
    for compiled in (True, False):
        controller = StackController(load_stack("walk", robot))
        controller.solver.compiled = compiled
        recordings[compiled] = run(controller, robot, ref)
        back[compiled] = controller.solver.handed_back_ticks
    # (none today: an active set that cycles on dependent collision rows would be given up
    # early by the kernels and solved by DAQP)
    assert back[True] <= ref.n // 100
    assert np.abs(recordings[True].q - recordings[False].q).max() < 1e-5
    kin = Kinematics(robot)
    limit = SelfCollisionConstraint(robot, 0.005, 0.02)
    closest = np.inf
    for q in recordings[True].q[::5]:
        kin.update(q)
        closest = min(closest, limit.min_distance(kin))
    assert closest > 0.005 - LINEARISATION


def test_walk_stack_has_the_limit_with_its_hard_level(robot):
    control = load_stack("walk", robot)
    c = control.stack.constraint("self_collision")
    assert c in control.stack.level(0).constraints and control.stack.level(0).hard
    assert (c.margin, c.trigger) == (0.005, 0.02)


@given(seed=st.integers(0, 10_000))
def test_recovering_rows_hold_the_pairs_at_the_margin_itself(robot, limit, seed):
    """split(recovering=True) (an infeasible tick's re-solve): the rows of the pairs outside
    the margin at max(h(d), gap − margin) — down to the margin in one step, never into it
    (to first order) — and the same requests of the pairs inside."""
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    kin = Kinematics(robot, q)
    (G, h), (Gi, hi) = limit.split(kin)
    (G_r, h_r), (Gi_r, hi_r) = limit.split(kin, recovering=True)
    np.testing.assert_array_equal(G, G_r)
    np.testing.assert_array_equal(Gi, Gi_r)
    np.testing.assert_array_equal(hi, hi_r)
    assert (h >= 0).all() and (h_r >= h).all()
    # the witness row of a pair outside the margin, where the damper is the stricter
    # (h(d) <= d − margin), holds it at the margin itself: −J_d Δq <= d − margin
    knee = TRIGGER - DAMPING * (TRIGGER - MARGIN)
    for d in limit.last.distance.tolist():
        if MARGIN <= d <= knee:
            assert np.isclose(h_r, d - MARGIN, rtol=0, atol=1e-12).any()


def _feet_inside_the_margin(robot) -> np.ndarray:
    """The standing pose with the legs rolled inwards, the soles flat: the feet 3.2 mm apart."""
    q = robot.configuration("stand")
    for joint, sign in (("hip_roll", -1), ("ankle_roll", 1)):
        q[7 + robot.joint_names.index(f"l_{joint}")] += sign * 0.07
        q[7 + robot.joint_names.index(f"r_{joint}")] -= sign * 0.07
    return q


@pytest.mark.parametrize("double", [True, False])
def test_a_hard_pair_held_inside_its_margin_raises_naming_it(robot, double):
    """Both soles in hard contact fix the feet 3.2 mm apart, inside the 5 mm margin: no tick
    can bring them back, and within RECOVERY_TICKS ticks the solve raises InfeasibleError
    naming the pair (never a silent result); with one sole free the pair moves back out."""
    q = _feet_inside_the_margin(robot)
    kin = Kinematics(robot, q)
    limit = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING)
    assert limit.min_distance(kin) < MARGIN - RECOVERY_TOL
    stack = TaskStack(robot)
    stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
    if double:
        stack.add(ContactTask(robot, "r_sole"), level=0, hard=True).make_contact(kin)
    stack.add_constraint(limit, level=0)
    stack.add(PostureTask(robot, q), level=1)
    solver = HierarchicalQP(stack)
    if double:
        with pytest.raises(InfeasibleError, match=r"l_foot / r_foot .* for more than 25 ticks"):
            for _ in range(RECOVERY_TICKS + 1):
                q = solver.step(q, 0.02)
    else:
        for _ in range(RECOVERY_TICKS + 1):
            q = solver.step(q, 0.02)
        assert limit.min_distance(Kinematics(robot, q)) > MARGIN - RECOVERY_TOL


def test_the_packed_call_follows_its_own_buffers_through_copies(robot):
    """The limit passes its buffers to the kernel by address: a deep copy (a stack copied, a
    plan pickled) computes from its own buffers (the same rows as the original, which keeps
    its own), a second call at the same configuration returns the same rows without
    computing, and the views a compiled plan copies are those rows."""
    import copy

    limit = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING)
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    rows = limit.compute(kin)
    assert rows.h.size > 0  # (arms beside the torso: rows)
    assert limit.compute(kin) is rows  # (same configuration: kept)
    G, h = limit.rows_view(kin)
    assert np.array_equal(G, rows.G) and np.array_equal(h, rows.h)
    twin = copy.deepcopy(limit)
    moved = q.copy()
    moved[7:] += 0.05
    kin_2 = Kinematics(robot, moved)
    theirs = twin.compute(kin_2)
    assert limit.compute(kin) is rows  # (the copy wrote none of the original's buffers)
    assert np.array_equal(limit.rows_view(kin)[1], rows.h)
    mine = limit.compute(kin_2)
    assert np.array_equal(mine.G, theirs.G) and np.array_equal(mine.h, theirs.h)
    assert not np.array_equal(mine.h, rows.h) or mine.h.size != rows.h.size


def test_a_subclass_computing_its_own_rows_gives_them_to_a_compiled_plan(robot):
    """``rows_view`` of a subclass that overrides :meth:`compute` gives that compute's rows."""

    class Halved(SelfCollisionConstraint):
        def compute(self, kin):
            rows = super().compute(kin)
            return Inequality(rows.G, rows.h / 2)

    limit = Halved(robot, MARGIN, TRIGGER, DAMPING)
    kin = Kinematics(robot, robot.configuration("walk_ready"))
    G, h = limit.rows_view(kin)
    plain = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING).compute(kin)
    assert np.array_equal(G, plain.G) and np.array_equal(h, plain.h / 2)


def test_forgotten_rows_are_computed_again_the_same(robot):
    """forget_rows: the next call at the same configuration runs the kernel again (a
    rehearsed first tick runs its code) and gives the same rows bit for bit."""
    limit = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING)
    kin = Kinematics(robot, robot.configuration("walk_ready"))
    rows = limit.compute(kin)
    exact = limit.distances.exact_computations
    assert limit.compute(kin) is rows and limit.distances.exact_computations == exact
    limit.forget_rows()
    again = limit.compute(kin)
    assert again is not rows and limit.distances.exact_computations > exact
    assert np.array_equal(again.G, rows.G) and np.array_equal(again.h, rows.h)


def test_rows_written_into_a_plans_buffer_are_the_rows_and_found_there(robot):
    """``rows_into``: the rows of :meth:`compute` written at a row offset of the caller's
    buffers (a compiled plan's: no copy), nothing outside them touched; at the same
    configuration, into other buffers, the same rows (copied from where they are, the
    kernel not run); :meth:`compute` and ``rows_view`` find them too; a buffer with less
    room than the limit's most rows raises and is left as it was."""
    q = robot.configuration("walk_ready")
    q[7:] += np.random.default_rng(3).uniform(-0.2, 0.2, robot.nv - 6)
    kin = Kinematics(robot, q)
    reference = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING).compute(kin)
    m = reference.h.size
    assert m > 0
    limit = SelfCollisionConstraint(robot, MARGIN, TRIGGER, DAMPING)
    most, r0 = limit.max_rows, 5
    G, h = np.full((r0 + most + 3, robot.nv), 7.0), np.full(r0 + most + 3, 7.0)
    assert limit.rows_into(kin, G, h, r0) == m
    assert np.array_equal(G[r0 : r0 + m], reference.G) and np.array_equal(
        h[r0 : r0 + m], reference.h
    )
    assert (G[:r0] == 7.0).all() and (h[:r0] == 7.0).all()
    assert (G[r0 + m :] == 7.0).all() and (h[r0 + m :] == 7.0).all()
    exact = limit.distances.exact_computations
    G2, h2 = np.zeros((most, robot.nv)), np.zeros(most)
    assert limit.rows_into(kin, G2, h2, 0) == m
    assert np.array_equal(G2[:m], reference.G) and np.array_equal(h2[:m], reference.h)
    rows = limit.compute(kin)
    assert np.array_equal(rows.G, reference.G) and np.array_equal(rows.h, reference.h)
    Gv, hv = limit.rows_view(kin)
    assert np.array_equal(Gv, reference.G) and np.array_equal(hv, reference.h)
    assert limit.distances.exact_computations == exact  # (found, not computed again)
    small_G, small_h = np.full((most - 1, robot.nv), 7.0), np.full(most - 1, 7.0)
    moved = q.copy()
    moved[7:] += 0.01
    with pytest.raises(ConfigurationError, match="room"):
        limit.rows_into(Kinematics(robot, moved), small_G, small_h, 0)
    assert (small_G == 7.0).all() and (small_h == 7.0).all()
    with pytest.raises(ConfigurationError, match="room"):
        limit.rows_into(kin, G, h, r0 + 4)  # (r0 + most overruns G)


def test_a_compiled_plan_holds_the_limits_rows_in_place(robot):
    """Along a walk, each tick's self-collision rows in the compiled plan's buffers are the
    limit's rows at that tick's configuration (computed afresh by another limit), and the
    plan's buffers have room for the limit's most rows (what the in-place write needs)."""
    from wbc.solvers.plan import _Plan

    ref = build("walk10", robot)
    control = load_stack("walk_strict", robot)
    controller = StackController(control)
    limit = next(c for c in control.stack.constraints() if isinstance(c, SelfCollisionConstraint))
    fresh = SelfCollisionConstraint(robot, limit.margin, limit.trigger, limit.damping)
    seen = []
    solve = _Plan.solve

    def checked(plan, kin, dt):
        status = solve(plan, kin, dt)
        if limit in plan.constraints.items and len(seen) < 150:
            blocks = plan.constraints.level_blocks()
            k = next(i for i, lv in enumerate(plan.constraints.levels) if limit in lv)
            G, h, slices = blocks[k]
            sl = dict(slices)[limit.name]
            rows = fresh.compute(kin)
            assert np.array_equal(G[sl], rows.G) and np.array_equal(h[sl], rows.h)
            assert plan.inequalities.h.shape[0] >= limit.max_rows
            seen.append(rows.h.size)
        return status

    _Plan.solve = checked
    try:
        run(controller, robot, ref)
    finally:
        _Plan.solve = solve
    assert len(seen) == 150 and max(seen) > 0
