"""Limits and constraints: bounds, the CoM polygon, ground clearance, linear inequalities."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numba import njit

from wbc import ConfigurationError, Kinematics, TaskError
from wbc.compiled.rows import frame_jacobian
from wbc.geometry import convex_hull, halfplanes, signed_distance
from wbc.limits import (
    Bounds,
    BoxLimit,
    ComPolygonConstraint,
    Constraint,
    GroundClearanceConstraint,
    JointPositionLimit,
    JointVelocityLimit,
    LinearInequality,
    box_bounds,
)
from wbc.limits.limit import Inequality
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.tasks import ComTask, ContactTask, PostureTask


def random_q(robot, seed):
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    q[:3] = rng.uniform(-0.1, 0.1, 3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.4, 0.4, 3))).coeffs()
    return q, rng


@given(seed=st.integers(0, 10_000))
def test_ground_clearance_rows_are_the_linearised_corner_heights(robot, seed):
    q, rng = random_q(robot, seed)
    c = GroundClearanceConstraint(robot, "r_sole", clearance=0.002)
    G, h = c.compute(Kinematics(robot, q))
    dq = rng.normal(size=robot.nv) * 1e-6
    M0 = robot.frame_placement(q, "r_sole")
    z0 = M0.translation[2] + c.corners @ M0.rotation[2]
    M = robot.frame_placement(robot.integrate(q, dq), "r_sole")
    z = M.translation[2] + c.corners @ M.rotation[2]
    # G dq <= h  <=>  corner heights after the step >= clearance (to first order); a corner
    # below the clearance (depth δ) rises by min(ξ δ, max_rise) instead (no jump back)
    depth = np.maximum(0.002 - z0, 0.0)
    rise = np.minimum(c.damping * depth, c.max_rise)
    assert np.allclose(h - G @ dq, z - np.where(depth > 0, z0 + rise, 0.002), atol=1e-11)
    assert c.lowest_point(Kinematics(robot, q)) == pytest.approx(
        robot.frame_placement(q, "r_sole").translation[2]
        + np.min(c.corners @ robot.frame_placement(q, "r_sole").rotation[2])
    )


def test_ground_clearance_settings_are_its_kernel_parameters(robot):
    """clearance, damping and max_rise write into the array the kernel reads (by address)."""
    kin = Kinematics(robot, robot.configuration("walk_ready"))
    c = GroundClearanceConstraint(robot, "r_sole", clearance=-0.01)
    h0 = c.compute(kin).h.copy()
    assert h0.min() > 0.0  # (no corner below: no way back)
    c.clearance = -0.02
    assert c.clearance == -0.02 and c.settings[0] == -0.02
    np.testing.assert_allclose(c.compute(kin).h, h0 + 0.01, atol=1e-15)
    c.clearance, c.max_rise = h0.max() + 0.01, 0.001  # every corner below: capped way back
    assert np.all(c.compute(kin).h == -0.001)


@given(st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=3, max_size=30))
def test_convex_hull_contains_every_point(points):
    pts = np.array(points)
    hull = convex_hull(pts)
    if len(hull) < 3:
        return
    A, b = halfplanes(hull)
    assert np.all(A @ pts.T <= b[:, None] + 1e-9)


def test_signed_distance_inside_and_outside():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert signed_distance(square, [0.5, 0.5]) == pytest.approx(0.5)
    assert signed_distance(square, [0.5, 0.1]) == pytest.approx(0.1)
    assert signed_distance(square, [2.0, 0.5]) == pytest.approx(-1.0)
    assert signed_distance(square, [2.0, 2.0]) == pytest.approx(-np.sqrt(2.0))


def test_com_polygon_rows_keep_the_com_inside(robot):
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    c = ComPolygonConstraint(robot, ["l_sole"], margin=0.01)
    G, h = c.compute(kin)
    # at Walk Ready the CoM is between the feet: outside the left foot's polygon
    assert np.any(h < 0)
    # rows are A (c + Jc dq) <= b
    A, b = c.polygon.A, c.polygon.b
    dq = np.random.default_rng(1).normal(size=robot.nv) * 1e-3
    assert np.allclose(G @ dq - h, A @ (kin.com[:2] + kin.com_jacobian[:2] @ dq) - b)
    both = ComPolygonConstraint(robot, ["l_sole", "r_sole"], margin=0.01)
    _, h2 = both.compute(kin)
    assert np.all(h2 > 0)  # double support: the CoM is well inside


def test_bounds_move_a_joint_back_inside_at_the_servo_speed(robot):
    q = robot.configuration("walk_ready")
    i = robot.joint_index("r_knee")
    q[7 + i] = robot.q_min[i] - 0.3  # far outside
    kin = Kinematics(robot, q)
    lower, upper = np.empty(robot.nv), np.empty(robot.nv)
    box_bounds([JointPositionLimit(robot), JointVelocityLimit(robot)], kin, 0.01, lower, upper)
    step = robot.v_max[i] * 0.01
    assert lower[6 + i] == pytest.approx(step) and upper[6 + i] == pytest.approx(step)
    assert np.all(lower <= upper)
    assert np.all(np.isinf(lower[:6])) and np.all(np.isinf(upper[:6]))


def test_linear_inequality_validation():
    with pytest.raises(TaskError, match="rows"):
        LinearInequality(np.zeros((2, 24)), np.zeros(3))
    with pytest.raises(TaskError, match="non-finite"):
        LinearInequality(np.full((1, 24), np.nan), np.zeros(1))


# ---------------------------------------------------------------------- a user's own box limit
@njit(cache=True)
def _band_bounds(params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, lo, hi):
    """lo_j − q_j <= Δq_j <= hi_j − q_j (params: lo, then hi, every joint; base unbounded)."""
    nj = params.shape[0] // 2
    nb = lo.shape[0] - nj
    for i in range(nb):
        lo[i] = -np.inf
        hi[i] = np.inf
    for j in range(nj):
        lo[nb + j] = params[j] - q[7 + j]
        hi[nb + j] = params[nj + j] - q[7 + j]


class JointBand(BoxLimit):
    """A box limit written outside the package: every joint within a band [low, high]."""

    name = "joint_band"
    bound_kernel = staticmethod(_band_bounds)
    param_fields = ("band",)

    def __init__(self, low: np.ndarray, high: np.ndarray) -> None:
        self.band = np.concatenate([low, high])


class PythonBand(BoxLimit):
    """The same band in Python only (no bound kernel): the numpy path."""

    name = "python_band"

    def __init__(self, low: np.ndarray, high: np.ndarray) -> None:
        self.low, self.high = low, high

    def bounds(self, kin, dt):
        lower = np.full(kin.model.nv, -np.inf)
        upper = np.full(kin.model.nv, np.inf)
        lower[6:] = self.low - kin.q[7:]
        upper[6:] = self.high - kin.q[7:]
        return Bounds(lower, upper)


def _band_stack(robot, q, limit):
    stack = TaskStack(robot)
    kin = Kinematics(robot, q)
    for sole in ("l_sole", "r_sole"):
        stack.add(ContactTask(robot, sole, name=sole), level=0, hard=True).set_target_from(kin)
    stack.add(PostureTask(robot, q[7:] + 0.3), level=1)  # pulls every joint up
    stack.add_limit(limit)
    return _one_user_set(robot, stack)


def _one_user_set(robot, stack):
    """``stack`` with each of this module's kernel types (JointBand, FrameFloor, FrameAbove)
    it lacks, where it cannot bind (bounds and a floor 10 m beyond): a compiled tick is built
    per set of kernel types, whatever their values, so the tests of a user's limits share one
    set per solver instead of compiling three."""
    have = {type(b) for b in stack.extra_limits} | {type(c) for c in stack.constraints()}
    if JointBand not in have:
        stack.add_limit(JointBand(robot.q_min - 10.0, robot.q_max + 10.0))
    if FrameFloor not in have:
        stack.add_limit(FrameFloor(robot, "torso", -10.0))
    if FrameAbove not in have:
        stack.add_constraint(FrameAbove(robot, "torso", -10.0), level=0)
    return stack


@pytest.mark.long(15)
@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_a_box_limit_defined_outside_the_package_runs_compiled(robot, solver):
    """A user's box limit (a bound kernel, in a module outside wbc) keeps the stack on the
    compiled path, binds (the joints stop at the band), and the compiled step is the numpy
    path's to 1e-9; a limit with Python bounds only runs the numpy path, with the same step."""
    q = robot.configuration("walk_ready")
    low, high = robot.q_min.copy(), np.minimum(q[7:] + 0.004, robot.q_max)
    steps = {}
    for compiled in (None, False):
        band = JointBand(low, high)
        s = solver(_band_stack(robot, q, band), compiled=compiled)
        s.step(q, dt=0.01)
        band.band[len(low) :] += 0.001  # updated in place: read by address on every path
        steps[compiled] = s.step(q, dt=0.01)
        assert s.compiled_ticks == (2 if compiled is None else 0), s.compiled_reason()
    assert np.abs(steps[None] - steps[False]).max() < 1e-9
    assert np.all(steps[None][7:] <= high + 0.001 + 1e-12)
    assert np.isclose(steps[None][7:], high + 0.001, atol=1e-9).sum() >= 4  # (it binds)
    s = solver(_band_stack(robot, q, PythonBand(low, high + 0.001)))
    assert "PythonBand" in s.compiled_reason()
    assert np.abs(s.step(q, dt=0.01) - steps[None]).max() < 1e-6
    assert s.compiled_ticks == 0


def test_an_unknown_limit_input_is_named():
    with pytest.raises(ConfigurationError, match=r"kernel_inputs \['speed'\]"):

        class Bad(JointBand):
            kernel_inputs = frozenset({"speed"})


@njit(cache=True)
def _frame_floor_bounds(
    params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, lo, hi
):
    """The base's vertical step Δq_z >= floor − p_z of a frame (params: the floor)."""
    for i in range(lo.shape[0]):
        lo[i] = -np.inf
        hi[i] = np.inf
    lo[2] = params[0] - ps[slots[0], 2]


class FrameFloor(BoxLimit):
    """A box limit outside the package that reads a frame (its slot): the base may not sink
    so that the frame ends below a floor (to first order, in the base's own z)."""

    name = "frame_floor"
    bound_kernel = staticmethod(_frame_floor_bounds)
    param_fields = ("floor",)

    def __init__(self, robot, frame: str, floor: float) -> None:
        self.frame_id = robot.frame_id(frame)
        self.floor = np.array([floor])

    def frame_ids(self) -> tuple[int, ...]:
        return (self.frame_id,)


@pytest.mark.long(15)
@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_a_box_limit_reading_a_frame_runs_compiled(robot, solver):
    """A user's box limit reading a frame's placement (its slot beside the tasks' frames):
    compiled, and the numpy path's step to 1e-9."""
    q = robot.configuration("walk_ready")
    torso = robot.frame_placement(q, "torso").translation[2]
    steps = {}
    for compiled in (None, False):
        s = solver(_band_stack(robot, q, FrameFloor(robot, "torso", torso)), compiled=compiled)
        steps[compiled] = s.step(q, dt=0.01)
        assert s.compiled_ticks == (1 if compiled is None else 0), s.compiled_reason()
        assert s.last.lower[2] == pytest.approx(0.0, abs=1e-12)  # the floor: the frame now
    assert np.abs(steps[None] - steps[False]).max() < 1e-9


# ---------------------------------------------------------------------- a user's own constraint
@njit(cache=True)
def _frame_above_rows(params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, h, G):
    """A frame stays above a floor: p_z + J_z Δq >= floor ⇔ −J_z Δq <= p_z − floor."""
    s = slots[0]
    frame_jacobian(Jw, supports[s], ps[s], Jf)
    for k in range(G.shape[1]):
        G[0, k] = -Jf[2, k]
    h[0] = ps[s, 2] - params[0]


class FrameAbove(Constraint):
    """An inequality limit written outside the package (a constraint kernel, one row)."""

    row_kernel = staticmethod(_frame_above_rows)
    param_fields = ("floor",)
    rows = 1

    def __init__(self, robot, frame: str, floor: float) -> None:
        super().__init__("frame_above")
        self.frame_id = robot.frame_id(frame)
        self.floor = np.array([floor])

    def frame_ids(self) -> tuple[int, ...]:
        return (self.frame_id,)


class PythonAbove(Constraint):
    """The same row in Python (no constraint kernel)."""

    def __init__(self, robot, frame: str, floor: float) -> None:
        super().__init__("python_above")
        self.frame_id, self.floor = robot.frame_id(frame), floor

    def compute(self, kin):
        fid = self.frame_id
        Jf = np.zeros((6, kin.model.nv))
        frame_jacobian(kin.data.J, kin.robot.frame_support(fid), kin.translation(fid), Jf)
        return Inequality(-Jf[2:3].copy(), np.array([kin.translation(fid)[2] - self.floor]))


def _sinking_stack(robot, q, constraint):
    """Both soles held, the CoM pulled 2 cm down; the torso kept above a floor 1 mm below it."""
    stack = TaskStack(robot)
    kin = Kinematics(robot, q)
    for sole in ("l_sole", "r_sole"):
        stack.add(ContactTask(robot, sole, name=sole), level=0, hard=True).set_target_from(kin)
    stack.add(ComTask(robot, kin.com - [0.0, 0.0, 0.02]), level=1)
    stack.add(PostureTask(robot, q[7:]), level=2, weight=1e-3)
    stack.add_constraint(constraint, level=0)
    return _one_user_set(robot, stack)


@pytest.mark.long(15)
@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_a_constraint_defined_outside_the_package_runs_compiled(robot, solver):
    """A user's inequality limit (a constraint kernel, in a module outside wbc): its rows
    are the Python twin's, the stack stays on the compiled path, the row binds (the torso
    stops at the floor), and the compiled step is the numpy path's to 1e-9."""
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    torso = robot.frame_id("torso")
    floor = kin.translation(torso)[2] - 0.001
    user, twin = FrameAbove(robot, "torso", floor), PythonAbove(robot, "torso", floor)
    (G, h), (G2, h2) = user.compute(kin), twin.compute(kin)
    assert np.array_equal(G, G2) and np.array_equal(h, h2)
    steps = {}
    for compiled in (None, False):
        s = solver(_sinking_stack(robot, q, FrameAbove(robot, "torso", floor)), compiled=compiled)
        steps[compiled] = s.step(q, dt=0.01)
        assert s.compiled_ticks == (1 if compiled is None else 0), s.compiled_reason()
    assert np.abs(steps[None] - steps[False]).max() < 1e-9
    dq = pin.difference(robot.model, q, steps[None])
    assert G @ dq - h == pytest.approx([0.0], abs=1e-9)  # it binds: the torso at the floor
    free = solver(_sinking_stack(robot, q, FrameAbove(robot, "torso", floor - 1.0)))
    assert G @ pin.difference(robot.model, q, free.step(q, dt=0.01)) > h + 1e-4  # (else below)
    s = solver(_sinking_stack(robot, q, twin))
    assert np.abs(s.step(q, dt=0.01) - steps[None]).max() < 1e-9


def test_a_constraint_kernel_needs_its_rows(robot):
    class NoRows(Constraint):
        row_kernel = staticmethod(_frame_above_rows)

    with pytest.raises(ConfigurationError, match="no rows count"):
        NoRows("no_rows").compute(Kinematics(robot, robot.configuration("walk_ready")))


def test_a_constraint_without_rows_of_its_own_is_named():
    with pytest.raises(ConfigurationError, match="neither a row_kernel nor compute"):
        Constraint("bare").compute(None)
    with pytest.raises(ConfigurationError, match=r"constraint type Bad: kernel_inputs"):

        class Bad(FrameAbove):
            kernel_inputs = frozenset({"speed"})
