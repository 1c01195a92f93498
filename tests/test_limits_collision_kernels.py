"""The compiled box–box distances and self-collision rows (wbc.limits.collision_kernels)
against coal (hpp-fcl) and against the numpy forms of the rows."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from wbc import Kinematics
from wbc.limits import SelfCollisionConstraint
from wbc.limits.collision_kernels import box_distance
from wbc.limits.collision_reference import distance_jacobian, joint_masks, separating_plane_rows
from wbc.limits.self_collision import (
    UNREACHABLE,
    _cached_collision_model,
    damper_bound,
)

#: the distances agree with coal's to this (m), coal's GJK/EPA run to 1e-13
EXACT = 1e-9


def _coal_request() -> coal.DistanceRequest:
    request = coal.DistanceRequest()
    request.gjk_tolerance = 1e-13
    request.epa_tolerance = 1e-13
    return request


def _rotation(rng: np.random.Generator) -> np.ndarray:
    return pin.Quaternion(*rng.normal(size=4)).normalized().toRotationMatrix()


def _assert_the_numpy_forms_rows(robot, limit, kin, w, G, h) -> None:
    """``G``, ``h`` (the constraint's rows at ``kin``, witness ``w``) are the numpy form's:
    separating_plane_rows' features, distance_jacobian, damper_bound (to 1e-12)."""
    pr = separating_plane_rows(w, limit.distances.vertices(kin, w.index.tolist()), limit.trigger)
    masks = joint_masks(robot)
    k = w.index[pr.pair]
    pd = limit.distances
    common = bool(limit._params[4])  # (the rows' normal in the pair's common frame)
    J = distance_jacobian(
        kin.data.J, masks[pd.joint_1[k]], masks[pd.joint_2[k]], pr.a, pr.b, pr.normal, common
    )
    hb = damper_bound(pr.gap, limit.margin, limit.trigger, limit.damping)
    keep = hb < UNREACHABLE
    np.testing.assert_allclose(G, -J[keep], atol=1e-12)
    np.testing.assert_allclose(h, hb[keep], atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), parallel=st.sampled_from(["no", "exact", "nearly"]))
def test_box_distance_is_coals(seed, parallel):
    """Signed distance of two random boxes (parallel faces, exactly or to 1e-9 rad, two
    times in three: the feet side by side) = coal's, separated (GJK) or overlapping (the
    separating-axis depth against EPA); the witnesses lie on their boxes with
    nᵀ(p2 − p1) = d, |n| = 1."""
    rng = np.random.default_rng(seed)
    h1, h2 = rng.uniform(0.005, 0.05, 3), rng.uniform(0.005, 0.05, 3)
    R1 = _rotation(rng)
    R2 = _rotation(rng) if parallel == "no" else R1.copy()
    if parallel == "nearly":  # (an edge pair's 1 − (u·w)² rounds to 0)
        R2 = R2 @ pin.exp3(rng.normal(size=3) * 1e-9)
    c1, c2 = rng.uniform(-0.05, 0.05, 3), rng.uniform(-0.05, 0.05, 3)
    p1, p2, n = np.zeros(3), np.zeros(3), np.zeros(3)
    d = box_distance(R1, c1, h1, R2, c2, h2, p1, p2, n)
    result = coal.DistanceResult()
    expected = coal.distance(
        coal.Box(*(2 * h1)),
        coal.Transform3s(R1, c1),
        coal.Box(*(2 * h2)),
        coal.Transform3s(R2, c2),
        _coal_request(),
        result,
    )
    assert d == pytest.approx(expected, abs=EXACT)
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
    assert n @ (p2 - p1) == pytest.approx(d, abs=1e-12)
    if d > 0:  # the closest points: on the boxes, d apart
        for p, R, c, h in ((p1, R1, c1, h1), (p2, R2, c2, h2)):
            assert np.all(np.abs(R.T @ (p - c)) <= h + 1e-12)
        assert np.linalg.norm(p2 - p1) == pytest.approx(d, abs=1e-12)


def test_robot_pair_distances_are_coals(robot):
    """Every pair of the default limit at random configurations: our distances (the broad
    phase off: query +inf) = pinocchio's computeDistances through coal, to 1e-9 m."""
    limit = SelfCollisionConstraint(robot)
    pd = limit.distances
    cm = _cached_collision_model(robot)
    geometry = cm.geometry.copy()
    geometry.removeAllCollisionPairs()
    for i, j in pd.pairs:
        geometry.addCollisionPair(pin.CollisionPair(i, j))
    gdata = pin.GeometryData(geometry)
    for request in gdata.distanceRequests:
        request.gjk_tolerance = request.epa_tolerance = 1e-13
    rng = np.random.default_rng(7)
    data = robot.model.createData()
    for _ in range(20):
        q = robot.random_configuration(rng)
        w = pd.below(Kinematics(robot, q), np.inf)
        pin.computeDistances(robot.model, data, geometry, gdata, q)
        expected = np.array([r.min_distance for r in gdata.distanceResults])
        assert np.array_equal(w.index, np.arange(len(pd.pairs)))
        np.testing.assert_allclose(w.distance, expected, rtol=0, atol=EXACT)


def test_broad_phase_skips_far_pairs_and_misses_no_close_one(robot):
    """Along a random walk of the joints: the pairs below the trigger are those of the exact
    distances, while most pairs never reach the exact computation."""
    limit = SelfCollisionConstraint(robot)
    fresh = SelfCollisionConstraint(robot).distances
    rng = np.random.default_rng(2)
    q = robot.configuration("stand")
    steps = 60
    for _ in range(steps):
        q[7:] = np.clip(q[7:] + rng.normal(0, 0.02, robot.n_joints), robot.q_min, robot.q_max)
        kin = Kinematics(robot, q)
        close = limit.distances.below(kin, limit.trigger)
        exact = fresh.below(kin, np.inf)
        wanted = exact.distance < limit.trigger
        assert np.array_equal(close.index, exact.index[wanted])
        np.testing.assert_allclose(close.distance, exact.distance[wanted], atol=1e-12)
    assert limit.distances.exact_computations < 0.2 * steps * len(limit.distances.pairs)
    # a pair's last separating axis is tried first: the 15 axes' gap is computed again for
    # few pairs but those kept for their exact distance (without it: every pair the spheres
    # do not turn away)
    counts = limit.distances._counts
    assert counts[1] < 1.2 * counts[0]


@pytest.mark.parametrize("common_frame", [False, True])
@pytest.mark.parametrize("seed", range(6))
def test_compiled_rows_are_the_numpy_rows(robot, seed, common_frame):
    """The compiled rows (witness and corner rows, Jacobians, damper bounds) equal those of
    the numpy forms (separating_plane_rows, distance_jacobian, damper_bound) on the same
    witnesses, at configurations where pairs are within the trigger; with the rows' normal
    in the pair's common frame too."""
    rng = np.random.default_rng(seed)
    limit = SelfCollisionConstraint(robot, common_frame=common_frame)
    q = robot.configuration("stand")
    q[7:] = np.clip(q[7:] + rng.normal(0, 0.3, robot.n_joints), robot.q_min, robot.q_max)
    kin = Kinematics(robot, q)
    G, h = limit.compute(kin)
    w = limit.witness(kin)
    assert w.index.size  # (pairs within the trigger at these seeds)
    _assert_the_numpy_forms_rows(robot, limit, kin, w, G, h)


#: floats / ints past the end of the kernels' scratch, each set to a value no kernel writes
GUARD, F_SENTINEL, I_SENTINEL = 64, -1.2345e300, -987_654_321


def _guarded_scratch(limit, short: int) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The limit's scratch replaced, before its first compute, by views ``short`` elements
    shorter than :func:`~wbc.limits.collision_kernels.work_sizes` of buffers whose
    remainder (``GUARD`` past the full size) holds sentinels: the compiled kernels do not
    check their bounds, and what they write past a view's end lands there. Returns the
    float and int buffers and the lengths of the views."""
    pd = limit.distances
    n, ni = pd._work.size - short, pd._iwork.size - short
    work = np.full(n + short + GUARD, F_SENTINEL)
    iwork = np.full(ni + short + GUARD, I_SENTINEL, np.int64)
    work[:n], iwork[:ni] = 0.0, 0  # (the scratch as the limit makes it)
    pd._work, pd._iwork = work[:n], iwork[:ni]
    limit._packed = None  # (the packed kernel's addresses: taken at the next compute)
    return work, iwork, n, ni


@pytest.mark.parametrize("short", [0, 1])
def test_the_kernels_scratch_holds_every_pair_close(robot, short):
    """A trigger past every pair's distance (1 m: every pair close, the witness and 16
    corners' rows each at most): the kernels write nothing past the limit's own scratch
    (its size :func:`~wbc.limits.collision_kernels.work_sizes`: the kernels allocate nothing
    in a tick; sentinels after it, unchanged) and its rows are the numpy form's; a second
    configuration reuses the same scratch. One element shorter (``short=1``) and both
    scratches overflow into the sentinels: the check can fail, and the sizes are the least
    that hold the last pair's rows."""
    limit = SelfCollisionConstraint(robot, trigger=1.0, samples=0)
    work, iwork, n, ni = _guarded_scratch(limit, short)
    rng = np.random.default_rng(5)
    for q in (robot.configuration("stand"), robot.random_configuration(rng)):
        kin = Kinematics(robot, q)
        G, h = limit.compute(kin)
        w = limit.witness(kin)
        assert w.index.size == limit.n_pairs
        assert h.size > 8 * limit.n_pairs
        past = (work[n:] != F_SENTINEL).any(), (iwork[ni:] != I_SENTINEL).any()
        if short:
            assert past == (True, True)
            return
        assert past == (False, False)
        _assert_the_numpy_forms_rows(robot, limit, kin, w, G, h)


def _rows_around(limit, robot, q, rng, draws, size):
    """The rows at q and at ``draws`` configurations ``size`` rad away in random directions:
    (rows at q, the largest change of G or h, the largest jump of a witness point (m)). A
    row's change of h is counted over its damper's slope dh/dd where that exceeds 1: near the
    trigger T the bound h(d) = ξ(d − m)(T − m)/(T − d) is steep by design (ξ(T − m)²/(T − d)²,
    ~5600ξ at 0.2 mm inside it), so a continuous row's h moves by that slope times the
    distance's change (O(size))."""
    limit.forget_rows()
    kin = Kinematics(robot, q)
    G0, h0 = (a.copy() for a in limit.compute(kin))
    w0 = limit.last
    span, xi = limit.trigger - limit.margin, limit.damping
    gap = np.where(h0 > 0, h0 * span / (xi * span + np.maximum(h0, 0.0)), 0.0)  # h⁻¹: d − m
    slope = np.maximum(1.0, xi * span**2 / (span - gap) ** 2)
    change = jump = 0.0
    for _ in range(draws):
        limit.forget_rows()
        G, h = limit.compute(
            Kinematics(robot, robot.integrate(q, rng.normal(size=robot.nv) * size))
        )
        assert G.shape == G0.shape  # (no row comes or goes)
        change = max(change, np.abs(G - G0).max(), (np.abs(h - h0) / slope).max())
        w = limit.last
        assert np.array_equal(w.index, w0.index)
        jump = max(jump, np.abs(w.p1 - w0.p1).max(), np.abs(w.p2 - w0.p2).max())
    return (G0, h0), change, jump


@settings(max_examples=15, deadline=None)
@given(pitch=st.floats(-0.6, 0.6), seed=st.integers(0, 2**16))
@example(pitch=0.453125, seed=0)  # (a row 0.2 mm inside the trigger: h steep there)
def test_rows_are_continuous_where_faces_are_parallel(robot, pitch, seed):
    """The arms beside the torso and the feet side by side have parallel features (a face
    along a face or an edge): any point of their overlap is a witness, and the last bits of
    q pick which (the torso / l_upper_arm witness jumps by up to 32 mm for a 1e-12 rad
    change: walk10's tick 166, benchmarks/self_collision.md). The rows do not: q moved by
    1e-12 rad changes G and h by O(1e-12) (main: G by 0.063, a row more or less)."""
    rng = np.random.default_rng(seed)
    limit = SelfCollisionConstraint(robot)
    q = robot.configuration("stand")
    for side in "lr":  # (the shoulder pitch keeps the arm's edge along the torso's face)
        q[7 + robot.joint_names.index(f"{side}_shoulder_pitch")] = pitch
    (G0, _), change, _ = _rows_around(limit, robot, q, rng, draws=12, size=1e-12)
    assert G0.shape[0] > 0
    assert change < 1e-10
    # the rows are the numpy form's at such a tie too
    kin = Kinematics(robot, q)
    limit.forget_rows()
    G, h = limit.compute(kin)
    w = limit.last
    _assert_the_numpy_forms_rows(robot, limit, kin, w, G, h)


def test_the_tie_is_there_and_the_witness_jumps(robot):
    """The case above is a tie (the test can fail): at the standing pose the torso / arm
    witnesses move by millimetres for a 1e-12 rad change of q, the rows by ~1e-12."""
    limit = SelfCollisionConstraint(robot, pairs=[["torso", "l_upper_arm"]])
    q = robot.configuration("stand")
    _, change, jump = _rows_around(limit, robot, q, np.random.default_rng(0), 30, 1e-12)
    assert jump > 1e-3
    assert change < 1e-10


@pytest.mark.parametrize("pitch", [-0.4, 0.0, 0.4])
def test_rows_in_the_common_frame_leave_the_base_alone(robot, pitch):
    """The arm beside the torso (walk_strict's slow ticks, benchmarks/self_collision.md ninth
    pass): the torso's corners' rows pair each with an arm point beside it, across n, so in
    the world frame a rotation of the base moves their gaps (non-zero base columns, up to
    ~0.06); with ``common_frame`` the columns of the joints that carry both links are 0 and
    the rest of each row is the world frame's."""
    q = robot.configuration("stand")
    q[7 + robot.joint_names.index("l_shoulder_pitch")] = pitch
    kin = Kinematics(robot, q)
    rows = {}
    for common in (False, True):
        limit = SelfCollisionConstraint(
            robot, pairs=[["torso", "l_upper_arm"]], common_frame=common
        )
        G, h = (a.copy() for a in limit.compute(kin))
        _assert_the_numpy_forms_rows(robot, limit, kin, limit.last, G, h)
        rows[common] = G, h
    (G0, h0), (G1, h1) = rows[False], rows[True]
    assert G0.shape == G1.shape and np.array_equal(h0, h1)
    assert np.abs(G0[:, :6]).max() > 1e-2  # (the world frame's rows move with the base)
    assert np.abs(G1[:, :6]).max() == 0.0
    np.testing.assert_array_equal(G1[:, 6:], G0[:, 6:])
