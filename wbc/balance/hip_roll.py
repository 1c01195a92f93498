"""The hip strategy's roll of the torso target (``Gains.k_hip``) and the gains' array layout.

:func:`_hip_roll` is the strategy's compiled step (:mod:`wbc.balance.stabilizer` runs it
inside its tick, :func:`~wbc.balance.stabilizer._feedback_tick`): in single support a DCM
estimated beyond ``hip_band`` outward of the stance sole rolls the torso target toward it,
``Exp(h (z × u)) R_ref``. ``hip_axis`` (``Gains``; 0: off) takes that roll about the torso's
own axis: ``z × u`` less its part along the torso's vertical (1: the target's, 2: the
estimate's), so a torso leaned forward is rolled, not twisted (issue 30: s0 ``lateral_wb``
18, the roll about the level axis of a torso leaned 11.5° forward drove both hip yaws to
stall, ringing ~12 Hz; benchmarks/physics.md, nineteenth session).

The ``_K_*`` indices are the layout of the gains' array the compiled tick reads
(:meth:`Stabilizer._consts <wbc.balance.stabilizer.Stabilizer._consts>`), defined once here
for both modules.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .estimator import exp3_into
from .push_jump import JUMP_SIGMA, JUMP_TAU, jumped

# the gains' array (Stabilizer._consts: these, the fall detector's limits, the estimator's
# model): _torso_feedback's five, the hip strategy's four, the fall detector on (1/0), the
# torso's roll scale, the heading part's low-pass cut-off (Hz), its own clip (rad; 0: shared),
# its extra rate gain (s), the ringing's RMS threshold (rad/s; yaw_ring), the lag's (s; lag_yaw)
_K_P, _K_I, _K_D, _K_YAW, _K_MAX_TILT, _K_HIP, _K_BAND, _K_MAX_HIP, _K_RELEASE, _K_FALL = range(10)
_K_ROLL, _K_YAW_CUT, _K_MAX_YAW, _K_YAW_D, _K_RING, _K_LAG = 10, 11, 12, 13, 14, 15
_K_HIP_JUMP = 16  # (hip_jump × hip_band, m; 0: off)
_K_KICK_RELEASE = 17  # (kick_release, rad/s, when hip_kick > 0; else 0: no kick)
_K_TWIST = 18  # (k_twist: the command's part about the target's own vertical axis, scaled)
_K_HIP_AXIS = 19  # (hip_axis: the roll's axis, 0 level, 1 the target's, 2 the torso's)
_K_SIZE = 20


@numba.njit(cache=True, error_model="numpy")
def _hip_roll(
    single: bool,
    stance: np.ndarray,
    other: np.ndarray,
    y_norm: float,
    dcm: np.ndarray,
    h: np.ndarray,
    k: np.ndarray,
    dt: float,
    H: np.ndarray,
    jump: np.ndarray,
    up: np.ndarray,
) -> None:
    """The hip strategy (``k_hip``): writes ``H``, the rotation that turns the torso target
    toward the stance sole's outer side, and updates the roll ``h`` (2, in place). In single
    support, with ``u`` the stance sole's lateral axis pointing away from the other sole (the
    side no step can reach; ``stance``, ``other``: the soles' homogeneous placements,
    ``y_norm`` the lateral axis's length, ``max(hypot, 1e-9)``) and ``s = (ξ − p_stance)·u``
    the estimated DCM's offset from the stance sole's centre along it, the roll wanted is
    ``min(k_hip (s − hip_band)⁺, max_hip)`` along ``u``; ``H = Exp(h (z × u))``, the torso's
    top thrown toward the fall. Spinning the upper body that way takes angular momentum from
    the fall: the centroidal moment pivot moves beyond the sole's edge while the torso
    accelerates (benchmarks/pushes.md). The roll grows at once along its direction; any other
    change (shrinking, turning, double support: back to 0) goes at ``hip_release`` rad/s at
    most (a fast return would throw the DCM out again). With ``k[_K_HIP_JUMP]`` > 0 (m) the
    push trigger (``hip_jump``; ``jump``: the last offset, the single support's ticks, the
    latch, the per-tick change's mean square; updated in place): an offset grown by more than
    that and :data:`~wbc.balance.push_jump.JUMP_SIGMA` × its running RMS in one tick
    (:func:`~wbc.balance.push_jump.jumped`, one-sided; the step adjustment's push trigger
    asks the same both ways), past the support switch's first tick, asks the whole
    ``max_hip`` while the DCM is outward of the sole's centre until the support changes.
    With ``k[_K_HIP_AXIS]`` > 0 (``hip_axis``) the roll's axis ``a = h (z × u)`` is taken
    about the torso's own axis: ``a`` less its part along ``up`` (the torso's vertical, a
    unit vector: the target's or the estimate's), its length kept, so the roll of a torso
    leaned forward is no twist about its own vertical (what the hip yaws would turn)."""
    want0 = want1 = 0.0
    if single:
        y0, y1 = stance[0, 1] / y_norm, stance[1, 1] / y_norm
        p0, p1 = stance[0, 3], stance[1, 3]
        if (p0 - other[0, 3]) * y0 + (p1 - other[1, 3]) * y1 < 0:
            y0, y1 = -y0, -y1
        s = (dcm[0] - p0) * y0 + (dcm[1] - p1) * y1
        threshold = k[_K_HIP_JUMP]
        if threshold > 0:
            if jump[1] >= 2:  # (not across the support switch; outward only)
                share = min(dt / JUMP_TAU, 1.0)
                fired, jump[3] = jumped(s - jump[0], False, threshold, JUMP_SIGMA, share, jump[3])
                if fired:
                    jump[2] = 1.0
            jump[0] = s
            jump[1] += 1
        pushed = jump[2] > 0.5
        s -= 0.0 if pushed else k[_K_BAND]
        if s > 0:
            m = k[_K_MAX_HIP] if pushed else min(k[_K_HIP] * s, k[_K_MAX_HIP])
            want0, want1 = y0 * m, y1 * m
    else:  # (double support: the trigger re-armed; the jitter's mean square kept)
        jump[0], jump[1], jump[2] = 0.0, 0.0, 0.0
    kick = k[_K_KICK_RELEASE] > 0
    if kick and jump[2] > 0.5:
        jump[4] = 1.0  # (hip_kick: the roll after a push shrinks at kick_release)
    h0, h1 = h[0], h[1]
    if want0 * h0 + want1 * h1 >= h0 * h0 + h1 * h1:  # growing along its direction: at once
        h[0], h[1] = want0, want1
    else:  # h + clip_norm(want − h, hip_release dt)
        d0, d1 = want0 - h0, want1 - h1
        n = math.sqrt(d0 * d0 + d1 * d1)
        limit = (k[_K_KICK_RELEASE] if kick and jump[4] > 0.5 else k[_K_RELEASE]) * dt
        if n > limit:
            f = limit / n
            d0, d1 = d0 * f, d1 * f
        h[0], h[1] = h0 + d0, h1 + d1
    if h[0] == 0.0 and h[1] == 0.0:
        jump[4] = 0.0
    v = np.empty(3)
    v[0], v[1], v[2] = -h[1], h[0], 0.0
    if k[_K_HIP_AXIS] > 0:  # (hip_axis: a − (a·up) up, |a| kept)
        n = math.sqrt(v[0] * v[0] + v[1] * v[1])
        d = v[0] * up[0] + v[1] * up[1]
        for i in range(3):
            v[i] -= d * up[i]
        m = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if m > 1e-9:
            for i in range(3):
                v[i] *= n / m
    exp3_into(v, H)
