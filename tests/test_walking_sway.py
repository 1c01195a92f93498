"""The closed loop's narrower sway, planned by the walk's own generator
(wbc.walking.gait.narrow_sway, the ZMP path's ``transfer``): CoM and ZMP stay consistent and
the ZMP keeps the walk's margin inside the soles. The ZMP is recomputed here from the CoM and
its acceleration, ``c_xy - c_z c''_xy / (g + c''_z)``."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from wbc.bench.trajectories import build
from wbc.exceptions import TrajectoryError
from wbc.recording import SUPPORT_DOUBLE
from wbc.walking import forward_walk
from wbc.walking.gait import narrow_sway
from wbc.walking.schedule import GaitTiming, build_phases, sample_knots, zmp_knots


def zmp_from_com(ref) -> np.ndarray:
    c, a = ref.com, ref.com_acc
    return c[:, :2] - c[:, 2:3] * a[:, :2] / (ref.g + a[:, 2:3])


def dcm_from_outer_edge(ref, i: int) -> float:
    """The planned DCM's distance (m) from the stance sole's outer edge at tick ``i``."""
    stance = ref.stance_side(i)
    pos, yaw = ref.sole(stance)
    v = np.array([-math.sin(yaw[i]), math.cos(yaw[i])])  # the sole's lateral axis,
    other = ref.sole("right" if stance == "left" else "left")[0]
    v = v if (other[i, :2] - pos[i, :2]) @ v > 0 else -v  # toward the other sole
    return float((ref.dcm_at(i) - pos[i, :2]) @ v + 0.5 * ref.foot.width)


def mid_first_single_support(ref) -> int:
    a, b, _ = next(p for p in ref.phases() if p[2] != SUPPORT_DOUBLE)
    return (a + b) // 2


@pytest.fixture(scope="module")
def walks(robot):
    return {name: build(name, robot) for name in ("walk10", "walk10_wb", "lateral_wb")}


def test_a_short_transfer_reaches_the_landed_sole_early_and_holds_it(start):
    ref = forward_walk(start, 4)
    phases = build_phases(ref.plan, GaitTiming(**ref.meta["timing"]))
    ds = next(ph for ph in phases if ph.kind == "double")
    offset = tuple(ref.meta["zmp_offset"])
    kt, kp = zmp_knots(ref.plan, phases, start.com[:2], offset, transfer=0.25)
    z = sample_knots(kt, kp, ref.t)
    landed = z[ds.i1]  # the next single support's ZMP
    at = ds.i0 + math.ceil(0.25 * (ds.i1 - ds.i0))
    assert np.allclose(z[at : ds.i1 + 1], landed)
    assert not np.allclose(z[ds.i0], landed)
    # transfer = 1: the plan's path, linear over the whole double support
    kt1, kp1 = zmp_knots(ref.plan, phases, start.com[:2], offset, transfer=1.0)
    assert np.allclose(sample_knots(kt1, kp1, ref.t), ref.zmp_ref)
    for bad in (0.0, 1.5, math.nan):
        with pytest.raises(TrajectoryError, match="transfer"):
            zmp_knots(ref.plan, phases, start.com[:2], offset, transfer=bad)


@pytest.mark.parametrize("name", ["walk10", "walk10_wb", "lateral_wb"])
def test_the_narrowed_reference_is_consistent_and_keeps_the_walks_margin(walks, name):
    ref = walks[name]
    out = narrow_sway(ref, 0.15)
    assert out is not ref
    # the same walk: soles, schedule, footsteps
    for field in ("t", "l_sole", "r_sole", "l_sole_yaw", "r_sole_yaw", "support"):
        assert np.array_equal(getattr(out, field), getattr(ref, field))
    assert out.plan is ref.plan
    # consistent: the CoM's own ZMP tracks the generator's ZMP path as the plan's does
    # (overall and in single support, within 0.5 mm)
    zmp = zmp_from_com(out)
    error = np.linalg.norm(zmp - out.zmp_ref, axis=1)
    planned = np.linalg.norm(zmp_from_com(ref) - ref.zmp_ref, axis=1)
    assert error.max() <= planned.max() + 1e-4
    single = out.support != SUPPORT_DOUBLE
    assert error[single].max() <= planned[single].max() + 5e-4
    # position, velocity and acceleration are one jerk-driven (cart-table) motion: with
    # u_k the jerk, dc = dt v + dt²/2 a + dt³/6 u and dv = dt a + dt²/2 u
    dt, c, v, a = out.dt, out.com[:, :2], out.com_vel[:, :2], out.com_acc[:, :2]
    dc = c[1:] - c[:-1] - dt * v[:-1] - 0.5 * dt**2 * a[:-1]
    dv = v[1:] - v[:-1] - dt * a[:-1]
    assert np.allclose(dc, dt / 3 * dv, atol=1e-12)
    # the ZMP of the CoM stays the walk's margin inside the support polygon at every tick
    # (walk10: 1 mm; the whole-body walks: 10 mm), as the plan's
    margins = out.margins(zmp)
    assert ref.margin in (0.001, 0.010)
    assert margins.min() >= ref.margin - 1e-6
    assert ref.margins(zmp_from_com(ref)).min() >= ref.margin - 1e-6
    # narrower: at mid first single support the DCM is >= 3 mm further from the stance
    # sole's outer edge than planned
    i = mid_first_single_support(ref)
    assert dcm_from_outer_edge(out, i) - dcm_from_outer_edge(ref, i) > 0.003
    # a whole-body walk's torso leans for the new CoM, within the window's roll range
    if ref.torso_roll is not None:
        assert not np.array_equal(out.torso_roll, ref.torso_roll)
        assert np.max(np.abs(out.torso_roll)) <= np.max(np.abs(ref.meta["window"]["rolls"])) + 1e-12


def test_without_the_changes_the_generator_gives_the_plan_back(walks):
    ref = walks["walk10"]
    same = narrow_sway(ref, 1.0, inward=False)
    assert np.allclose(same.com, ref.com, atol=1e-12)
    assert np.allclose(same.com_acc, ref.com_acc, atol=1e-9)
    # the transfer alone keeps the plan's ZMP offset; inward alone widens it
    assert narrow_sway(ref, 0.15, inward=False).meta["zmp_offset"] == ref.meta["zmp_offset"]
    widened = narrow_sway(ref, 1.0).meta["zmp_offset"][1]
    assert ref.meta["zmp_offset"][1] < widened <= 0.5 * ref.foot.width - ref.margin


def test_other_references_are_walked_as_planned(robot, start, walks):
    static = build("static_walk", robot)
    assert narrow_sway(static, 0.15) is static
    # single supports longer than `longest` (lateral_wb's last 0.4 s)
    assert narrow_sway(walks["lateral_wb"], 0.15, longest=0.3) is walks["lateral_wb"]
    assert narrow_sway(walks["walk10"], 0.15, longest=0.3) is not walks["walk10"]
    if importlib.util.find_spec("casadi") is not None:  # the MPC's optional package
        mpc = forward_walk(start, 2, generator="mpc")
        assert narrow_sway(mpc, 0.15) is mpc
    lipm = forward_walk(start, 4, generator="lipm")
    out = narrow_sway(lipm, 0.15)
    assert out is not lipm and out.margins(zmp_from_com(out)).min() >= lipm.margin - 1e-6
    for bad in (0.0, -0.1, 2.0, math.inf):
        with pytest.raises(TrajectoryError, match="transfer"):
            narrow_sway(lipm, bad)
