"""Stress laws of the solvers (issue 17), on random problems drawn as ``benchmarks/stress.py``
draws them (a few dozen here; the long run is ``python benchmarks/stress.py --n 10000``).

For any stack, solver, path, support, start (inside the limits or slightly outside) and
targets (reachable, out of reach, upside down): no joint leaves its limits (or goes further out
than it started), nothing non-finite is returned, every failure is a typed :class:`WbcError`,
a converged pose holds its hard contacts to 1e-6 m, and every tick and pose ends within a
bounded time (``TICK_TIME_BOUND``, ``POSE_TIME_PER_ITERATION`` in the script: generous bounds
that catch runaway solves, not speed figures; a pose that spends its own work budget counts
as a runaway).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st


@pytest.fixture(scope="module")
def stress(stress_script):
    stress_script.compile_first()  # no timed tick or pose waits for numba
    return stress_script


@pytest.mark.parametrize("backends", [["daqp"], ["proxqp", "quadprog", "osqp"]])
def test_random_problems_keep_the_laws(robot, stress, backends):
    @settings(max_examples=12 if backends == ["daqp"] else 6)
    @given(trial=st.integers(0, 2**31 - 1))
    def check(trial):
        tally = stress.Tally()
        p = stress.draw(robot, np.random.default_rng([2024, trial]), backends)
        stress.run_trial(robot, p, tally, ticks=5, iterations=20)
        assert tally.limit_violations == 0
        assert tally.non_finite == 0
        assert not tally.untyped, tally.untyped
        assert tally.pose_contact_misses == 0, tally.max_pose_contact
        assert tally.slow_ticks == 0, (tally.slowest_tick, tally.slowest_tick_trial)
        assert tally.slow_poses == 0, (tally.slowest_pose, dict(tally.typed))

    check()


@pytest.mark.parametrize(
    ("trial", "backends"),
    [
        (187, ["daqp"]),
        (218, ["daqp"]),
        (356, ["daqp"]),
        (455, ["daqp"]),
        (705, ["daqp"]),
        (76, ["proxqp", "quadprog", "osqp"]),
    ],
)
def test_trials_that_reported_feasible_problems_as_failures(robot, stress, trial, backends):
    """Stress trials (seed 2024; walk stack, double support, targets out of reach) on which
    DAQP reported "exit flag -2" (187, a tick) or a bare "daqp: the QP is infeasible" naming
    no task (218, a converged pose); both problems are feasible. 187 starts outside the
    limits with links inside the self-collision margin: since the walk stack's hard
    self-collision rows it raised "hard level 0 is infeasible" at tick 0. 356 (weighted QP,
    single support, a joint outside its limits): an iterate of its converged pose is
    infeasible, and the weighted QP's diagnosis (DAQP cycling, exit flag -2) raised a
    SolverError, which left the recovery no chance. 76 (quadprog, hierarchical, single
    support): quadprog called an iterate infeasible, DAQP's re-check cycled (exit flag -2)
    and that SolverError ended the pose. 455, 705 (hierarchical, double support): DAQP
    cycled in the hierarchy's cascade at an iterate (a SolverError, no verdict), and the
    iterate never got the recovery's re-solve, which meets it. 705's start has a foot 3.6 mm
    inside the other ankle's margin, where both soles pin it: its ticks now end with the
    error naming that pair (issue 29: never a silent result); its converged pose does not."""
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, trial]), backends)
    stress.run_trial(robot, p, tally, ticks=50, iterations=50)
    pinned = [k for k in tally.typed if k.startswith("ticks: InfeasibleError: self_collision")]
    assert len(pinned) == (trial == 705) == len(tally.typed), dict(tally.typed)
    assert pinned or tally.ok()


@pytest.mark.parametrize(
    ("trial", "backends"),
    [
        (1091, ["daqp"]),
        (307, ["proxqp", "quadprog", "osqp"]),
        (136, ["daqp"]),
        (584, ["daqp"]),
    ],
)
def test_converged_pose_ending_at_the_iteration_cap_holds_its_contacts(
    robot, stress, trial, backends
):
    """Stress trial 1091 (walk stack, double support, targets out of reach, numpy path): its
    50th step, never checked by a solve, left the contacts 15 mm off, beyond what the final
    projection could undo within the joint limits; since the self-collision rows its pose
    raised a bare DAQP "exit flag -2" from the hierarchy's diagnosis of an infeasible
    iterate instead of going on. Trial 307 (the same with quadprog) ended 2.8e-5 m off
    before main's redesigned core (1.2e-7 on main, 7e-11 here: kept as a check). Trial 136
    (weighted QP, double support, joints outside their limits, links inside the margin)
    ended 4.3e-5 m off its contacts (the guard raised); its infeasible iterates are now
    re-solved with the rows of the pairs outside the margin held at the margin itself, not
    at the damper's rate (as is the final projection). Trial 584 (walk stack, weighted,
    double support): the guard raised, the contacts 2e-4 m off; its iterates were never
    checked (a hard level with inequality rows) and drifted 1e-4 off where the joint limits
    no longer let the chain close."""
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, trial]), backends)
    stress.run_trial(robot, p, tally, ticks=0, iterations=50)
    assert tally.poses == 1
    assert tally.pose_contact_misses == 0, tally.max_pose_contact


@pytest.mark.parametrize("trial", [60, 85, 258])
def test_starts_below_the_ground_recover(robot, stress, trial):
    """Stress trials (walk stack, weighted QP, single support) whose swing sole starts 20-54
    mm below the ground, with joints outside their limits (85, compiled path) or boxes
    overlapping by 22 mm (258): they raised at tick 0, naming ground_clearance (60, 85),
    contact_support and self_collision (258). Now no typed error, ticks or converged pose."""
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, trial]), ["daqp"])
    assert (p["stack"], p["kind"], p["double"]) == ("walk", "weighted", False)
    stress.run_trial(robot, p, tally, ticks=50, iterations=50)
    assert not tally.typed, dict(tally.typed)
    assert tally.limit_violations == tally.non_finite == tally.pose_contact_misses == 0


@pytest.mark.parametrize(("trial", "ticks"), [(771, 12), (1271, 3)])
def test_contact_drift_against_a_pair_at_its_margin_is_restored(robot, stress, trial, ticks):
    """Stress trials 771, 1271 (walk stack, weighted QP, double support, targets out of reach
    or upside down, numpy path): tick 0 at servo speed leaves the contacts 5.4 mm (771) and
    0.5 mm (1271) off, to second order; at tick 1 their full correction, linearised, takes
    a self-collision pair at its margin (the feet side by side; a foot and the other ankle)
    inside it, and "hard level 0 is infeasible" was raised, although the configuration one
    tick back met both. The tick now restores the hard levels by re-linearised steps within
    its box (to 1e-6 at q ⊕ Δq): no error, contacts held."""
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, trial]), ["daqp"])
    assert (p["stack"], p["kind"], p["double"]) == ("walk", "weighted", True)
    stress.run_trial(robot, p, tally, ticks=ticks, iterations=0)
    assert not tally.typed, dict(tally.typed)
    assert tally.ok()


def test_hard_level_met_exactly_where_its_null_space_is_coupled(robot, stress):
    """Stress trial 1529 (walk stack, weighted QP, single support, the swing sole 58 mm below
    the ground, two joints outside their limits, many pairs inside the margin): the first
    iterate of its converged pose raised "ground_clearance_swing infeasible" although the
    recovery's first cascade had met the contact exactly: the second cascade's hard level,
    solved as least squares with a ridge on its null space, traded a 5e-6 m contact
    residual for the ridge (coupled through the held rows). A hard level is now met as an
    equality where it can be."""
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, 1529]), ["daqp"])
    stress.run_trial(robot, p, tally, ticks=0, iterations=50)
    assert not tally.typed, dict(tally.typed)
    assert tally.poses == 1 and tally.ok()


def test_ticks_and_poses_beyond_their_time_bound_count(robot, stress, monkeypatch):
    """The time laws can fail: with bounds below any solve's time every tick counts as slow,
    and the pose is stopped by its own time budget (solve_pose's typed SolverError, naming
    it) rather than running on."""
    monkeypatch.setattr(stress, "TICK_TIME_BOUND", 0.0)
    monkeypatch.setattr(stress, "POSE_TIME_PER_ITERATION", 1e-6)
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, 3]), ["daqp"])
    stress.run_trial(robot, p, tally, ticks=3, iterations=5)
    assert tally.slow_ticks == 3
    assert tally.slow_poses == 1 and tally.poses == 0
    assert [k for k in tally.typed if "spent its time budget" in k], dict(tally.typed)
    assert not tally.ok()


@pytest.mark.parametrize("trial", [974, 4169])
def test_converged_pose_of_a_nearly_singular_chain_holds_its_contacts(robot, stress, trial):
    """Stress trials 974 (walk, weighted) and 4169 (walk, hierarchical): double support, joints
    outside their limits; their poses ended 7.4e-5 / 1.7e-6 m off the contacts (the guard
    raised). With several joints at a limit and pairs at their margin the chain is nearly
    singular: the projections' minimum-norm Gauss–Newton steps were radians long for
    millimetres of error and crept at t = 1/32. Within a trust region they converge."""
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, trial]), ["daqp"])
    assert (p["stack"], p["double"]) == ("walk", True)
    stress.run_trial(robot, p, tally, ticks=0, iterations=50)
    assert not tally.typed, dict(tally.typed)
    assert tally.poses == 1 and tally.ok()


def test_projections_of_a_slow_pose_take_few_steps(robot, stress):
    """Stress trial 3972 (walk, weighted, double support): its pose took 93 s, 84 of them in
    173 projections onto the contacts, 2876 Gauss–Newton steps (creeping: see above). A work
    count, not a timing: now under 500 steps, and it still ends on its contacts."""
    tally = stress.Tally()
    p = stress.draw(robot, np.random.default_rng([2024, 3972]), ["daqp"])
    stress.run_trial(robot, p, tally, ticks=0, iterations=50)
    assert tally.poses == 1 and tally.ok(), dict(tally.typed)
    assert 0 < tally.most_projection_steps < 500
