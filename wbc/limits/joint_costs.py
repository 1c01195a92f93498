"""Joint-limit costs and weights of the thesis (com-control-thesis sec. 1.7): pure functions of
θ and the limits, shared by the tasks (:class:`wbc.tasks.LimitDampingTask`) and the thesis's
pseudo-inverse schemes (:mod:`wbc.pinv`).

1. **Costs** G that grow towards the limits (θm, θM the limits, θc = (θM + θm)/2,
   Δθ = θM − θm, n joints), descended in a null space by gradient projection
   (:func:`wbc.pinv.joint_limits.gradient_projection`, eq. 1.44):

   * Liégeois (1.45–1.46): ``G = 1/n Σ ((θ − θc)/(θc − θM))²``;
   * Joint Range Availability, JRA (1.47–1.48): ``Σ ((θ − θc)/Δθ)²``;
   * Marey–Chaumette (1.49–1.50): ``G_s = β/2 Σ Δq_i²/Δθ_i`` with Δq_i = θ − θm below
     the range, θ − θM above it, 0 inside: no action inside the range. The thesis prints
     ``Δq_i/Δθ_i`` without the square; that form's gradient β/(2Δθ_i) has the same sign on
     both sides of the range and would push a joint below θm further down, contradicting the
     thesis's own description ("regresarla a su rango operativo"); we use Marey and
     Chaumette's squared form (gradient β Δq_i/Δθ_i);
   * Zghal (1.51): ``H = Σ Δθ_i² / (4 (θM − θ_i)(θ_i − θm))``, infinite at the limits.

2. **Weighting** (Chan & Dubey 1995, eqs. 1.52–1.54), the method the thesis adopts:
   ``w_i = 1 + |∂H/∂θ_i|`` while |∂H/∂θ_i| grows (the joint moves towards a limit), else 1,
   used as the diagonal of W in the weighted (damped) pseudo-inverse. It cannot bring back a
   joint that is already outside its range (for it, ∂H/∂θ changes sign and the rule breaks
   down), and at a limit the weight is infinite (the joint freezes).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..exceptions import ConfigurationError

__all__ = [
    "COSTS",
    "ChanDubeyWeights",
    "jra_cost",
    "jra_gradient",
    "liegeois_cost",
    "liegeois_gradient",
    "marey_chaumette_cost",
    "marey_chaumette_gradient",
    "zghal_cost",
    "zghal_gradient",
]


def _limits(theta, lower, upper) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    theta = np.asarray(theta, dtype=float)
    lower = np.broadcast_to(np.asarray(lower, dtype=float), theta.shape)
    upper = np.broadcast_to(np.asarray(upper, dtype=float), theta.shape)
    if np.any(upper <= lower):
        raise ConfigurationError("joint limits must satisfy lower < upper for every joint")
    return theta, lower, upper


# ---------------------------------------------------------------- Liégeois (1.45-1.46)
def liegeois_cost(theta, lower, upper) -> float:
    """G(θ) = 1/n Σ ((θ_i − θc_i)/(θc_i − θM_i))² (eq. 1.45)."""
    theta, lo, hi = _limits(theta, lower, upper)
    c = 0.5 * (hi + lo)
    return float(np.mean(((theta - c) / (c - hi)) ** 2))


def liegeois_gradient(theta, lower, upper) -> np.ndarray:
    """∇G = 2 (θ − θc) / (n (θc − θM)²)."""
    theta, lo, hi = _limits(theta, lower, upper)
    c = 0.5 * (hi + lo)
    return 2.0 * (theta - c) / (theta.size * (c - hi) ** 2)


# ---------------------------------------------------------------- JRA (1.47-1.48)
def jra_cost(theta, lower, upper) -> float:
    """JRA(θ) = Σ ((θ_i − θc_i)/Δθ_i)² (eq. 1.47), Δθ = θM − θm (1.48)."""
    theta, lo, hi = _limits(theta, lower, upper)
    return float(np.sum(((theta - 0.5 * (hi + lo)) / (hi - lo)) ** 2))


def jra_gradient(theta, lower, upper) -> np.ndarray:
    """∇JRA = 2 (θ − θc)/Δθ²."""
    theta, lo, hi = _limits(theta, lower, upper)
    return 2.0 * (theta - 0.5 * (hi + lo)) / (hi - lo) ** 2


# ---------------------------------------------------------------- Marey-Chaumette (1.49-1.50)
def _outside(theta, lo, hi) -> np.ndarray:
    """Δq_i of eq. 1.50: θ − θm below the range, θ − θM above it, 0 inside."""
    return np.where(theta < lo, theta - lo, np.where(theta > hi, theta - hi, 0.0))


def marey_chaumette_cost(theta, lower, upper, beta: float = 1.0) -> float:
    """G_s = β/2 Σ Δq_i²/Δθ_i (eqs. 1.49-1.50, squared as in Marey & Chaumette 2010)."""
    theta, lo, hi = _limits(theta, lower, upper)
    return float(0.5 * beta * np.sum(_outside(theta, lo, hi) ** 2 / (hi - lo)))


def marey_chaumette_gradient(theta, lower, upper, beta: float = 1.0) -> np.ndarray:
    """∇G_s = β Δq_i/Δθ_i: zero inside the range, pointing out of it outside."""
    theta, lo, hi = _limits(theta, lower, upper)
    return beta * _outside(theta, lo, hi) / (hi - lo)


# ---------------------------------------------------------------- Zghal (1.51, 1.53)
def zghal_cost(theta, lower, upper) -> float:
    """H(θ) = Σ Δθ_i² / (4 (θM_i − θ_i)(θ_i − θm_i)) (eq. 1.51); inf at or beyond a limit."""
    theta, lo, hi = _limits(theta, lower, upper)
    den = 4.0 * (hi - theta) * (theta - lo)
    if np.any(den <= 0.0):
        return float("inf")
    return float(np.sum((hi - lo) ** 2 / den))


def zghal_gradient(theta, lower, upper) -> np.ndarray:
    """∂H/∂θ_i = Δθ_i² (2θ_i − θM_i − θm_i) / (4 (θM_i − θ_i)² (θ_i − θm_i)²) (eq. 1.53).

    ±inf exactly at a limit. Beyond a limit the formula is finite again and its sign points
    the wrong way (the reason Chan–Dubey cannot recover a joint that is outside).
    """
    theta, lo, hi = _limits(theta, lower, upper)
    num = (hi - lo) ** 2 * (2.0 * theta - hi - lo)
    den = 4.0 * (hi - theta) ** 2 * (theta - lo) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        g = num / den
    return np.where(den == 0.0, np.copysign(np.inf, 2.0 * theta - hi - lo), g)


#: name -> (cost, gradient) for :func:`gradient_projection` and the schemes' null-space term
COSTS: dict[str, tuple[Callable[..., float], Callable[..., np.ndarray]]] = {
    "liegeois": (liegeois_cost, liegeois_gradient),
    "jra": (jra_cost, jra_gradient),
    "marey_chaumette": (marey_chaumette_cost, marey_chaumette_gradient),
    "zghal": (zghal_cost, zghal_gradient),
}


class ChanDubeyWeights:
    """Joint-limit weights of Chan & Dubey (1995), eqs. 1.52–1.54.

    ``update(θ)`` returns w with ``w_i = 1 + |∂H/∂θ_i|`` if ``|∂H/∂θ_i|`` did not decrease
    since the previous call (Δ|∂H/∂θ_i| >= 0, eq. 1.54), else 1. Before the first call the
    previous |∂H/∂θ| is taken as 0, so the first weights are 1 + |∂H/∂θ| (a joint at mid-range
    has ∂H/∂θ = 0, weight 1). Call :meth:`reset` at the start of a new motion.
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray) -> None:
        self.lower = np.asarray(lower, dtype=float).copy()
        self.upper = np.asarray(upper, dtype=float).copy()
        _limits(self.lower, self.lower, self.upper)
        self.reset()

    def reset(self) -> None:
        self.previous = np.zeros_like(self.lower)
        self.weights = np.ones_like(self.lower)

    def update(self, theta: np.ndarray) -> np.ndarray:
        """Weights at θ given the previous call's |∂H/∂θ| (eq. 1.52); stores the new one."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape != self.lower.shape:
            raise ConfigurationError(f"θ must have shape {self.lower.shape}, got {theta.shape}")
        g = np.abs(zghal_gradient(theta, self.lower, self.upper))
        # Δ|∂H/∂θ| >= 0 as a comparison: at a limit |∂H/∂θ| is inf, and inf - inf would be nan
        growing = (g >= self.previous) | np.isinf(g)
        self.weights = np.where(growing, 1.0 + g, 1.0)
        self.previous = g
        return self.weights
