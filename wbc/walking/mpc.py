"""LIPM model-predictive control of the CoM over its jerk (Wieber 2006), a casadi QP.

Per MPC sample ``k`` (period ``T``) the state of both horizontal axes is
``x = [cx, cx', cx'', cy, cy', cy'']`` and the input the CoM jerk ``u = [ux, uy]``:

    x_k+1 = A x_k + B u_k        (cart-table model, exact for piecewise-constant jerk)
    z_k   = [cx - (h/g) cx'', cy - (h/g) cy'']       (the ZMP)

    minimise  sum_k  w_zmp |z_k - z_ref,k|^2 + w_jerk |u_k|^2
    subject to  H_i z_i <= b_i - margin   (ZMP inside the support polygon at every tick i)
                G_i c_i <= h_i            (both hips within their roll limits, ``hip_roll``)
                x_0 = current state; (whole-walk problem) x_K = at rest over the final ZMP.

The states are decision variables (sparse formulation, banded KKT), so one QP covers a
whole 10-step walk. Between samples the jerk is constant, so the ZMP at every reference
tick is affine in the interval's ``(x_k, u_k)``: the polygon constraints are imposed at every
tick (``H_i z_i <= b_i - margin`` with the support polygon of tick i), not only at the
samples; the hip rows (:meth:`.legs.LegGeometry.lateral_com_bounds`: the pelvis model
makes each hip roll affine in the CoM) likewise act on the CoM at every tick. The jerk
solution is integrated exactly onto the reference grid. With ``horizon``
set, the same QP is solved over a receding window and only the first jerk is applied each
sample (classic MPC).

Solved with ``casadi.conic`` and osqp by default (10-step walk: ~2300 variables, ~6800
constraints, ~25 ms; ``python benchmarks/mpc_timing.py``). Other plugins of this casadi
wheel on that walk: qrqp works (~150 ms); proxqp and highs did not finish within 100 s,
qpoases (dense) within 5 min; daqp and ipqp fail; hpipm needs a staged structure. The cost
is rescaled so that its largest Hessian entry is 1.

casadi is an optional package (``pip install "wbc[mpc]"``); without it the other generators
(``"preview"``, the default, and ``"lipm"``) work and the MPC raises one line saying so.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..exceptions import ConfigurationError, SolverError, TrajectoryError
from ..recording import SUPPORT_LEFT, SUPPORT_RIGHT
from .geometry import Foot, halfplanes, support_polygon
from .legs import LegGeometry
from .lipm import GRAVITY
from .preview import cart_table

NX, NU = 6, 2
_DEFAULT_OPTIONS: dict[str, dict[str, Any]] = {
    "osqp": {
        "osqp": {
            "verbose": False,
            "eps_abs": 1e-6,
            "eps_rel": 1e-6,
            "polishing": True,
            "max_iter": 20000,
        },
        "error_on_fail": False,
    },
    "proxqp": {"proxqp": {"eps_abs": 1e-9, "max_iter": 10000}, "error_on_fail": False},
    "qpoases": {"printLevel": "none", "sparse": True, "error_on_fail": False},
    "highs": {"highs": {"output_flag": False}, "error_on_fail": False},
    "qrqp": {"print_iter": False, "print_header": False, "error_on_fail": False},
    "daqp": {"error_on_fail": False},
    "ipqp": {"print_iter": False, "print_header": False, "error_on_fail": False},
}


def casadi_module() -> Any:
    """The ``casadi`` module, or one clear line saying how to install it
    (:class:`~wbc.exceptions.ConfigurationError`)."""
    try:
        import casadi
    except ModuleNotFoundError as exc:
        raise ConfigurationError(
            "the LIPM MPC (generator \"mpc\") needs the optional package 'casadi': "
            'pip install "wbc[mpc]"'
        ) from exc
    return casadi


@dataclass(frozen=True)
class MpcParams:
    """MPC sampling, horizon, weights and QP backend.

    ``w_zmp`` weighs tracking the planned ZMP (sole centres), ``w_jerk`` the jerk; a small
    ``w_zmp`` (e.g. 0.01) lets the ZMP use the whole polygon down to the margin.
    ``horizon=None`` solves the whole walk as one QP (with a terminal rest constraint);
    a number (s) re-solves a receding window every sample. ``sample_time`` must be a
    multiple of the reference ``dt`` (default: two ticks, 0.02 s at dt = 0.01 s).
    """

    sample_time: float | None = None
    horizon: float | None = None
    w_zmp: float = 1.0
    w_jerk: float = 1e-6
    solver: str = "osqp"
    solver_options: dict[str, Any] = field(default_factory=dict)
    # m added to the ZMP margin in the QP (2x for the hip rows): osqp meets constraints only
    # to ~1e-5 m in hard cases, and the checks afterwards are strict
    tighten: float = 5e-5
    hip_roll: bool = True  # keep the CoM where both hips stay within their roll limits

    def validate(self, dt: float) -> int:
        """Return the number of reference ticks per MPC sample."""
        sample = 2 * dt if self.sample_time is None else self.sample_time
        if not (sample > 0 and self.w_zmp > 0 and self.w_jerk > 0):
            # w_zmp = 0 (pure jerk) is a valid QP but so badly scaled that osqp stalls
            raise TrajectoryError(
                f"MPC: sample_time, w_zmp and w_jerk must be positive, got {self}"
            )
        m = round(sample / dt)
        if m < 1 or abs(m * dt - sample) > 1e-9:
            raise TrajectoryError(
                f"MPC: sample_time {self.sample_time} s is not a multiple of dt = {dt} s"
            )
        if self.horizon is not None and not self.horizon >= 2 * sample:
            raise TrajectoryError(
                f"MPC: the horizon must span at least two samples, got {self.horizon}"
            )
        return m


@dataclass
class MpcResult:
    """CoM on the reference grid (pos, vel, acc (N, 2)), total QP time (s), solver status."""

    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    solve_time: float
    status: str
    n_qp: int = 1
    sample_states: np.ndarray | None = None
    n_variables: int = 0
    n_constraints: int = 0
    build_time: float = 0.0


class LipmMpc:
    """Builds and solves the LIPM jerk QP for a walk."""

    def __init__(self, com_height: float, params: MpcParams | None = None, g: float = GRAVITY):
        if not com_height > 0:
            raise TrajectoryError(f"MPC: the CoM height must be positive, got {com_height}")
        self.h, self.g = float(com_height), float(g)
        self.params = params or MpcParams()

    # ------------------------------------------------------------------ problem data
    def _model(self, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        A1, B1, C1 = cart_table(T, self.h, self.g)
        A = np.kron(np.eye(2), A1)
        B = np.kron(np.eye(2), B1[:, None])
        Cz = np.kron(np.eye(2), C1[None, :])  # (2, 6): ZMP
        return A, B, Cz

    def _zmp_map(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """ZMP at ``tau`` into an interval as ``Zx x_k + Zu u_k`` ((2, 6), (2, 2))."""
        k = self.h / self.g
        zx = np.array([1.0, tau, 0.5 * tau * tau - k])
        zu = tau**3 / 6.0 - k * tau
        return np.kron(np.eye(2), zx[None, :]), zu * np.eye(2)

    def tick_constraints(
        self,
        soles: Any,
        foot: Foot,
        margin: float,
        legs: LegGeometry | None = None,
        heading: np.ndarray | None = None,
        tighten: float = 0.0,
    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """Per tick ``(Hz, bz, Hc, bc)``: ZMP rows ``Hz z <= bz`` (support polygon shrunk by
        ``margin``) and CoM rows ``Hc c_xy <= bc`` (hip roll limits of both legs, if ``legs``;
        else none)."""
        n = len(soles.support)
        cache: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        out = []
        none = (np.zeros((0, 2)), np.zeros(0))
        for i in range(n):
            s = int(soles.support[i])
            left = (*np.round(soles.l_pos[i, :2], 9), round(float(soles.l_yaw[i]), 9))
            right = (*np.round(soles.r_pos[i, :2], 9), round(float(soles.r_yaw[i]), 9))
            key = (s, *(left if s != SUPPORT_RIGHT else ()), *(right if s != SUPPORT_LEFT else ()))
            if key not in cache:
                poly = support_polygon(
                    s, soles.l_pos[i, :2], soles.l_yaw[i], soles.r_pos[i, :2], soles.r_yaw[i], foot
                )
                cache[key] = halfplanes(poly, margin)
            hip = none
            if legs is not None:
                hip_z = self.h + legs.hip_offset[1]
                height = hip_z - (
                    np.array([soles.l_pos[i, 2], soles.r_pos[i, 2]]) + legs.ankle_height
                )
                Gh, bh = legs.lateral_com_bounds(
                    float(heading[i]), soles.l_pos[i, :2], soles.r_pos[i, :2], height
                )
                hip = (Gh, bh - tighten)
            out.append((*cache[key], *hip))
        return out

    def _qp(
        self,
        x0: np.ndarray,
        zref: np.ndarray,
        cons: list[list[tuple[np.ndarray, np.ndarray]]],
        m: int,
        dt: float,
        terminal: np.ndarray | None,
        rows_per_tick: int | None = None,
    ) -> dict[str, Any]:
        """Triplets and bounds of the sparse QP over samples 0..K (K = len(zref) - 1).

        ``cons[k]`` holds the half-planes of the m ticks of interval k (from sample k to
        k + 1); the ZMP at tick j of the interval is affine in ``(x_k, u_k)``.
        """
        p = self.params
        T = m * dt
        A, B, Cz = self._model(T)
        K = len(zref) - 1
        stride = NX + NU
        nvar = K * stride + NX
        xs = np.arange(K + 1) * stride  # first column of x_k
        us = np.arange(K) * stride + NX  # first column of u_k
        # cost 0.5 z'Hz + g'z (upper triangle of H): w_zmp |Cz x_k - zref_k|^2 + w_jerk |u_k|^2
        Qx = 2.0 * p.w_zmp * Cz.T @ Cz
        qi, qj = np.nonzero(np.triu(Qx))
        hr = [(xs[1:, None] + qi).ravel(), (us[:, None] + np.arange(NU)).ravel()]
        hc = [(xs[1:, None] + qj).ravel(), (us[:, None] + np.arange(NU)).ravel()]
        hv = [np.tile(Qx[qi, qj], K), np.full(K * NU, 2.0 * p.w_jerk)]
        grad = np.zeros(nvar)
        grad[(xs[1:, None] + np.arange(NX)).ravel()] = (-2.0 * p.w_zmp * zref[1:] @ Cz).ravel()
        # dynamics: x_k+1 - A x_k - B u_k = 0, rows 6k .. 6k + 5
        ai, aj = np.nonzero(A)
        bi, bj = np.nonzero(B)
        rows0 = np.arange(K)[:, None] * NX
        ar = [
            (rows0 + np.arange(NX)).ravel(),
            (rows0 + ai).ravel(),
            (rows0 + bi).ravel(),
        ]
        ac = [
            (xs[1:, None] + np.arange(NX)).ravel(),
            (xs[:-1, None] + aj).ravel(),
            (us[:, None] + bj).ravel(),
        ]
        av = [np.ones(K * NX), np.tile(-A[ai, aj], K), np.tile(-B[bi, bj], K)]
        n_eq = K * NX
        # ZMP inside the support polygon at every tick of every interval
        maps = [self._zmp_map(j * dt) for j in range(1, m + 1)]
        com_maps = [_com_map(j * dt) for j in range(1, m + 1)]
        cols8 = np.arange(NX + NU)
        G_rows, G_cols, G_vals, ub = [], [], [], []
        row = n_eq
        for k in range(K):
            for j, (Zx, Zu) in enumerate(maps):
                Hz, bz, Hc, bc = cons[k][j]
                Cx, Cu = com_maps[j]
                G = np.vstack([np.hstack([Hz @ Zx, Hz @ Zu]), np.hstack([Hc @ Cx, Hc @ Cu])])
                b = np.concatenate([bz, bc])  # (r, 8) rows on [x_k, u_k]
                r = len(b)
                if rows_per_tick is not None:
                    if r > rows_per_tick:
                        raise TrajectoryError("MPC: more support half-planes than rows reserved")
                    G = np.vstack([G, np.zeros((rows_per_tick - r, NX + NU))])
                    b = np.concatenate([b, np.ones(rows_per_tick - r)])
                    r = rows_per_tick
                G_rows.append(np.repeat(np.arange(row, row + r), NX + NU))
                G_cols.append(np.tile(xs[k] + cols8, r))
                G_vals.append(G.ravel())
                ub.append(b)
                row += r
        ar += G_rows
        ac += G_cols
        av += G_vals
        lba = np.concatenate([np.zeros(n_eq), np.full(row - n_eq, -np.inf)])
        uba = np.concatenate([np.zeros(n_eq), *ub])
        lbx = np.full(nvar, -np.inf)
        ubx = np.full(nvar, np.inf)
        lbx[:NX] = ubx[:NX] = x0
        if terminal is not None:
            lbx[xs[K] : xs[K] + NX] = ubx[xs[K] : xs[K] + NX] = terminal
        cat = np.concatenate
        return dict(
            nvar=nvar,
            ncon=row,
            h=(cat(hr), cat(hc), cat(hv)),
            g=grad,
            a=(cat(ar), cat(ac), cat(av)),
            lba=lba,
            uba=uba,
            lbx=lbx,
            ubx=ubx,
            K=K,
        )

    def _solver(self, qp: dict[str, Any]):
        ca = casadi_module()

        p = self.params
        hs = ca.Sparsity.triplet(qp["nvar"], qp["nvar"], qp["h"][0].tolist(), qp["h"][1].tolist())
        as_ = ca.Sparsity.triplet(qp["ncon"], qp["nvar"], qp["a"][0].tolist(), qp["a"][1].tolist())
        opts = dict(_DEFAULT_OPTIONS.get(p.solver, {"error_on_fail": False}))
        opts.update(p.solver_options)
        try:
            # casadi expects the full symmetric Hessian pattern
            solver = ca.conic("lipm_mpc", p.solver, {"h": hs + hs.T, "a": as_}, opts)
        except Exception as exc:  # plugin missing or options rejected
            raise SolverError(
                f"MPC: cannot create the casadi QP solver {p.solver!r}: {exc}"
            ) from exc
        return solver

    def _solve(self, solver, qp: dict[str, Any]) -> tuple[np.ndarray, str, float]:
        ca = casadi_module()

        hr, hc, hv = qp["h"]
        # scale the cost so its largest Hessian entry is 1 (the minimiser is unchanged;
        # first-order solvers converge much better on a well-scaled problem)
        scale = 1.0 / max(float(np.max(np.abs(hv))), 1e-300)
        Hu = ca.DM.triplet(hr.tolist(), hc.tolist(), ca.DM(hv * scale), qp["nvar"], qp["nvar"])
        H = Hu + Hu.T - ca.diag(ca.diag(Hu))
        ar, ac, av = qp["a"]
        A = ca.DM.triplet(ar.tolist(), ac.tolist(), ca.DM(av), qp["ncon"], qp["nvar"])
        t0 = time.perf_counter()
        sol = solver(
            h=H, g=qp["g"] * scale, a=A, lba=qp["lba"], uba=qp["uba"], lbx=qp["lbx"], ubx=qp["ubx"]
        )
        elapsed = time.perf_counter() - t0
        stats = solver.stats()
        status = str(stats.get("return_status", stats.get("success", "")))
        if not stats.get("success", False):
            if "infeasible" in status.lower():
                raise TrajectoryError(
                    f"MPC: no CoM motion keeps the ZMP inside the support polygons with this "
                    f"margin and the hips within their roll limits ({self.params.solver}: "
                    f"{status}); lower the margin, shorten the steps' single support or widen "
                    "the ZMP path"
                )
            raise SolverError(f"MPC: the {self.params.solver} QP failed ({status})")
        return np.array(sol["x"]).ravel(), status, elapsed

    # ------------------------------------------------------------------ walk
    def solve_walk(
        self,
        t: np.ndarray,
        soles: Any,
        foot: Foot,
        zref_ticks: np.ndarray,
        com0_xy: np.ndarray,
        margin: float,
        legs: LegGeometry | None = None,
        heading: np.ndarray | None = None,
    ) -> MpcResult:
        """CoM for a walk on the tick grid ``t``, starting at rest over ``com0_xy``.

        With ``legs`` (and the torso ``heading`` per tick) the CoM also keeps both hips within
        their roll limits (:meth:`LegGeometry.lateral_com_bounds`)."""
        if legs is not None and heading is None:
            raise TrajectoryError("MPC: the hip roll constraints need the heading per tick")
        wall = time.perf_counter()
        p = self.params
        dt = float(t[1] - t[0])
        m = p.validate(dt)
        n = len(t)
        K = int(np.ceil((n - 1) / m))
        zref = zref_ticks[np.minimum(np.arange(K + 1) * m, n - 1)]
        # slightly tighter than asked: the QP solver's tolerance must not eat the margin
        ticks = self.tick_constraints(
            soles, foot, margin + p.tighten, legs, heading, 2.0 * p.tighten
        )
        # interval k constrains ticks k*m + 1 .. k*m + m (past the end: the last polygon)
        cons = [[ticks[min(k * m + j, n - 1)] for j in range(1, m + 1)] for k in range(K)]
        x0 = np.array([com0_xy[0], 0, 0, com0_xy[1], 0, 0], dtype=float)
        final = np.array([zref_ticks[-1, 0], 0, 0, zref_ticks[-1, 1], 0, 0])
        A, B, _ = self._model(m * dt)
        stride = NX + NU
        if p.horizon is None:
            qp = self._qp(x0, zref, cons, m, dt, final)
            z, status, elapsed = self._solve(self._solver(qp), qp)
            X = np.stack([z[k * stride : k * stride + NX] for k in range(K + 1)])
            U = np.stack([z[k * stride + NX : (k + 1) * stride] for k in range(K)])
            n_qp = 1
        else:
            Kh = max(2, round(p.horizon / (m * dt)))
            rows = max(len(c[1]) + len(c[3]) for c in ticks)
            X = np.zeros((K + 1, NX))
            U = np.zeros((K, NU))
            X[0] = x0
            elapsed, n_qp, status = 0.0, 0, ""
            solver = None
            for k in range(K):
                win = np.arange(k, k + Kh)
                c_win = [cons[min(j, K - 1)] for j in win]
                z_win = zref[np.minimum(np.arange(k, k + Kh + 1), K)]
                qp = self._qp(X[k], z_win, c_win, m, dt, None, rows_per_tick=rows)
                if solver is None:
                    solver = self._solver(qp)
                z, status, dt_solve = self._solve(solver, qp)
                elapsed += dt_solve
                n_qp += 1
                U[k] = z[NX : NX + NU]
                X[k + 1] = A @ X[k] + B @ U[k]
        pos, vel, acc = _resample(X, U, m, dt, n)
        build = time.perf_counter() - wall - elapsed
        return MpcResult(pos, vel, acc, elapsed, status, n_qp, X, qp["nvar"], qp["ncon"], build)


def _com_map(tau: float) -> tuple[np.ndarray, np.ndarray]:
    """CoM position at ``tau`` into an interval as ``Cx x_k + Cu u_k`` ((2, 6), (2, 2))."""
    cx = np.array([1.0, tau, 0.5 * tau * tau])
    return np.kron(np.eye(2), cx[None, :]), (tau**3 / 6.0) * np.eye(2)


def _resample(X: np.ndarray, U: np.ndarray, m: int, dt: float, n: int):
    """Integrate the piecewise-constant jerk exactly onto the reference ticks."""
    i = np.arange(n)
    k = np.minimum(i // m, len(U))
    tau = (i - k * m) * dt
    Uk = np.vstack([U, np.zeros((1, NU))])[k]
    pos = np.empty((n, 2))
    vel = np.empty((n, 2))
    acc = np.empty((n, 2))
    for a in range(2):
        c, v, ac = X[k, 3 * a], X[k, 3 * a + 1], X[k, 3 * a + 2]
        u = Uk[:, a]
        pos[:, a] = c + v * tau + ac * tau**2 / 2 + u * tau**3 / 6
        vel[:, a] = v + ac * tau + u * tau**2 / 2
        acc[:, a] = ac + u * tau
    return pos, vel, acc
