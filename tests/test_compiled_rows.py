"""The compiled task rows equal the task classes' own fill (wbc.compiled.rows)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("numba")

from wbc.compiled.plan import KINDS, Frames, Rows, Targets, frame_ids
from wbc.compiled.rows import fill_rows, frame_jacobian, jlog3, log3
from wbc.model import Kinematics
from wbc.tasks import (
    ComTask,
    ContactTask,
    DampingTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
    SwingFootOrientationTask,
    TorsoOrientationTask,
)

seeds = st.integers(0, 2**31 - 1)


def random_rotation(rng: np.random.Generator, angle: float | None = None) -> np.ndarray:
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    theta = rng.uniform(0, np.pi) if angle is None else angle
    return pin.exp3(theta * axis)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 1e-3, 0.5, 2.0, np.pi - 1e-3, np.pi - 1e-7])
def test_log3_and_jlog3_match_pinocchio(angle):
    rng = np.random.default_rng(3)
    for _ in range(20):
        R = random_rotation(rng, angle)
        out = np.zeros(3)
        theta = log3(R, out)
        ref = pin.log3(R)
        # near π the log's direction is only determined to ~sqrt(eps) by any method
        tol = 1e-12 if angle < 3.0 else 1e-6
        assert np.allclose(out, ref, atol=tol), (out, ref)
        assert abs(theta - np.linalg.norm(ref)) < tol
        J = np.zeros((3, 3))
        jlog3(theta, out, J)
        assert np.allclose(J, pin.Jlog3(R), atol=1e-9 if angle < 3.0 else 1e-3)


@settings(deadline=None)
@given(seeds)
def test_log3_random_rotations(seed):
    R = random_rotation(np.random.default_rng(seed))
    out = np.zeros(3)
    log3(R, out)
    assert np.allclose(pin.exp3(out), R, atol=1e-12)


@settings(deadline=None)
@given(seeds)
def test_frame_jacobian_matches_pinocchio(robot, seed):
    rng = np.random.default_rng(seed)
    kin = Kinematics(robot, robot.random_configuration(rng))
    for name in ("l_sole", "r_hand", "torso"):
        fid = robot.frame_id(name)
        frames = Frames(robot, kin, [fid])
        out = np.zeros((6, robot.nv))
        frame_jacobian(kin.data.J, frames.support[0], kin.translation(fid), out)
        assert np.allclose(out, kin.frame_jacobian(fid), atol=1e-12)


def make_tasks(robot, rng):
    def rot():
        return random_rotation(rng, rng.uniform(0, 3.0))

    w6 = rng.uniform(0.1, 10, size=6)
    tasks = [
        ComTask(robot, rng.normal(scale=0.05, size=3), weight=1000.0, gain=0.7),
        FramePositionTask(robot, "r_hand", rng.normal(scale=0.1, size=3), mask=[1, 0, 1]),
        FrameOrientationTask(robot, "torso", rot(), weight=[1.0, 2.0, 3.0], name="torso"),
        FramePoseTask(robot, "l_sole", pin.SE3(rot(), rng.normal(size=3)), weight=w6),
        ContactTask(robot, "r_sole", mask=[1, 1, 1, 0, 1, 1]),
        PostureTask(robot, rng.normal(scale=0.3, size=robot.n_joints), weight=0.01),
        DampingTask(robot, weight=1e-3, mask=[True] * 6 + [False] * robot.n_joints),
        SwingFootOrientationTask(robot, "r_sole", rot(), weight=[3.0, 0.5]),
        TorsoOrientationTask(robot, axis=rng.normal(size=3), weight=2.0, gain=0.3),
    ]
    return tasks


@settings(deadline=None)
@given(seeds, st.booleans())
def test_fill_rows_equals_task_fill(robot, seed, weighted):
    rng = np.random.default_rng(seed)
    kin = Kinematics(robot, robot.random_configuration(rng))
    tasks = make_tasks(robot, rng)
    tasks[4].make_contact(Kinematics(robot, robot.random_configuration(rng)))
    assert {type(t) for t in tasks} == set(KINDS)  # every compiled kind is checked
    targets = Targets()
    frames = Frames(robot, kin, frame_ids(tasks))
    rows = Rows(tasks, robot.nv, frames, targets, weighted=weighted)
    targets.seal()
    fill_rows(
        rows.spec, rows.sel, targets.gather(), frames.R, frames.p, frames.support,
        kin.data.J, kin.com, kin.com_jacobian, kin.q[7:], rows.sqrt_w, rows.gain_w,
        rows.J, rows.E, rows.b,
    )  # fmt: skip
    for t, (_, sl) in zip(tasks, rows.slices, strict=True):
        assert np.shares_memory(t.last_error, rows.E)  # errors readable after each solve
        J, e = t.compute(kin)
        w = np.sqrt(t.weight) if weighted else np.ones(t.rows)
        assert np.allclose(rows.E[sl], e, atol=1e-12, rtol=1e-12), t.name
        assert np.allclose(rows.J[sl], w[:, None] * J, atol=1e-12, rtol=1e-12), t.name
        assert np.allclose(rows.b[sl], t.gain * w * e, atol=1e-12, rtol=1e-12), t.name


def test_targets_follow_in_place_updates(robot):
    kin = Kinematics(robot, robot.configuration("walk_ready"))
    com = ComTask(robot, [0.0, 0.0, 0.2])
    targets = Targets()
    Rows([com], robot.nv, Frames(robot, kin, []), targets, weighted=True)
    targets.seal()
    com.set_target([0.01, 0.02, 0.25])
    assert np.array_equal(targets.gather(), [0.01, 0.02, 0.25])


@settings(deadline=None)
@given(seeds)
def test_compiled_integrate_matches_pinocchio(robot, seed):
    from wbc.compiled.ticks import integrate

    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    dq = rng.normal(scale=rng.choice([1e-7, 1e-3, 0.3]), size=robot.nv)
    inf = np.full(robot.nv, np.inf)
    out = np.empty(robot.nq)
    integrate(q, dq, -inf, inf, np.full(robot.n_joints, -10.0), np.full(robot.n_joints, 10.0), out)
    assert np.allclose(out, pin.integrate(robot.model, q, dq), atol=1e-12)
    # clipping: increments to the box, joints to their limits (or where they already are)
    lower, upper = -inf.copy(), inf.copy()
    lower[6:], upper[6:] = -0.01, 0.01
    integrate(q, dq, lower, upper, robot.q_min, robot.q_max, out)
    j, j0 = out[7:], q[7:]
    assert np.all(np.abs(j - j0) <= 0.01 + 1e-15)
    assert np.all((j >= np.minimum(robot.q_min, j0)) & (j <= np.maximum(robot.q_max, j0)))
