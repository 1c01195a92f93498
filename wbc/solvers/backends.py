"""QP backends behind one interface, called through their native APIs.

Every backend solves::

    min ½ xᵀ H x + cᵀ x   s.t.   A x = b,   G x <= h,   lower <= x <= upper

(``lower``/``upper`` may hold ±inf). A backend object keeps state between calls of the same
shape (ProxQP and OSQP warm-start from the previous solution).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from ..exceptions import ConfigurationError, InfeasibleError, SolverError

INF = 1e30  # what DAQP and OSQP read as infinity
#: ProxQP's iteration caps, per variable and constraint row (outer) and per outer iteration
#: (inner): the defaults (10,000 x 1,500) let one degenerate level of a hierarchy run for
#: minutes; these bound a solve to ~2,700 inner iterations (~0.15 s for the stacks here),
#: while the stacks' solves need a few hundred (a capped solve is retried once cold)
PROXQP_ITER_PER_ROW = 5
PROXQP_INNER_ITER = 10
#: OSQP's iteration cap per variable and constraint row (was a flat 50,000 whatever the
#: size); a capped solve fails with a SolverError, which the cascade answers by solving the
#: tick with DAQP (solve_cascade_or_daqp)
OSQP_ITER_PER_ROW = 400


class QPWorkspace:
    """Preallocated problem arrays of a fixed shape, filled in place by a solver each tick.

    For some backends the arrays are views into the solver's own packed buffers, so filling
    them is the only copy made.
    """

    def __init__(self, n: int, m_eq: int, m_in: int) -> None:
        self.shape = (n, m_eq, m_in)
        self.H = np.zeros((n, n))
        self.c = np.zeros(n)
        self.A = np.zeros((m_eq, n))
        self.b = np.zeros(m_eq)
        self.G = np.zeros((m_in, n))
        self.h = np.zeros(m_in)
        self.lower = np.full(n, -np.inf)
        self.upper = np.full(n, np.inf)


class QPBackend(ABC):
    """One QP solver; ``solve`` raises InfeasibleError or SolverError on failure."""

    name: str = "backend"

    def __init__(self, eps: float = 1e-9) -> None:
        self.eps = eps
        self.iterations = 0

    def workspace(self, n: int, m_eq: int, m_in: int) -> QPWorkspace:
        """Arrays to fill in place before :meth:`solve_workspace`."""
        return QPWorkspace(n, m_eq, m_in)

    def solve_workspace(self, ws: QPWorkspace) -> np.ndarray:
        """Solve the problem held by a workspace from :meth:`workspace`."""
        return self.solve(ws.H, ws.c, ws.A, ws.b, ws.G, ws.h, ws.lower, ws.upper)

    @abstractmethod
    def solve(
        self,
        H: np.ndarray,
        c: np.ndarray,
        A: np.ndarray,
        b: np.ndarray,
        G: np.ndarray,
        h: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
    ) -> np.ndarray:
        """Return the minimiser x (a new array)."""

    def reset(self) -> None:  # noqa: B027 (optional hook: stateless backends keep it)
        """Forget any warm-start state."""


class DaqpBackend(QPBackend):
    """DAQP (dual active set) via ``daqp.solve``: simple bounds, equalities by sense."""

    name = "daqp"

    def __init__(self, eps: float = 1e-9) -> None:
        super().__init__(eps)
        import daqp

        self._daqp = daqp
        self._shape: tuple[int, int, int] | None = None

    def workspace(self, n: int, m_eq: int, m_in: int) -> QPWorkspace:
        """Workspace whose A, G, b, h, lower, upper are views into DAQP's packed arrays."""
        ws = QPWorkspace(n, m_eq, m_in)
        m = m_eq + m_in
        ws.C = np.zeros((m, n))
        ws.bu = np.zeros(n + m)
        ws.bl = np.zeros(n + m)
        ws.sense = np.zeros(n + m, dtype=np.intc)
        ws.sense[n : n + m_eq] = 5  # equality rows
        ws.bl[n + m_eq :] = -np.inf
        ws.A, ws.G = ws.C[:m_eq], ws.C[m_eq:]
        ws.upper, ws.lower = ws.bu[:n], ws.bl[:n]
        ws.b, ws.h = ws.bu[n : n + m_eq], ws.bu[n + m_eq :]
        ws.upper[:] = np.inf
        ws.lower[:] = -np.inf
        return ws

    def solve_workspace(self, ws: QPWorkspace) -> np.ndarray:
        n, m_eq, _ = ws.shape
        ws.bl[n : n + m_eq] = ws.b
        return self._call(ws.H, ws.c, ws.C, ws.bu, ws.bl, ws.sense)

    def solve(self, H, c, A, b, G, h, lower, upper):
        n, m_eq, m_in = H.shape[0], A.shape[0], G.shape[0]
        if self._shape != (n, m_eq, m_in):
            self._ws = self.workspace(n, m_eq, m_in)
            self._shape = (n, m_eq, m_in)
        ws = self._ws
        ws.A[:] = A
        ws.G[:] = G
        ws.upper[:] = upper
        ws.lower[:] = lower
        ws.b[:] = b
        ws.h[:] = h
        ws.H, ws.c = H, c
        return self.solve_workspace(ws)

    def _call(self, H, c, C, bu, bl, sense) -> np.ndarray:
        x, _, exitflag, info = self._daqp.solve(
            H, c, C, bu, bl, sense, primal_tol=self.eps, sing_tol=1e-11
        )
        for eps_prox in (1e-6, 1e-4):
            if exitflag in (1, 2):
                break
            # DAQP 0.11 can report a feasible but degenerate problem (many rows active at the
            # same point, as on the lower levels of a hierarchy) infeasible (-1), cycling (-2)
            # or with other failure flags (4 was seen); its proximal mode (with a primal
            # tolerance it can meet) solves those, and still reports a truly infeasible
            # problem as infeasible
            x, _, exitflag, info = self._daqp.solve(
                H,
                c,
                C,
                bu,
                bl,
                sense,
                primal_tol=max(self.eps, 1e-8),
                sing_tol=1e-11,
                eps_prox=eps_prox,
            )
        self.iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
        if exitflag in (1, 2):
            return np.asarray(x, dtype=float)
        if exitflag == -1:
            raise InfeasibleError("daqp: the QP is infeasible")
        raise SolverError(f"daqp failed with exit flag {exitflag}")


class ProxqpBackend(QPBackend):
    """ProxQP dense API, one solver object reused with warm start while the shape holds."""

    name = "proxqp"

    def __init__(self, eps: float = 1e-9) -> None:
        super().__init__(eps)
        from proxsuite import proxqp

        self._proxqp = proxqp
        self._qp = None
        self._shape: tuple[int, int, int, bool] | None = None

    def reset(self) -> None:
        self._qp = None
        self._shape = None

    def solve(self, H, c, A, b, G, h, lower, upper):
        args = self._arguments(H, c, A, b, G, h, lower, upper)
        out = self._proxqp.QPSolverOutput
        status = self._solve(args, self.eps)
        if status in (out.PROXQP_PRIMAL_INFEASIBLE, out.PROXQP_MAX_ITER_REACHED):
            # ProxQP 0.8 reports some feasible but degenerate problems (many active bounds,
            # e.g. the lower levels of a hierarchy) primal infeasible at eps_abs < 1e-8, or
            # stalls on them from a warm start; a cold solve at 1e-8 gets most of them
            # through, and a truly infeasible problem stays infeasible
            self.reset()
            status = self._solve(args, max(self.eps, 1e-8))
        self.iterations = int(self._qp.results.info.iter)
        if status == self._proxqp.QPSolverOutput.PROXQP_SOLVED:
            return self._qp.results.x.copy()
        self.reset()  # do not warm start from a failed solve
        if status in (
            self._proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE,
            self._proxqp.QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE,
        ):
            raise InfeasibleError("proxqp: the QP is primal infeasible")
        raise SolverError(f"proxqp failed: {status}")

    @staticmethod
    def _arguments(H, c, A, b, G, h, lower, upper) -> tuple:
        m_eq, m_in = A.shape[0], G.shape[0]
        lq = np.full(m_in, -1e20) if m_in else None  # -inf upsets its infeasibility test
        box = bool(np.isfinite(lower).any() or np.isfinite(upper).any())
        return (
            H,
            c,
            A if m_eq else None,
            b if m_eq else None,
            G if m_in else None,
            lq,
            h if m_in else None,
            *((lower, upper) if box else ()),  # an all-infinite box fails its duality-gap test
        )

    def _solve(self, args: tuple, eps: float):
        proxqp = self._proxqp
        H, A, G = args[0], args[2], args[4]
        n_eq, n_in = 0 if A is None else A.shape[0], 0 if G is None else G.shape[0]
        shape = (H.shape[0], n_eq, n_in, len(args) > 7)
        if self._shape != shape or self._qp.settings.eps_abs != eps:
            qp = proxqp.dense.QP(*shape)
            qp.settings.eps_abs = eps
            qp.settings.eps_rel = 0.0
            qp.settings.eps_primal_inf = 1e-12  # the default 1e-4 fires on feasible problems
            # "solved" only at a duality gap <= eps too: primal and dual residuals alone pass
            # points with multipliers on inactive rows (a gap of 4e-3 on a degenerate level
            # of a hierarchy, Δq 0.12 rad off the optimum, was reported solved)
            qp.settings.check_duality_gap = True
            qp.settings.eps_duality_gap_abs = eps
            qp.settings.eps_duality_gap_rel = 0.0
            qp.settings.verbose = False
            # bounded time per solve: iteration caps scaled to the problem (the defaults,
            # 10,000 outer x 1,500 inner iterations, let one degenerate level run for minutes);
            # a solve that hits them fails with PROXQP_MAX_ITER_REACHED (a SolverError)
            qp.settings.max_iter = PROXQP_ITER_PER_ROW * (shape[0] + shape[1] + shape[2])
            qp.settings.max_iter_in = PROXQP_INNER_ITER
            qp.init(*args)
            self._qp, self._shape = qp, shape
            qp.solve()
            # warm start only once a previous result exists (ProxQP 0.8 crashes otherwise)
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        else:
            self._qp.update(*args)
            self._qp.solve()
        return self._qp.results.info.status


class QuadprogBackend(QPBackend):
    """quadprog (Goldfarb–Idnani): constraints as Cᵀx >= b, finite bounds as rows."""

    name = "quadprog"
    #: room granted on a retry when quadprog calls a degenerate problem inconsistent
    RETRY_ROOM = 1e-9

    def __init__(self, eps: float = 1e-9) -> None:
        super().__init__(eps)
        import quadprog

        self._quadprog = quadprog

    def solve(self, H, c, A, b, G, h, lower, upper):
        lo = np.flatnonzero(np.isfinite(lower))
        hi = np.flatnonzero(np.isfinite(upper))
        n = H.shape[0]
        rows = [A, -G]
        rhs = [b, -h]
        if lo.size:
            rows.append(np.eye(n)[lo])
            rhs.append(lower[lo])
        if hi.size:
            rows.append(-np.eye(n)[hi])
            rhs.append(-upper[hi])
        C = np.vstack(rows).T.copy()
        rhs = np.concatenate(rhs)
        m_eq = A.shape[0]
        try:
            x, *_, iters, _, _ = self._quadprog.solve_qp(H, -c, C, rhs, m_eq)
        except ValueError as exc:
            if "inconsistent" not in str(exc):
                raise SolverError(f"quadprog: {exc}") from exc
            # Goldfarb–Idnani gives up on feasible problems with many rows active at one
            # point (the lower levels of a hierarchy); a little room on the inequalities
            # (not the equalities) lets it through, a truly infeasible problem still fails
            rhs[m_eq:] -= self.RETRY_ROOM
            try:
                x, *_, iters, _, _ = self._quadprog.solve_qp(H, -c, C, rhs, m_eq)
            except ValueError as exc2:
                raise InfeasibleError(f"quadprog: {exc2}") from exc2
        self.iterations = int(iters[0])
        return np.asarray(x, dtype=float)


class OsqpBackend(QPBackend):
    """OSQP (ADMM) with a fixed dense sparsity pattern, updated and warm-started each call."""

    name = "osqp"

    def __init__(self, eps: float = 1e-9) -> None:
        super().__init__(eps)
        import osqp
        from scipy import sparse

        self._osqp = osqp
        self._sparse = sparse
        self._solver = None
        self._shape: tuple[int, int, int] | None = None

    def reset(self) -> None:
        self._solver = None
        self._shape = None

    def solve(self, H, c, A, b, G, h, lower, upper):
        sparse = self._sparse
        n, m_eq, m_in = H.shape[0], A.shape[0], G.shape[0]
        K = np.vstack([A, G, np.eye(n)])
        lo = np.concatenate([b, np.full(m_in, -np.inf), np.clip(lower, -INF, INF)])
        up = np.concatenate([b, h, np.clip(upper, -INF, INF)])
        # dense patterns so that values can be updated in place
        P = sparse.csc_matrix(np.triu(H) + np.triu(np.ones((n, n))) * 1e-300)
        Kc = sparse.csc_matrix(K + 1e-300 * (K == 0))
        if self._shape != (n, m_eq, m_in):
            solver = self._osqp.OSQP()
            solver.setup(
                P,
                c,
                Kc,
                lo,
                up,
                verbose=False,
                eps_abs=max(self.eps, 1e-6),
                eps_rel=1e-6,
                polishing=True,
                max_iter=OSQP_ITER_PER_ROW * (n + m_eq + m_in),
                warm_starting=True,
                polish_refine_iter=10,
            )
            self._solver, self._shape = solver, (n, m_eq, m_in)
        else:
            self._solver.update(q=c, l=lo, u=up, Px=P.data, Ax=Kc.data)
        res = self._solver.solve(raise_error=False)  # the status is checked below
        status = res.info.status
        self.iterations = int(res.info.iter)
        if status in ("solved", "solved inaccurate") and res.x is not None:
            return np.asarray(res.x, dtype=float)
        self.reset()
        if "infeasible" in status:
            raise InfeasibleError(f"osqp: {status}")
        raise SolverError(f"osqp: {status}")


BACKENDS: dict[str, type[QPBackend]] = {
    "daqp": DaqpBackend,
    "proxqp": ProxqpBackend,
    "quadprog": QuadprogBackend,
    "osqp": OsqpBackend,
}


def make_backend(name: str, eps: float = 1e-9) -> QPBackend:
    """A backend by name: ``daqp``, ``proxqp``, ``quadprog`` or ``osqp``."""
    try:
        return BACKENDS[name](eps)
    except KeyError:
        raise ConfigurationError(
            f"unknown QP backend {name!r}; choose from {sorted(BACKENDS)}"
        ) from None


def daqp_for(problems: list) -> list[QPBackend]:
    """One DAQP backend per level, whatever the solver's backend, for the rare re-solves of
    infeasible ticks (the recovery, the diagnosis and ``on_infeasible="relax"``): an exact
    active set (a first-order backend's iteration caps on these degenerate levels cost
    seconds per tick, to fall back to DAQP in the end)."""
    return [make_backend("daqp") for _ in problems]
