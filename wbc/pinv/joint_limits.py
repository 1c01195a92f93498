"""Gradient projection of the thesis (com-control-thesis sec. 1.7, eq. 1.44):
``Δq = J†Δx − (I − J†J) k ∇G`` descends a cost G that grows towards the limits
(:data:`wbc.limits.joint_costs.COSTS`: Liégeois, JRA, Marey–Chaumette, Zghal), inside the null
space of the primary task. It acts only in the null space, so it cannot guarantee the limits
(the thesis found it slow and unable to keep a walk within limits); the weighting the thesis
adopts is :class:`wbc.limits.joint_costs.ChanDubeyWeights`.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigurationError
from .pseudoinverse import moore_penrose, null_space_projector

__all__ = ["gradient_projection"]


def gradient_projection(
    J: np.ndarray,
    dx: np.ndarray,
    grad: np.ndarray,
    gain: float = 1.0,
    J_pinv: np.ndarray | None = None,
) -> np.ndarray:
    """Δq = J†Δx − (I − J†J) k ∇G (eq. 1.44), J† Moore–Penrose unless ``J_pinv`` is given."""
    J = np.asarray(J, dtype=float)
    Jp = moore_penrose(J) if J_pinv is None else J_pinv
    grad = np.asarray(grad, dtype=float)
    if grad.shape != (J.shape[1],):
        raise ConfigurationError(f"gradient must have {J.shape[1]} entries, got {grad.shape}")
    return Jp @ dx - null_space_projector(J, Jp) @ (gain * grad)
