"""The pre-motion solves' rows (wbc.walking.rows): each is the first-order model of its error."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbc.walking.rows import sole_rows


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sole_rows_and_com_rows_are_first_order_models(robot, seed):
    """Soles held where they are at q: after a small step dq the errors are ``−J dq`` and the
    CoM moves by ``J_c dq``, to second order in |dq|."""
    model, data = robot.model, robot.data
    rng = np.random.default_rng(seed)
    q = robot.configuration("stand")
    fids = [robot.frame_id(f) for f in ("l_sole", "r_sole")]
    targets = [robot.frame_placement(q, f) for f in ("l_sole", "r_sole")]
    com, Jc, J, e = sole_rows(model, data, q, fids, targets)
    assert J.shape == (12, model.nv) and e.shape == (12,)
    assert np.abs(e).max() < 1e-12
    np.testing.assert_allclose(com, robot.com(q), atol=1e-15)
    dq = rng.standard_normal(model.nv)

    def residuals(step: float) -> tuple[float, float]:
        """How far the first-order models miss after ``step * dq``."""
        d = step * dq
        com1, _, _, e1 = sole_rows(model, data, pin.integrate(model, q, d), fids, targets)
        return float(np.abs(e1 + J @ d).max()), float(np.abs(com1 - com - Jc @ d).max())

    big, small = residuals(1e-3), residuals(1e-4)
    for b, s in zip(big, small, strict=True):
        assert 0 < s < 1e-6 and b / s > 50  # second order: 10x smaller step, ~100x smaller miss
    # and the models are not trivially zero
    assert np.abs(J @ dq).max() > 0.1 and np.abs(Jc @ dq).max() > 0.01


def test_sole_rows_need_one_target_per_sole(robot):
    q = robot.configuration("stand")
    with pytest.raises(ValueError):
        sole_rows(robot.model, robot.data, q, [robot.frame_id("l_sole")], [])
