"""The thesis's pseudo-inverse family (com-control-thesis sec. 1.6) and its adaptive damping.

All four are written as the thesis writes them, and they keep their weaknesses: the
undamped ones fail (raise :class:`~wbc.exceptions.SolverError`) when ``J W⁻¹ Jᵀ`` is
singular and blow up near singularities; the damped ones trade accuracy for robustness.

* Moore–Penrose (1.38): ``J† = Jᵀ (J Jᵀ)⁻¹`` — the minimum-norm solution of ``J Δq = Δx``
  (for a tall ``J``, 1.37: ``(JᵀJ)⁻¹ Jᵀ``, the least-squares solution).
* weighted (1.40): ``J_w† = W⁻¹ Jᵀ (J W⁻¹ Jᵀ)⁻¹`` — minimises ½ ΔqᵀWΔq s.t. ``J Δq = Δx``.
* damped, Levenberg–Marquardt (1.42): ``(JᵀJ + λ²I)⁻¹ Jᵀ`` — minimises
  ``‖J Δq − Δx‖² + λ² ‖Δq‖²``; computed as the identical ``Jᵀ (J Jᵀ + λ²I)⁻¹``.
* weighted-damped (1.43, the thesis's proposal): ``W⁻¹ Jᵀ (J W⁻¹ Jᵀ + λ I)⁻¹`` — minimises
  ``‖J Δq − Δx‖² + λ ΔqᵀWΔq``. Note λ, not λ², as the thesis writes it.

Weights ``W`` are either a full symmetric positive-definite matrix or, as in the thesis (a
diagonal W), a vector of its diagonal. A diagonal weight may be ``inf``: that joint is frozen
(its entry of W⁻¹ is 0) — what the Chan–Dubey weights give at a joint limit.

Adaptive damping (Wang et al. 2013, thesis sec. 1.6.2 and 3.3): halve λ when an iteration
reduces the error, double it and discard the iteration when the error grows
(:class:`AdaptiveDamping`).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigurationError, SolverError

__all__ = [
    "AdaptiveDamping",
    "damped_pinv",
    "inverse_weights",
    "moore_penrose",
    "null_space_projector",
    "weighted_damped_pinv",
    "weighted_pinv",
]


def _check_jacobian(J: np.ndarray) -> np.ndarray:
    J = np.asarray(J, dtype=float)
    if J.ndim != 2 or J.size == 0:
        raise ConfigurationError(f"Jacobian must be a non-empty 2-D array, got shape {J.shape}")
    if not np.all(np.isfinite(J)):
        raise ConfigurationError("Jacobian has non-finite entries")
    return J


def _check_damping(damping: float) -> float:
    if not (np.isfinite(damping) and damping >= 0.0):
        raise ConfigurationError(f"damping λ must be finite and >= 0, got {damping}")
    return float(damping)


def inverse_weights(W: np.ndarray | float, n: int) -> np.ndarray:
    """W⁻¹ of a weight matrix for ``n`` columns: a vector (diagonal W) or an (n, n) matrix.

    Diagonal weights must be > 0; ``inf`` gives 0 (frozen joint). A full W must be symmetric
    positive definite.
    """
    W = np.asarray(W, dtype=float)
    if W.ndim == 0:
        W = np.full(n, float(W))
    if W.ndim == 1:
        if W.shape != (n,):
            raise ConfigurationError(
                f"weights must have {n} entries (one per column), got {W.shape}"
            )
        if np.any(np.isnan(W)) or np.any(W <= 0.0):
            raise ConfigurationError(f"diagonal weights must be > 0 (inf allowed), got {W}")
        return 1.0 / W
    if W.shape != (n, n):
        raise ConfigurationError(f"weight matrix must be ({n}, {n}), got {W.shape}")
    if not np.all(np.isfinite(W)) or not np.allclose(W, W.T):
        raise ConfigurationError("weight matrix must be finite and symmetric")
    try:
        np.linalg.cholesky(W)
    except np.linalg.LinAlgError:
        raise ConfigurationError("weight matrix must be positive definite") from None
    return np.linalg.inv(W)


def _solve_gram(G: np.ndarray, rhs: np.ndarray, what: str) -> np.ndarray:
    """X = G⁻¹ rhs; a singular G is the undamped inverses' weakness: it raises."""
    try:
        X = np.linalg.solve(G, rhs)
    except np.linalg.LinAlgError:
        raise SolverError(f"{what} is singular (the Jacobian lost rank); use damping") from None
    if not np.all(np.isfinite(X)):
        raise SolverError(f"{what} is singular (the Jacobian lost rank); use damping")
    return X


def moore_penrose(J: np.ndarray) -> np.ndarray:
    """Moore–Penrose pseudo-inverse J† = Jᵀ(JJᵀ)⁻¹ (eq. 1.38); (JᵀJ)⁻¹Jᵀ (1.37) if J is tall.

    Raises SolverError when J is rank-deficient (the formula needs full rank).
    """
    J = _check_jacobian(J)
    m, n = J.shape
    if m <= n:
        return _solve_gram(J @ J.T, J, "J Jᵀ").T
    return _solve_gram(J.T @ J, J.T, "Jᵀ J")


def weighted_pinv(J: np.ndarray, W: np.ndarray | float) -> np.ndarray:
    """Weighted pseudo-inverse W⁻¹Jᵀ(JW⁻¹Jᵀ)⁻¹ (eq. 1.40): minimises ½ΔqᵀWΔq s.t. JΔq = Δx."""
    J = _check_jacobian(J)
    Wi = inverse_weights(W, J.shape[1])
    WiJt = Wi[:, None] * J.T if Wi.ndim == 1 else Wi @ J.T
    return _solve_gram(J @ WiJt, WiJt.T, "J W⁻¹ Jᵀ").T


def damped_pinv(J: np.ndarray, damping: float) -> np.ndarray:
    """Damped (Levenberg–Marquardt) pseudo-inverse (JᵀJ + λ²I)⁻¹Jᵀ (eq. 1.42).

    Minimises ‖JΔq − Δx‖² + λ²‖Δq‖². Evaluated through the identity
    (JᵀJ + λ²I)⁻¹Jᵀ = Jᵀ(JJᵀ + λ²I)⁻¹ on the smaller of the two systems.
    """
    J = _check_jacobian(J)
    lam2 = _check_damping(damping) ** 2
    m, n = J.shape
    if m <= n:
        G = J @ J.T
        G.flat[:: m + 1] += lam2
        return _solve_gram(G, J, "J Jᵀ + λ²I").T
    G = J.T @ J
    G.flat[:: n + 1] += lam2
    return _solve_gram(G, J.T, "Jᵀ J + λ²I")


def weighted_damped_pinv(J: np.ndarray, W: np.ndarray | float, damping: float) -> np.ndarray:
    """Weighted-damped pseudo-inverse W⁻¹Jᵀ(JW⁻¹Jᵀ + λI)⁻¹ (eq. 1.43, the thesis's proposal).

    Minimises ‖JΔq − Δx‖² + λ ΔqᵀWΔq (λ enters unsquared, as in the thesis). With λ = 0 it
    is :func:`weighted_pinv`.
    """
    J = _check_jacobian(J)
    lam = _check_damping(damping)
    m = J.shape[0]
    Wi = inverse_weights(W, J.shape[1])
    WiJt = Wi[:, None] * J.T if Wi.ndim == 1 else Wi @ J.T
    G = J @ WiJt
    G.flat[:: m + 1] += lam
    return _solve_gram(G, WiJt.T, "J W⁻¹ Jᵀ + λI").T


def null_space_projector(J: np.ndarray, J_pinv: np.ndarray) -> np.ndarray:
    """I − J⁺J for a generalised inverse J⁺ of J (eqs. 1.25, 1.44, 4.8).

    With an exact inverse (J J⁺ J = J: Moore–Penrose or weighted, full row rank),
    J (I − J⁺J) = 0: whatever is projected leaves the task's velocity unchanged. With a
    damped inverse the projection leaks (J (I − J⁺J) ≠ 0) — a weakness the thesis keeps.
    """
    n = J.shape[1]
    if J_pinv.shape != (n, J.shape[0]):
        raise ConfigurationError(f"J⁺ must have shape {(n, J.shape[0])}, got {J_pinv.shape}")
    P = -(J_pinv @ J)
    P.flat[:: n + 1] += 1.0
    return P


class AdaptiveDamping:
    """λ adapted per iteration (Wang et al. 2013; thesis sec. 1.6.2, DEAV/MSAV in sec. 3.3).

    After an iteration, :meth:`accept` compares the new error with the old one: if it
    decreased, λ ← λ/2 and the iteration is kept; otherwise λ ← 2λ and the caller must discard
    the iteration. λ is kept within [``minimum``, ``maximum``] (not in the thesis: it keeps
    the damped Gram matrix invertible and stops endless doubling); :attr:`exhausted` tells
    that λ reached ``maximum`` after a rejection, i.e. no progress is possible.
    """

    def __init__(self, initial: float, minimum: float = 1e-9, maximum: float = 1e6) -> None:
        if not (0.0 < minimum <= maximum):
            raise ConfigurationError(f"need 0 < minimum <= maximum, got {minimum}, {maximum}")
        self.initial = _check_damping(initial)
        self.minimum = float(minimum)
        self.maximum = float(maximum)
        self.reset()

    def reset(self) -> None:
        self.value = min(max(self.initial, self.minimum), self.maximum)
        self.exhausted = False
        self.rejections = 0

    def accept(self, new_error: float, old_error: float) -> bool:
        """Update λ from the errors before/after an iteration; True to keep the iteration."""
        if new_error < old_error:
            self.value = max(self.value / 2.0, self.minimum)
            self.exhausted = False
            return True
        self.rejections += 1
        self.exhausted = self.value >= self.maximum
        self.value = min(self.value * 2.0, self.maximum)
        return False

    def __repr__(self) -> str:
        return f"AdaptiveDamping(value={self.value:g}, initial={self.initial:g})"
