"""Value types shared by the compiled kernels and the solvers (a leaf: imports only numpy)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: violation up to which a compiled solution counts as meeting the inequality rows (the
#: backends' own primal tolerance is of the same order)
CONSTRAINT_TOL = 1e-9


class Solution(NamedTuple):
    """What one solve returns: Δq, the box it was solved in, and q ⊕ Δq when the compiled
    tick integrated it already (None: not yet)."""

    dq: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    q_next: np.ndarray | None = None


#: the support codes of a tick (which soles bear the weight): the ``support`` channel of a
#: recording (:mod:`wbc.recording`, which exports them) and :func:`wbc.geometry.support_hull`
SUPPORT_DOUBLE = 0
SUPPORT_LEFT = 1
SUPPORT_RIGHT = 2
SUPPORT_NAMES = {SUPPORT_DOUBLE: "double", SUPPORT_LEFT: "left", SUPPORT_RIGHT: "right"}
