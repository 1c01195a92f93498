"""The thesis's pseudo-inverses against their closed forms (wbc.pinv.pseudoinverse)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import Kinematics
from wbc.exceptions import ConfigurationError, SolverError
from wbc.pinv import SoleRooted
from wbc.pinv.pseudoinverse import (
    AdaptiveDamping,
    damped_pinv,
    inverse_weights,
    moore_penrose,
    null_space_projector,
    weighted_damped_pinv,
    weighted_pinv,
)
from wbc.tasks import ComTask, FramePositionTask

seeds = st.integers(0, 2**32 - 1)
rows = st.integers(1, 6)
extra_cols = st.integers(0, 12)
dampings = st.floats(1e-3, 10.0)


def _matrix(rng: np.random.Generator, m: int, n: int) -> np.ndarray:
    """A random m x n matrix of full rank with singular values in [0.2, 5]."""
    k = min(m, n)
    U = np.linalg.qr(rng.normal(size=(m, m)))[0][:, :k]
    V = np.linalg.qr(rng.normal(size=(n, n)))[0][:, :k]
    return U @ np.diag(rng.uniform(0.2, 5.0, k)) @ V.T


def _wide(seed: int, m: int, extra: int):
    """A random full-row-rank m x n Jacobian (n >= m), a target and diagonal weights."""
    rng = np.random.default_rng(seed)
    n = m + extra
    J = _matrix(rng, m, n)
    e = rng.normal(size=m)
    w = np.exp(rng.uniform(-2.3, 2.3, size=n))  # 0.1 .. 10, like Annex B
    return rng, J, e, w


@given(seeds, rows, extra_cols)
def test_moore_penrose_is_the_minimum_norm_solution(seed, m, extra):
    rng, J, e, _ = _wide(seed, m, extra)
    Jp = moore_penrose(J)
    np.testing.assert_allclose(Jp, np.linalg.pinv(J), atol=1e-8)
    dq = Jp @ e
    np.testing.assert_allclose(J @ dq, e, atol=1e-9)
    # any other solution dq + n (n in the null space) is longer
    n = rng.normal(size=J.shape[1])
    n -= Jp @ (J @ n)
    assert np.linalg.norm(dq + n) >= np.linalg.norm(dq) - 1e-12


@given(seeds, st.integers(1, 5), st.integers(1, 6))
def test_moore_penrose_of_a_tall_matrix_is_least_squares(seed, n, extra):
    rng = np.random.default_rng(seed)
    J = _matrix(rng, n + extra, n)
    e = rng.normal(size=n + extra)
    np.testing.assert_allclose(moore_penrose(J) @ e, np.linalg.lstsq(J, e)[0], atol=1e-8)


@given(seeds, rows, extra_cols)
def test_weighted_pinv_minimises_the_weighted_norm_subject_to_the_task(seed, m, extra):
    _, J, e, w = _wide(seed, m, extra)
    n = J.shape[1]
    dq = weighted_pinv(J, w) @ e
    # KKT of min ½ dqᵀW dq s.t. J dq = e
    K = np.block([[np.diag(w), J.T], [J, np.zeros((m, m))]])
    expected = np.linalg.solve(K, np.concatenate([np.zeros(n), e]))[:n]
    np.testing.assert_allclose(dq, expected, atol=1e-8)
    np.testing.assert_allclose(J @ dq, e, atol=1e-9)
    # a full weight matrix gives the same as its diagonal
    np.testing.assert_allclose(weighted_pinv(J, np.diag(w)) @ e, dq, atol=1e-9)


@given(seeds, rows, extra_cols)
def test_weighted_pinv_with_unit_weights_is_moore_penrose(seed, m, extra):
    _, J, _, _ = _wide(seed, m, extra)
    np.testing.assert_allclose(weighted_pinv(J, 1.0), moore_penrose(J), atol=1e-10)


@given(seeds, st.integers(1, 8), st.integers(1, 8), dampings)
def test_damped_pinv_minimises_the_damped_least_squares_cost(seed, m, n, lam):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(m, n))
    e = rng.normal(size=m)
    dq = damped_pinv(J, lam) @ e
    # closed form (1.42) and zero gradient of ‖J dq − e‖² + λ²‖dq‖²
    np.testing.assert_allclose(
        dq, np.linalg.solve(J.T @ J + lam**2 * np.eye(n), J.T @ e), atol=1e-9
    )
    np.testing.assert_allclose(J.T @ (J @ dq - e) + lam**2 * dq, 0.0, atol=1e-9)


@given(seeds, rows, extra_cols, dampings)
def test_weighted_damped_pinv_minimises_its_cost(seed, m, extra, lam):
    _, J, e, w = _wide(seed, m, extra)
    dq = weighted_damped_pinv(J, w, lam) @ e
    # (1.43) minimises ‖J dq − e‖² + λ dqᵀ W dq: gradient Jᵀ(J dq − e) + λ W dq = 0
    np.testing.assert_allclose(J.T @ (J @ dq - e) + lam * w * dq, 0.0, atol=1e-9)


@given(seeds, rows, extra_cols)
def test_weighted_damped_without_damping_is_weighted(seed, m, extra):
    _, J, _, w = _wide(seed, m, extra)
    np.testing.assert_allclose(weighted_damped_pinv(J, w, 0.0), weighted_pinv(J, w), atol=1e-9)


def test_undamped_inverses_fail_on_a_rank_deficient_jacobian_and_damped_ones_do_not():
    J = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0]])  # rank 1
    with pytest.raises(SolverError, match="singular"):
        moore_penrose(J)
    with pytest.raises(SolverError, match="singular"):
        weighted_pinv(J, [0.1, 1.0, 10.0])
    assert np.all(np.isfinite(damped_pinv(J, 0.1)))
    assert np.all(np.isfinite(weighted_damped_pinv(J, [0.1, 1.0, 10.0], 0.1)))
    zero_row = np.vstack([J[:1], np.zeros((1, 3))])  # the aligned-axes orientation task
    with pytest.raises(SolverError):
        weighted_pinv(zero_row, 1.0)


def test_an_infinite_weight_freezes_its_joint():
    J = np.array([[1.0, 1.0, 1.0]])
    dq = weighted_damped_pinv(J, [np.inf, 1.0, 1.0], 0.0) @ np.array([1.0])
    assert dq[0] == 0.0
    np.testing.assert_allclose(J @ dq, [1.0])


def test_bad_inputs_raise_clear_errors():
    J = np.ones((2, 3))
    with pytest.raises(ConfigurationError, match="3 entries"):
        weighted_pinv(J, [1.0, 1.0])
    with pytest.raises(ConfigurationError, match="> 0"):
        inverse_weights(np.array([1.0, 0.0, 1.0]), 3)
    with pytest.raises(ConfigurationError, match="positive definite"):
        inverse_weights(-np.eye(3), 3)
    with pytest.raises(ConfigurationError, match="damping"):
        damped_pinv(J, -1.0)
    with pytest.raises(ConfigurationError, match="non-finite"):
        moore_penrose(np.array([[np.nan, 1.0]]))
    with pytest.raises(ConfigurationError, match="2-D"):
        moore_penrose(np.ones(3))


@given(seeds, rows, st.integers(1, 12))
def test_null_space_projection_leaves_the_primary_velocity_unchanged(seed, m, extra):
    rng, J, e, w = _wide(seed, m, extra)
    z = rng.normal(size=J.shape[1])
    for Jp in (moore_penrose(J), weighted_pinv(J, w)):
        P = null_space_projector(J, Jp)
        np.testing.assert_allclose(J @ (Jp @ e + P @ z), J @ (Jp @ e), atol=1e-8)
        np.testing.assert_allclose(P @ P, P, atol=1e-8)  # a projector


def test_a_damped_projector_leaks_into_the_primary_task():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(3, 8))
    P = null_space_projector(J, damped_pinv(J, 0.5))
    assert np.linalg.norm(J @ P) > 1e-3  # the weakness the thesis's CJ schemes keep


def test_null_space_projection_on_the_robot_keeps_the_foot_still(robot):
    """Primary: swing-foot position (sole-rooted); secondary: the CoM, projected."""
    q = robot.configuration("walk_ready")
    root = SoleRooted(robot, "l_sole")
    root.anchor(q)
    kin: Kinematics = root.kin
    foot = FramePositionTask(robot, "r_sole")
    com = ComTask(robot, target=kin.com + np.array([0.0, 0.01, 0.0]))
    foot.set_target_from(kin)
    Jf = root.reduce(foot.compute(kin)[0])
    Jc, ec = root.reduce(*com.compute(kin))
    Jp = weighted_pinv(Jf, np.ones(robot.n_joints))
    dq = null_space_projector(Jf, Jp) @ (moore_penrose(Jc) @ ec)
    np.testing.assert_allclose(Jf @ dq, 0.0, atol=1e-12)
    assert Jc @ dq @ ec > 0.0  # and the CoM still moves towards its target


def test_adaptive_damping_halves_on_progress_and_doubles_and_rejects_otherwise():
    lam = AdaptiveDamping(0.1, minimum=1e-3, maximum=0.8)
    assert lam.accept(new_error=1.0, old_error=2.0) and lam.value == pytest.approx(0.05)
    assert not lam.accept(new_error=2.0, old_error=1.0) and lam.value == pytest.approx(0.1)
    assert not lam.accept(new_error=1.0, old_error=1.0)  # no progress: reject too
    for _ in range(10):
        lam.accept(3.0, 1.0)
    assert lam.value == 0.8 and lam.exhausted
    for _ in range(20):
        lam.accept(0.0, 1.0)
    assert lam.value == 1e-3 and not lam.exhausted
    lam.reset()
    assert lam.value == 0.1 and lam.rejections == 0
