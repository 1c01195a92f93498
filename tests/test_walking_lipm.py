"""3-D LIPM (thesis eqs. 1.62-1.68) and the LIPM CoM for a moving ZMP (wbc.walking.lipm)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.exceptions import TrajectoryError
from wbc.walking.lipm import GRAVITY, Lipm3D, lipm_com_for_zmp, lipm_walk_com
from wbc.walking.schedule import sample_knots

coord = st.floats(-0.05, 0.05)
speed = st.floats(-0.3, 0.3)


@given(
    st.floats(0.1, 0.8),
    st.floats(-0.3, 0.3),
    st.floats(-0.3, 0.3),
    coord,
    coord,
    speed,
    speed,
    coord,
    coord,
)
def test_solution_satisfies_the_ode(zc, kx, ky, x0, y0, vx, vy, px, py):
    lipm = Lipm3D(zc, kx, ky)
    dt = 1e-4
    t = np.arange(0.0, 0.6, dt)
    traj = lipm.trajectory(t, [px + x0, py + y0], [vx, vy], pivot=[px, py])
    pos = traj.pos
    # second differences of the position (not the closed-form acceleration)
    acc_fd = (pos[2:, :2] - 2 * pos[1:-1, :2] + pos[:-2, :2]) / dt**2
    rel = pos[1:-1, :2] - [px, py]
    np.testing.assert_allclose(
        acc_fd, (GRAVITY / zc) * rel, atol=1e-5 + 1e-5 * np.abs(rel).max() * GRAVITY / zc
    )
    vel_fd = (pos[2:] - pos[:-2]) / (2 * dt)
    np.testing.assert_allclose(vel_fd, traj.vel[1:-1], atol=1e-6 * (1 + np.abs(traj.vel).max()))
    # CoM on the constraint plane (1.62)
    np.testing.assert_allclose(
        pos[:, 2], zc + kx * (pos[:, 0] - px) + ky * (pos[:, 1] - py), atol=1e-12
    )
    np.testing.assert_allclose(pos[0, :2], [px + x0, py + y0], atol=1e-15)
    np.testing.assert_allclose(traj.vel[0, :2], [vx, vy], atol=1e-15)


@given(st.floats(0.12, 0.4), coord, coord, coord, coord, st.floats(0.1, 1.5))
def test_initial_velocity_reaches_target_at_cycle_time(zc, x0, y0, x1, y1, T):
    lipm = Lipm3D(zc)
    pivot = np.array([0.01, -0.02])
    v0 = lipm.initial_velocity([x0, y0], [x1, y1], T, pivot)
    end = lipm.trajectory(np.array([T]), [x0, y0], v0, pivot).pos[0, :2]
    np.testing.assert_allclose(end, [x1, y1], atol=1e-9)


@given(st.floats(0.12, 0.4), st.floats(-0.04, -0.005), st.floats(0.01, 0.05), st.floats(0.2, 1.2))
def test_cycle_velocity_gives_symmetric_cycle(zc, x0, y0, T):
    lipm = Lipm3D(zc)
    pivot = np.array([0.1, -0.04])
    p0 = pivot + [x0, y0]
    v0 = lipm.cycle_velocity(p0, T, pivot)
    traj = lipm.trajectory(np.array([0.0, T]), p0, v0, pivot)
    np.testing.assert_allclose(traj.pos[1, 0] - pivot[0], -x0, atol=1e-9)  # mirrored over the pivot
    np.testing.assert_allclose(traj.pos[1, 1] - pivot[1], y0, atol=1e-9)  # swings back
    np.testing.assert_allclose(traj.vel[1, 0], traj.vel[0, 0], atol=1e-9)  # x speed kept
    np.testing.assert_allclose(traj.vel[1, 1], -traj.vel[0, 1], atol=1e-9)  # y speed reversed
    assert v0[0] > 0  # moves forward over the pivot


def test_bad_parameters():
    with pytest.raises(TrajectoryError, match="zc"):
        Lipm3D(0.0)
    with pytest.raises(TrajectoryError, match="cycle time"):
        Lipm3D(0.17).cycle_velocity([0, 0], 0.0)
    with pytest.raises(TrajectoryError, match="cycle time"):
        Lipm3D(0.17).initial_velocity([0, 0], [1, 0], -1.0)


def _zig_zag(n_steps=8, T=0.5, s=0.04, w=0.04, ds=0.0):
    """Alternating pivots with (ds > 0) or without (jumps) a linear transfer."""
    times, points = [0.0], [[0.0, 0.0]]
    t = 0.6
    times.append(t)
    points.append([0.0, w])
    for k in range(n_steps):
        p = [k * s, w if k % 2 == 0 else -w]
        times += [t, t + T]
        points += [p, p]
        t += T
        if ds:
            t += ds
    times += [t, t + 0.3, t + 1.5]
    mid = [(n_steps - 1) * s, 0.0]
    points += [[(n_steps - 1) * s, w if (n_steps - 1) % 2 == 0 else -w], mid, mid]
    return np.array(times), np.array(points)


@pytest.mark.parametrize("ds", [0.0, 0.15])
def test_com_for_piecewise_linear_zmp(ds):
    kt, kp = _zig_zag(ds=ds)
    if ds:  # drop the repeated times so the transfers are linear
        keep = np.concatenate([[True], np.diff(kt) > 0])
        kt, kp = kt[keep], kp[keep]
    tc = np.sqrt(0.17 / GRAVITY)
    dt = 1e-3
    t = np.arange(0.0, kt[-1], dt)
    pos, vel, acc = lipm_com_for_zmp(kt, kp, [0.0, 0.0], tc, t)
    zmp = sample_knots(kt, kp, t)
    # ZMP of the CoM is the planned one, and the ODE holds
    np.testing.assert_allclose(pos - tc**2 * acc, zmp, atol=1e-12)
    acc_fd = (pos[2:] - 2 * pos[1:-1] + pos[:-2]) / dt**2
    err = np.abs(acc_fd - acc[1:-1])
    # away from the few ticks at ZMP jumps/kinks the finite-difference acceleration matches
    assert np.quantile(err, 0.98) < 1e-4 * np.abs(acc).max()
    # position and velocity continuous (no jumps between ticks)
    assert np.max(np.abs(np.diff(pos, axis=0))) < 0.5 * dt * (np.abs(vel).max() + 1e-3) * 2
    assert np.max(np.abs(np.diff(vel, axis=0))) < 2 * dt * (np.abs(acc).max() + 1e-3)
    # ends at rest over the last ZMP
    np.testing.assert_allclose(pos[-1], kp[-1], atol=5e-4)
    assert np.all(np.abs(vel[-1]) < 5e-3)


def test_steady_cycle_uses_the_thesis_initial_velocities():
    """With instantaneous support exchange, the chained solution's state at a mid-walk
    exchange is the thesis's symmetric cycle: velocities from Lipm3D.cycle_velocity."""
    T, s, w, zc = 0.5, 0.04, 0.04, 0.17
    kt, kp = _zig_zag(n_steps=12, T=T, s=s, w=w)
    lipm = Lipm3D(zc)
    k = 6  # exchange onto the pivot of step k
    t_ex = kt[2 + 2 * k]
    pos, vel, _ = lipm_com_for_zmp(kt, kp, [0.0, 0.0], lipm.tc, np.array([t_ex]))
    pivot = kp[2 + 2 * k]
    np.testing.assert_allclose(pos[0], [pivot[0] - s / 2, 0.0], atol=2e-4)
    np.testing.assert_allclose(vel[0], lipm.cycle_velocity(pos[0], T, pivot), rtol=2e-3, atol=1e-4)


def test_walk_com_starts_at_rest():
    kt, kp = _zig_zag(ds=0.1)
    keep = np.concatenate([[True], np.diff(kt) > 0])
    kt, kp = kt[keep], kp[keep]
    tc = np.sqrt(0.17 / GRAVITY)
    t = np.arange(0.0, kt[-1], 0.01)
    pos, vel, acc = lipm_walk_com(kt, kp, [0.0, 0.0], tc, t, 0.6)
    np.testing.assert_allclose(pos[0], [0, 0], atol=1e-15)
    np.testing.assert_allclose(vel[0], [0, 0], atol=1e-12)
    np.testing.assert_allclose(acc[0], [0, 0], atol=1e-12)
    # after the start phase it is the LIPM: ZMP on the plan
    after = t >= 0.6
    np.testing.assert_allclose(
        (pos - tc**2 * acc)[after], sample_knots(kt, kp, t[after]), atol=1e-9
    )
    # continuous across the junction
    i = int(np.argmax(after))
    assert np.linalg.norm(vel[i] - vel[i - 1]) < 0.02 * np.abs(vel).max()
