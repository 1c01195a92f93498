"""Gaps between foot rectangles, vectorised: the walk engine's clearance check along a swing
(:meth:`wbc.walking.engine.WalkEngine._valid`), one call for every sample of the swing."""

from __future__ import annotations

import math

import numpy as np

from .geometry import Foot


def rectangle_gaps(
    xy: np.ndarray, yaw: np.ndarray, other_xy: np.ndarray, other_yaw: float, foot: Foot
) -> np.ndarray:
    """(N,) distance between the foot rectangle at each of ``xy`` (N, 2), ``yaw`` (N,) and
    the one at ``other_xy``, ``other_yaw``; negative (a separating-axis value) where they
    overlap: :func:`wbc.geometry.polygon_distance` for N rectangles at once."""
    half = 0.5 * np.array([foot.length, foot.width])
    signs = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    c, s_ = np.cos(yaw), np.sin(yaw)
    ax = np.stack([np.stack([c, s_], -1), np.stack([-s_, c], -1)], 1)  # (N, 2 axes, 2)
    A = xy[:, None, :] + np.einsum("kj,nji->nki", signs * half, ax)  # (N, 4, 2) corners
    co, so = math.cos(other_yaw), math.sin(other_yaw)
    bx = np.array([[co, so], [-so, co]])
    B = np.asarray(other_xy, float)[None, :] + (signs * half) @ bx  # (4, 2)
    axes = np.concatenate([ax, np.broadcast_to(bx, ax.shape)], axis=1)  # (N, 4, 2)
    pa = np.einsum("nki,nai->nak", A, axes)  # (N, 4 axes, 4 corners)
    pb = np.einsum("ki,nai->nak", B, axes)
    sep = np.max(
        np.maximum(pb.min(-1) - pa.max(-1), pa.min(-1) - pb.max(-1)), axis=1
    )  # (N,) > 0: apart
    out = sep.copy()
    apart = sep > 0
    if np.any(apart):
        Ai = A[apart]
        d1 = _point_segments(Ai, np.broadcast_to(B, Ai.shape))
        d2 = _point_segments(np.broadcast_to(B, Ai.shape), Ai)
        out[apart] = np.minimum(d1, d2)
    return out


def _point_segments(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(N,) the smallest distance from the points P (N, 4, 2) to the closed polygon edges of
    Q (N, 4, 2)."""
    a = Q
    d = np.roll(Q, -1, axis=1) - Q  # (N, 4, 2) edges
    dd = np.maximum(np.einsum("nei,nei->ne", d, d), 1e-30)
    rel = P[:, :, None, :] - a[:, None, :, :]  # (N, 4 pts, 4 edges, 2)
    t = np.clip(np.einsum("npei,nei->npe", rel, d) / dd[:, None, :], 0.0, 1.0)
    diff = rel - t[..., None] * d[:, None, :, :]
    return np.sqrt(np.min(np.einsum("npei,npei->npe", diff, diff), axis=(1, 2)))
