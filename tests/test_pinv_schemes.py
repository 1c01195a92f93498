"""Walking schemes of ch. 4: VAT, CJ, VATL, CJL (wbc.pinv.schemes)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from wbc.exceptions import ConfigurationError
from wbc.limits.joint_costs import zghal_cost
from wbc.pinv import (
    SCHEME_NAMES,
    ThesisScheme,
    run_walking_benchmark,
    settled_start,
    thesis_like_step,
    track_step,
)


@pytest.fixture(scope="module")
def q0(robot):
    """Walk Ready with the torso made upright, so every task holds at the first pose."""
    return settled_start(robot, robot.configuration("walk_ready"))


@pytest.fixture(scope="module")
def short_step(robot, q0):
    """12 poses: the CoM shifts 12 mm towards the support foot in straight line (6 poses),
    then the swing foot rises 8 mm and moves 6 mm forward in straight line (6 poses)."""
    c0 = robot.com(q0)
    f0 = robot.frame_placement(q0, "r_sole").translation
    s = np.linspace(0.0, 1.0, 7)[1:]
    com = np.vstack(
        [c0 + t * np.array([0.0, 0.012, 0.0]) for t in s] + [c0 + np.array([0.0, 0.012, 0.0])] * 6
    )
    foot = np.vstack([f0] * 6 + [f0 + t * np.array([0.006, 0.0, 0.008]) for t in s])
    return com, foot


@pytest.fixture(scope="module")
def runs(robot, q0, short_step):
    """Every scheme on the short step: per pose (errors by task, info)."""
    out = {}
    for name in SCHEME_NAMES:
        scheme = ThesisScheme.make(name, robot)
        scheme.reset(q0)
        q, poses = q0.copy(), []
        for com, foot in zip(*short_step, strict=True):
            scheme.set_targets(com, foot)
            q, info = scheme.solve_pose(q, tol=1e-5, max_iterations=200)
            poses.append(info)
        out[name] = (scheme, q, poses)
    return out


def test_the_start_pose_satisfies_every_task(robot, q0):
    assert robot.within_limits(q0)
    for name in SCHEME_NAMES:
        scheme = ThesisScheme.make(name, robot)
        scheme.reset(q0)
        _, info = scheme.solve_pose(q0)
        assert info.converged and info.iterations == 0 and info.max_error() < 1e-9


@pytest.mark.parametrize("name", SCHEME_NAMES)
def test_every_scheme_runs_the_step_with_the_support_sole_fixed(robot, q0, runs, name):
    _, q, poses = runs[name]
    assert np.all(np.isfinite(q))
    s0, s1 = robot.frame_placement(q0, "l_sole"), robot.frame_placement(q, "l_sole")
    np.testing.assert_allclose(s1.translation, s0.translation, atol=1e-9)
    np.testing.assert_allclose(s1.rotation, s0.rotation, atol=1e-9)
    assert sum(p.iterations for p in poses) > 0
    assert all(p.time > 0 for p in poses)


@pytest.mark.parametrize("name", ["vat", "vatl"])
def test_augmented_schemes_track_com_and_foot_to_hundredths_of_a_millimetre(runs, name):
    _, _, poses = runs[name]
    assert max(p.com_error for p in poses) < 2e-5
    assert max(p.foot_error for p in poses) < 2e-5


@pytest.mark.parametrize(
    ("name", "primary", "secondary"),
    [("cj_foot", "foot", "com"), ("cjl_foot", "foot", "com"),
     ("cj_com", "com", "foot"), ("cjl_com", "com", "foot")],
)  # fmt: skip
def test_hierarchical_schemes_keep_the_primary_task_error_small(runs, name, primary, secondary):
    scheme, _, poses = runs[name]
    assert scheme.hierarchical and scheme.secondary == secondary
    prim = [float(np.linalg.norm(p.errors[primary])) for p in poses]
    sec = [float(np.linalg.norm(p.errors[secondary])) for p in poses]
    assert max(prim) < 1e-5  # below 0.01 mm on every pose
    assert max(prim) < max(sec)  # the secondary task pays for the priority


def test_eq_4_8_taken_literally_pushes_the_secondary_task_away(robot, q0, short_step):
    errors = {}
    for sign in (1.0, -1.0):
        scheme = ThesisScheme.cj_com(robot, secondary_sign=sign)
        scheme.reset(q0)
        q = q0.copy()
        for com, foot in list(zip(*short_step, strict=True))[6:9]:
            scheme.set_targets(com, foot)
            q, info = scheme.solve_pose(q, max_iterations=50)
        errors[sign] = info.foot_error
    assert errors[-1.0] > 10 * errors[1.0]


def test_chan_dubey_weighting_keeps_the_joints_in_their_limits_where_vat_does_not(robot, q0):
    """The first 40 % of the benchmark step (double support, CoM shift over the left foot):
    VAT drives the support hip roll past its limit, VATL does not."""
    ref = thesis_like_step(robot, q0, n_poses=30)
    n = 12
    short = type(ref)(ref.com[:n], ref.swing[:n], ref.swinging[:n])
    vat = track_step(ThesisScheme.vat(robot), q0, short, max_iterations=100)
    vatl = track_step(ThesisScheme.vatl(robot), q0, short, max_iterations=100)
    assert vat["limit_excess"].max() > np.radians(1.0)
    assert vatl["limit_excess"].max() == 0.0
    assert vatl["com_error"].max() < 2e-5


def test_clipping_keeps_the_joints_in_their_limits_and_the_sole_anchored(robot, q0):
    """VAT drives the support hip roll past its limit on this shift; clipping (not the
    thesis's method) keeps it inside without moving the support sole."""
    ref = thesis_like_step(robot, q0, n_poses=30)
    n = 12
    short = type(ref)(ref.com[:n], ref.swing[:n], ref.swinging[:n])
    out = track_step(ThesisScheme.vat(robot, clip_to_limits=True), q0, short, max_iterations=50)
    assert out["limit_excess"].max() == 0.0
    sole0 = robot.frame_placement(q0, "l_sole").translation
    for q in out["q"]:
        np.testing.assert_allclose(robot.frame_placement(q, "l_sole").translation, sole0, atol=1e-9)


def test_step_is_one_iteration_towards_the_targets(robot, q0):
    scheme = ThesisScheme.vat(robot, gain=1.0)
    scheme.reset(q0)
    target = robot.com(q0) + np.array([0.0, 0.005, 0.0])
    scheme.set_targets(target, robot.frame_placement(q0, "r_sole").translation)
    q = q0
    errors = []
    for _ in range(4):
        q = scheme.step(q)
        errors.append(np.linalg.norm(target - robot.com(q)))
    assert errors[0] < 0.005 and all(b < a for a, b in itertools.pairwise(errors))
    assert scheme.last_time > 0
    np.testing.assert_allclose(np.linalg.norm(scheme.last_errors["com"]), errors[-2], atol=1e-12)


def test_gradient_projection_cost_in_the_null_space(robot, q0, short_step):
    plain, with_cost = (ThesisScheme.vat(robot, limit_cost=c, limit_cost_gain=1e-3)
                        for c in (None, "zghal"))  # fmt: skip
    qs = []
    for scheme in (plain, with_cost):
        scheme.reset(q0)
        q = q0.copy()
        for com, foot in zip(*short_step, strict=True):
            scheme.set_targets(com, foot)
            q, info = scheme.solve_pose(q, max_iterations=100)
        assert info.com_error < 1e-4
        qs.append(q)
    H = [zghal_cost(q[7:], robot.q_min, robot.q_max) for q in qs]
    assert H[1] < H[0]


def test_bad_arguments_are_rejected(robot):
    with pytest.raises(ConfigurationError, match="unknown scheme"):
        ThesisScheme.make("qp", robot)
    with pytest.raises(ConfigurationError, match="differ"):
        ThesisScheme.vat(robot, swing="l_sole")
    with pytest.raises(ConfigurationError, match="secondary_sign"):
        ThesisScheme.cj_foot(robot, secondary_sign=0.5)
    with pytest.raises(ConfigurationError, match="limit cost"):
        ThesisScheme.vat(robot, limit_cost="nope")
    with pytest.raises(ConfigurationError, match="weights"):
        ThesisScheme.vat(robot, weights="uniform")
    assert ThesisScheme.vat(robot, weights="annex_b").weights.min() == 0.1


def test_the_walking_step_and_benchmark_rows(robot, q0):
    ref = thesis_like_step(robot, q0, n_poses=20, step_length=0.03, step_height=0.015)
    assert len(ref) == 20 and ref.swinging.sum() == 13  # from pose 8 (40 %) on
    np.testing.assert_allclose(ref.com[0], robot.com(q0))
    sole = robot.frame_placement(q0, "l_sole").translation
    np.testing.assert_allclose(ref.com[5:, :2], np.tile(sole[:2], (15, 1)), atol=1e-12)
    f0 = robot.frame_placement(q0, "r_sole").translation
    np.testing.assert_allclose(ref.swing[-1], f0 + np.array([0.03, 0.0, 0.0]), atol=1e-12)
    assert ref.swing[:, 2].max() == pytest.approx(f0[2] + 0.015, abs=1e-3)
    rows = run_walking_benchmark(robot, ["vat", "cj_com"], n_poses=10, max_iterations=20)
    assert [r["scheme"] for r in rows] == ["vat", "cj_com"]
    assert rows[1]["thesis_ms_per_pose"] == 189.6 and rows[1]["thesis_foot_max_mm"] == 2.3
    for r in rows:
        assert r["poses"] == 10 and r["ms_per_pose"] > 0 and np.isfinite(r["com_max_mm"])
