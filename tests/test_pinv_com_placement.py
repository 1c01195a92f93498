"""Static CoM placement of ch. 3: MCMT, DE, MS, DEAV, MSAV (wbc.pinv.com_placement)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from wbc.exceptions import ConfigurationError
from wbc.pinv import (
    METHODS,
    TABLE_3_3_1,
    THESIS_COM_TOLERANCE,
    ComPlacement,
    default_com_target,
    place_com,
    run_com_placement_benchmark,
)
from wbc.pinv.thesis_data import TABLE_3_3_2


@pytest.fixture(scope="module")
def start(robot):
    q0 = robot.configuration("walk_ready")
    return q0, default_com_target(robot, q0, "l_sole")


@pytest.fixture(scope="module")
def placement(robot):
    return ComPlacement(robot, "l_sole", "r_sole")


def test_the_default_target_is_over_the_support_sole_at_the_same_height(robot, start):
    q0, target = start
    sole = robot.frame_placement(q0, "l_sole").translation
    np.testing.assert_allclose(target[:2], sole[:2])
    assert target[2] == pytest.approx(robot.com(q0)[2])
    assert np.linalg.norm(target - robot.com(q0)) > 0.03  # a real move (~4 cm)


@pytest.mark.parametrize("method", METHODS)
def test_each_method_reaches_the_target_within_the_thesis_tolerance_on_some_setting(
    robot, start, placement, method
):
    """Settings are tried in Table 3.3.1's order; the first that converges must be as
    accurate as the best the thesis reports for that method, and really be there."""
    q0, target = start
    for lam, alpha in TABLE_3_3_1.values():
        res = placement.solve(q0, target, method, lam, alpha)
        if res.converged:
            break
    else:
        pytest.fail(f"{method} converged on no setting of Table 3.3.1")
    assert res.com_error <= THESIS_COM_TOLERANCE
    assert res.com_error * 1e3 <= min(TABLE_3_3_2[method])
    np.testing.assert_allclose(robot.com(res.q), target, atol=THESIS_COM_TOLERANCE)
    # the support sole is still where it was (the thesis's fixed root)
    sole0 = robot.frame_placement(q0, "l_sole")
    sole = robot.frame_placement(res.q, "l_sole")
    np.testing.assert_allclose(sole.translation, sole0.translation, atol=1e-9)
    np.testing.assert_allclose(sole.rotation, sole0.rotation, atol=1e-9)
    assert res.iterations > 0 and res.time > 0.0


def test_mcmt_with_the_thesis_best_setting_converges_without_leaving_the_limits(robot, start):
    q0, target = start
    res = place_com(robot, q0, target, "mcmt", setting="sim1")
    assert res.converged and res.method == "MCMT" and (res.damping, res.gain) == (0.1, 0.1)
    assert res.outer_iterations == 0
    assert robot.within_limits(res.q)


def test_a_run_that_cannot_converge_stops_at_the_iteration_cap(robot, start):
    q0, target = start
    res = ComPlacement(robot, max_iterations=5).solve(q0, target, "MS", 0.1, 0.1)
    assert not res.converged and res.iterations == 5
    assert res.com_error < np.linalg.norm(target - robot.com(q0))  # it did make progress


@pytest.mark.parametrize("method", ["DEAV", "MSAV"])
def test_adaptive_damping_runs_discard_iterations_that_increase_the_error(robot, start, method):
    q0, target = start
    res = ComPlacement(robot, max_iterations=300).solve(q0, target, method, 0.1, 1.0)
    accepted = sum(len(t) - 1 for t in res.trace)
    assert accepted < res.iterations  # some iterations were discarded...
    for t in res.trace:  # ...and every kept one reduced its loop's error
        assert all(b < a for a, b in itertools.pairwise(t))
    # the same without adaptation keeps iterations that increase the error
    plain = ComPlacement(robot, max_iterations=300).solve(q0, target, method[:2], 0.1, 1.0)
    assert sum(len(t) - 1 for t in plain.trace) == plain.iterations
    assert any(b > a for t in plain.trace for a, b in itertools.pairwise(t))


def test_bad_arguments_are_rejected(robot, start):
    q0, target = start
    with pytest.raises(ConfigurationError, match="method"):
        ComPlacement(robot).solve(q0, target, "XYZ")
    with pytest.raises(ConfigurationError, match="gain"):
        ComPlacement(robot).solve(q0, target, "MCMT", 0.1, 0.0)
    with pytest.raises(ConfigurationError, match="setting"):
        place_com(robot, q0, target, setting="sim9")
    with pytest.raises(ConfigurationError, match="weights"):
        ComPlacement(robot, weights=np.ones(3))


def test_benchmark_rows_carry_our_figures_next_to_the_thesis(robot):
    rows = run_com_placement_benchmark(robot, methods=["MCMT"], settings=["sim1", "sim3"],
                                       repeats=1)  # fmt: skip
    assert [r["setting"] for r in rows] == ["sim1", "sim3"]
    for r in rows:
        assert r["converged"] and r["com_error_mm"] <= THESIS_COM_TOLERANCE * 1e3
        assert r["time_ms"] > 0
    assert rows[0]["thesis_com_error_mm"] == 0.0005 and rows[0]["thesis_time_ms"] == 31.6
    assert rows[1]["thesis_com_error_mm"] == 4.4929
