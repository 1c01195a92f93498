"""The walking loop's targets of a tick copied into the tasks' own arrays in one compiled
call (:meth:`wbc.walking.controller.StackController._copy_targets`), checked as the tasks' setters
check them. Apart from :mod:`wbc.compiled.checks` so that only a walking loop compiles it
(~1 s once, then cached) and the compiled tick does not depend on it."""

from __future__ import annotations

import math

import numpy as np
from numba import carray, njit

from .checks import address, copy_matrix, copy_vector, rotation_defect, squares


@njit(
    "boolean(float64[:], float64[:], float64[:, :], float64[:, :], int64[:, :], float64)",
    cache=True,
)
def copy_targets(
    v0: np.ndarray, v1: np.ndarray, R0: np.ndarray, R1: np.ndarray, outputs, tol: float
) -> bool:
    """Two 3-vectors and two rotations checked as the tasks' setters check them (every entry
    finite; :func:`rotation_defect` <= tol) and, if all four pass, each copied to the
    destinations listed in ``outputs``: rows (address of a C-contiguous float64 target array
    its owner keeps alive, source: 0 v0, 1 v1, 2 R0, 3 R1). False (nothing copied) if a
    check fails, or a vector's :func:`~wbc.compiled.checks.squares` overflow: the setters then
    say which and why."""
    if (
        not math.isfinite(squares(v0) + squares(v1))
        or rotation_defect(R0) > tol
        or rotation_defect(R1) > tol
    ):
        return False
    for k in range(outputs.shape[0]):
        source = outputs[k, 1]
        if source < 2:
            out = carray(address(outputs[k, 0]), (3,), np.float64)  # type: ignore[call-arg]
            copy_vector(v0 if source == 0 else v1, out)
        else:
            out_R = carray(address(outputs[k, 0]), (3, 3), np.float64)  # type: ignore[call-arg]
            copy_matrix(R0 if source == 2 else R1, out_R)
    return True
