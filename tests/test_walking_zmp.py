"""ZMP-based CoM generators keep the ZMP inside the support polygon (wbc.walking.gait,
preview, mpc). The ZMP is recomputed here from the CoM's acceleration,
``zmp = c_xy - (z_c / g) c''_xy``, both from the reference's acceleration and from finite
differences of the CoM positions alone."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from wbc.exceptions import ConfigurationError, TrajectoryError
from wbc.recording import SUPPORT_DOUBLE
from wbc.walking import (
    GaitTiming,
    MpcParams,
    PreviewController,
    PreviewParams,
    forward_walk,
    lateral_walk,
    turning_walk,
)
from wbc.walking.lipm import GRAVITY

WALKS = {
    "forward10": lambda s, **kw: forward_walk(s, 10, 0.035, **kw),
    "turning": lambda s, **kw: turning_walk(s, 8, 0.02, 0.2, **kw),
    "lateral": lambda s, **kw: lateral_walk(s, 6, 0.015, **kw),
}


def needs(gen: str) -> None:
    """Skip unless the generator's optional package is installed (the MPC's casadi)."""
    if gen == "mpc":
        pytest.importorskip("casadi")


class _Walks(dict):
    """``walks[gen, name]``: each walk of :data:`WALKS` by each generator, built on first use."""

    def __init__(self, start) -> None:
        super().__init__()
        self.start = start

    def __missing__(self, key):
        gen, name = key
        self[key] = WALKS[name](self.start, generator=gen)
        return self[key]


@pytest.fixture(scope="module")
def refs(start):
    return _Walks(start)


def zmp_from_acc(ref):
    h = ref.com[:, 2:3]
    return ref.com[:, :2] - h / GRAVITY * ref.com_acc[:, :2]


def zmp_from_positions(ref):
    """Second differences of the CoM positions only (independent of com_acc)."""
    c = ref.com[:, :2]
    acc = np.zeros_like(c)
    acc[1:-1] = (c[2:] - 2 * c[1:-1] + c[:-2]) / ref.dt**2
    return c - ref.com[:, 2:3] / GRAVITY * acc


@pytest.mark.parametrize("walk", list(WALKS))
@pytest.mark.parametrize("gen", ["preview", "mpc", "lipm"])
def test_zmp_inside_support_polygon(refs, gen, walk):
    needs(gen)
    ref = refs[gen, walk]
    z = zmp_from_acc(ref)
    np.testing.assert_allclose(z, ref.zmp, atol=1e-12)
    margin = ref.margins(z)
    assert margin.min() >= ref.margin - 1e-6, (gen, walk, margin.min())
    fd = ref.margins(zmp_from_positions(ref))[1:-1]
    assert fd.min() >= 0.0, (gen, walk, fd.min())  # inside, up to finite-difference error
    # in single support the ZMP is on the stance foot (not merely in a large hull)
    for a, b, _ in ref.phases():
        side = ref.stance_side(a)
        if side is not None:
            sole = ref.sole(side)[0][a:b, :2]
            assert np.all(np.linalg.norm(z[a:b] - sole, axis=1) < 0.5 * ref.foot.width)


@pytest.mark.parametrize("gen", ["preview", "mpc", "lipm"])
def test_com_starts_and_ends_at_rest(refs, start, gen):
    needs(gen)
    for walk in WALKS:
        ref = refs[gen, walk]
        np.testing.assert_allclose(ref.com[0], start.com, atol=1e-9)
        np.testing.assert_allclose(ref.com_vel[0], 0.0, atol=1e-9)
        assert np.linalg.norm(ref.com_vel[-1]) < 2e-3
        mid = 0.5 * (ref.l_sole[-1, :2] + ref.r_sole[-1, :2])
        assert np.linalg.norm(ref.com[-1, :2] - mid) < 2e-3
        np.testing.assert_allclose(ref.com[:, 2], ref.com_height)  # constant height
        # CoM continuous: velocity integrates to position
        dpos = np.diff(ref.com, axis=0)
        vmid = 0.5 * (ref.com_vel[1:] + ref.com_vel[:-1]) * ref.dt
        assert np.max(np.abs(dpos - vmid)) < 2e-5


def test_walk_structure(refs):
    ref = refs["preview", "forward10"]
    assert ref.support[0] == SUPPORT_DOUBLE and ref.support[-1] == SUPPORT_DOUBLE
    singles = [(a, b, s) for a, b, s in ref.phases() if s != SUPPORT_DOUBLE]
    assert len(singles) == 10
    for (a, b, _), step in zip(singles, ref.footsteps, strict=True):
        side = ref.swing_side(a)
        assert side == step.side
        pos, _ = ref.sole(side)
        assert pos[a:b, 2].max() == pytest.approx(0.02, abs=1e-3)  # apex
        np.testing.assert_allclose(pos[b, :2], [step.x, step.y], atol=1e-12)  # lands on the step
    for side in ("left", "right"):
        pos, _ = ref.sole(side)
        assert pos[:, 2].min() >= -1e-12
    # a 10-step forward walk moves ~ 9 x 35 mm
    assert ref.com[-1, 0] - ref.com[0, 0] == pytest.approx(9 * 0.035, abs=6e-3)
    turn = refs["preview", "turning"]
    assert turn.torso_yaw[-1] == pytest.approx(7 * 0.2, abs=0.02)
    assert np.all(np.abs(np.diff(turn.torso_yaw)) < 0.02)  # smooth heading


@pytest.mark.parametrize("walk", list(WALKS))
def test_mpc_enforces_the_margin_as_a_constraint(start, walk):
    """With a 29 mm margin the ZMP must hug the feet centres: the unconstrained tracking
    solution (preview, Kajita's R = 1e-6) violates it, the MPC's inequalities (rotated feet
    too) do not.
    (Hip roll limits off here: they cannot allow a CoM swaying over the sole centres.)"""
    pytest.importorskip("casadi")
    big = 0.029
    kw = dict(zmp_offset=(0.0, 0.0), margin=big, check=False)
    prev = WALKS[walk](start, generator="preview", preview=PreviewParams(r_input=1e-6), **kw)
    assert prev.zmp_margin().min() < big - 1e-3
    ref = WALKS[walk](start, generator="mpc", mpc=MpcParams(hip_roll=False), **kw)
    assert ref.zmp_margin().min() >= big
    assert ref.zmp_margin().min() < big + 1e-4  # the constraint is active
    assert ref.margins(zmp_from_positions(ref))[1:-1].min() > big - 2e-3  # FD error


def test_mpc_keeps_the_hips_within_their_roll_limits(start):
    """A ZMP path 20 mm in from the sole centres makes the preview CoM sway beyond what the
    hips' 5.6 deg inward roll allows; the MPC's CoM inequalities keep it inside."""
    pytest.importorskip("casadi")
    legs = start.legs
    with pytest.raises(TrajectoryError, match="hip would roll"):
        forward_walk(start, 6, generator="preview", zmp_offset=(0.0, 0.02))
    ref = forward_walk(start, 6, generator="mpc", zmp_offset=(0.0, 0.02))
    rolls = legs.leg_rolls(ref.com, ref.torso_yaw, ref.l_sole, ref.r_sole)
    assert -rolls.min() <= legs.max_adduction - legs.roll_margin
    assert -rolls.min() > legs.max_adduction - legs.roll_margin - 2e-3  # active
    assert ref.zmp_margin().min() >= ref.margin


def test_mpc_infeasible_margin_is_reported(start):
    pytest.importorskip("casadi")
    with pytest.raises(TrajectoryError, match="no CoM motion keeps the ZMP"):
        forward_walk(start, 4, generator="mpc", margin=0.031)  # half foot width is 30.5 mm


def test_mpc_low_zmp_weight_uses_the_polygon(start):
    pytest.importorskip("casadi")
    ref = turning_walk(start, 6, generator="mpc", mpc=MpcParams(w_zmp=0.01))
    assert ref.zmp_margin().min() == pytest.approx(ref.margin, abs=1e-4)
    with pytest.raises(TrajectoryError, match="w_zmp"):
        forward_walk(start, 2, generator="mpc", mpc=MpcParams(w_zmp=0.0))


def test_mpc_receding_horizon(start):
    pytest.importorskip("casadi")
    ref = forward_walk(start, 3, generator="mpc", mpc=MpcParams(horizon=0.8, sample_time=0.04))
    assert ref.meta["mpc"]["n_qp"] > 10  # one QP per MPC sample
    assert ref.zmp_margin().min() >= ref.margin


def test_preview_integral_action_removes_steady_error():
    ctrl = PreviewController(0.01, 0.17)
    ref = np.full((300, 1), 0.03)
    ref[:50] = 0.0
    _, _, _, zmp = ctrl.run(ref, np.zeros((3, 1)))
    assert abs(zmp[-1, 0] - 0.03) < 1e-6
    assert np.abs(zmp[:, 0] - ref[:, 0]).max() < 0.03


@pytest.mark.parametrize("gen", ["preview", "mpc"])
def test_jerk_generators_need_double_support(start, gen):
    with pytest.raises(TrajectoryError, match="needs double support"):
        forward_walk(start, 4, generator=gen, timing=GaitTiming(double_support_ratio=0.0))


def test_lipm_walks_without_double_support(start):
    timing = GaitTiming(step_time=0.3, double_support_ratio=0.0)
    ref = forward_walk(start, 4, generator="lipm", timing=timing)
    # on the stance soles, 28.5 mm in from their centres (the default ZMP path)
    assert ref.zmp_margin().min() == pytest.approx(0.0305 - 0.0285, abs=1e-6)


def test_the_mpc_without_casadi_says_how_to_install_it(start, monkeypatch):
    """casadi is optional (the ``mpc`` extra): without it the MPC raises one line naming the
    extra, and the other generators walk."""
    monkeypatch.setitem(sys.modules, "casadi", None)  # `import casadi` fails as if absent
    with pytest.raises(ConfigurationError, match=r"casadi.*pip install \"wbc\[mpc\]\""):
        forward_walk(start, 2, generator="mpc")
    assert forward_walk(start, 2, generator="preview").n > 0
