"""ZMP preview control of the cart-table model (Kajita et al., ICRA 2003).

Per horizontal axis the CoM is a cart on a table of height ``zc``, driven by its jerk ``u``:

    x_k+1 = A x_k + B u_k,   x = [c, c', c''],   p_k = C x_k = c - (zc / g) c''   (the ZMP)

with ``A = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]``, ``B = [dt^3/6, dt^2/2, dt]``. The
servo with integral action and preview (Katayama et al. 1985, as used by Kajita) minimises
``sum Qe e_k^2 + R du_k^2`` with ``e = p - p_ref`` on the augmented system
``[e; dx]``; with ``P`` from the discrete Riccati equation (scipy), the gains are
``[Gi, Gx] = (R + B~' P B~)^-1 B~' P A~`` and the preview gains ``Gp(1) = -Gi``,
``Gp(j) = (R + B~' P B~)^-1 B~' X_j-1``, ``X_1 = -Ac' P I~``, ``X_j = Ac' X_j-1``, and

    u_k = -Gi sum_{i<=k} e_i - Gx x_k - sum_{j=1..NL} Gp(j) p_ref,k+j.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.linalg import solve_discrete_are

from ..exceptions import TrajectoryError
from .lipm import GRAVITY


@dataclass(frozen=True)
class PreviewParams:
    """Preview horizon (s) and LQ weights (ZMP error, jerk increment)."""

    preview_time: float = 1.0
    q_error: float = 1.0
    r_input: float = 1e-8

    def validate(self) -> None:
        if not (self.preview_time > 0 and self.q_error > 0 and self.r_input > 0):
            raise TrajectoryError(f"preview control: parameters must be positive, got {self}")


def cart_table(
    dt: float, zc: float, g: float = GRAVITY
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete cart-table model ``(A (3,3), B (3,), C (3,))`` with jerk input."""
    A = np.array([[1.0, dt, dt * dt / 2.0], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    B = np.array([dt**3 / 6.0, dt * dt / 2.0, dt])
    C = np.array([1.0, 0.0, -zc / g])
    return A, B, C


class PreviewController:
    """Kajita's preview controller for one sampling time and CoM height (both axes)."""

    def __init__(
        self, dt: float, zc: float, params: PreviewParams | None = None, g: float = GRAVITY
    ) -> None:
        params = params or PreviewParams()
        params.validate()
        if not (dt > 0 and zc > 0):
            raise TrajectoryError(f"preview control: dt and zc must be positive, got {dt}, {zc}")
        self.dt, self.zc, self.params, self.g = dt, zc, params, g
        A, B, C = cart_table(dt, zc, g)
        self.A, self.B, self.C = A, B, C
        At = np.zeros((4, 4))
        At[0, 0] = 1.0
        At[0, 1:] = C @ A
        At[1:, 1:] = A
        Bt = np.concatenate([[C @ B], B])[:, None]
        Qt = np.zeros((4, 4))
        Qt[0, 0] = params.q_error
        R = np.array([[params.r_input]])
        P = solve_discrete_are(At, Bt, Qt, R)
        S = R + Bt.T @ P @ Bt
        K = np.linalg.solve(S, Bt.T @ P @ At)[0]
        self.Gi, self.Gx = float(K[0]), K[1:]
        Ac = At - Bt @ K[None, :]
        It = np.array([[1.0], [0.0], [0.0], [0.0]])
        X = -Ac.T @ P @ It
        self.n_preview = max(1, round(params.preview_time / dt))
        Gp = np.empty(self.n_preview)
        Gp[0] = -self.Gi
        for j in range(1, self.n_preview):
            Gp[j] = np.linalg.solve(S, Bt.T @ X)[0, 0]
            X = Ac.T @ X
        self.Gp = Gp

    def run(
        self, zmp_ref: np.ndarray, x0: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Track ``zmp_ref`` (N, d); returns CoM pos, vel, acc and ZMP, each (N, d).

        ``x0`` (3, d) is the initial [c, c', c'']; default: at rest over ``zmp_ref[0]``.
        The reference is held at its last value beyond the end for the preview.
        """
        pref = np.asarray(zmp_ref, dtype=float)
        pref = pref[:, None] if pref.ndim == 1 else pref
        n, d = pref.shape
        x = np.zeros((3, d)) if x0 is None else np.array(x0, dtype=float).reshape(3, d)
        if x0 is None:
            x[0] = pref[0]
        padded = np.vstack([pref, np.repeat(pref[-1:], self.n_preview + 1, axis=0)])
        # future[k] = sum_j Gp(j) p_ref(k + j), j = 1..NL
        windows = sliding_window_view(padded[1:], self.n_preview, axis=0)[:n]  # (n, d, NL)
        future = windows @ self.Gp
        out = np.empty((4, n, d))
        err_sum = np.zeros(d)
        A, B, C = self.A, self.B, self.C
        for k in range(n):
            p = C @ x
            out[0, k], out[1, k], out[2, k], out[3, k] = x[0], x[1], x[2], p
            err_sum += p - pref[k]
            u = -self.Gi * err_sum - self.Gx @ x - future[k]
            x = A @ x + np.outer(B, u)
        return out[0], out[1], out[2], out[3]
