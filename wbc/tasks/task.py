"""Base class of all tasks: an error e(q) and its Jacobian J(q).

A task asks for ``J Δq = α e`` with ``e = x* − x`` (target minus current, the thesis's
``Δx = x* − x``) and gain ``α``. Solvers use the same task object as a weighted cost
``w ‖J Δq − α e‖²``, as a hard equality, or at any level of a hierarchy; the pseudo-inverse
baselines use it through the same :meth:`Task.compute`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..exceptions import TaskError
from ..model import Kinematics

#: bumped whenever a task's structure (active, mask, weight, gain) changes; solvers compare it
#: to decide when to re-plan their preallocated layout (never on a plain target update)
STRUCTURE_EPOCH = [0]


def bump_structure() -> None:
    STRUCTURE_EPOCH[0] += 1


class Objective(NamedTuple):
    """Quadratic cost ½ Δqᵀ H Δq + cᵀ Δq."""

    H: np.ndarray
    c: np.ndarray


class Task(ABC):
    """A task of dimension ``dim`` (before masking).

    Args:
        name: unique name in a stack (used in errors and diagnostics).
        gain: α in ``J Δq = α e`` (1 = correct the whole error in one step).
        weight: w, scalar or one value per row of the full task (before masking).
        mask: which rows of the full task are used (bool sequence, default all).
    """

    dim: int = 0
    #: False for regularisation-like tasks (posture, damping) that never reach zero error;
    #: iterating a pose to convergence ignores them.
    blocks_convergence: bool = True
    #: error e (masked) at the configuration of the last :meth:`compute`
    last_error: np.ndarray

    def __init__(
        self,
        name: str,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        self.name = name
        self._active = True
        self.gain = gain
        self.mask = mask
        self.weight = weight

    # ------------------------------------------------------------------ parameters
    def _changed(self) -> None:
        """A parameter baked into the solvers' layouts changed (gain, mask or weight)."""
        self.params_version = getattr(self, "params_version", 0) + 1
        bump_structure()

    @property
    def active(self) -> bool:
        """Inactive tasks are skipped by every solver (e.g. the swing task in double support)."""
        return self._active

    @active.setter
    def active(self, value: bool) -> None:
        if bool(value) != self._active:
            self._active = bool(value)
            bump_structure()

    @property
    def gain(self) -> float:
        return self._gain

    @gain.setter
    def gain(self, value: float) -> None:
        if not np.isfinite(value) or value < 0:
            raise TaskError(f"task {self.name!r}: gain must be finite and >= 0, got {value}")
        self._gain = float(value)
        self._changed()

    @property
    def mask(self) -> np.ndarray:
        return self._mask

    @mask.setter
    def mask(self, value: Sequence[bool] | None) -> None:
        m = np.ones(self.dim, dtype=bool) if value is None else np.asarray(value, dtype=bool)
        if m.shape != (self.dim,):
            raise TaskError(
                f"task {self.name!r}: mask must have {self.dim} entries, got shape {m.shape}"
            )
        if not m.any():
            raise TaskError(f"task {self.name!r}: mask selects no row")
        self._mask = m
        self._changed()
        self._rows = np.flatnonzero(m)
        self._all = bool(m.all())
        self.last_error = np.zeros(self._rows.size)
        if hasattr(self, "_weight_full"):
            self._weight = self._weight_full[self._rows]

    @property
    def rows(self) -> int:
        """Number of rows after masking."""
        return self._rows.size

    @property
    def weight(self) -> np.ndarray:
        """Per-row weights (after masking)."""
        return self._weight

    @weight.setter
    def weight(self, value: float | Sequence[float]) -> None:
        w = np.asarray(value, dtype=float)
        if w.ndim == 0:
            w = np.full(self.dim, float(w))
        if w.shape != (self.dim,):
            raise TaskError(
                f"task {self.name!r}: weight must be a scalar or {self.dim} values, got {w.shape}"
            )
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise TaskError(f"task {self.name!r}: weights must be finite and >= 0, got {w}")
        self._weight_full = w
        self._weight = w[self._rows]
        self._changed()

    # ------------------------------------------------------------------ to implement
    @abstractmethod
    def compute_error(self, kin: Kinematics) -> np.ndarray:
        """Full (unmasked) error e = x* − x at the configuration of ``kin``."""

    @abstractmethod
    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """Full (unmasked) Jacobian of x (so that ẋ = J v), shape (dim, nv)."""

    # ------------------------------------------------------------------ used by solvers
    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """Masked (J, e) as new arrays; also stores e in :attr:`last_error`."""
        J = np.empty((self.rows, kin.model.nv))
        e = np.empty(self.rows)
        self.fill(kin, J, e)
        return J, e

    def fill(self, kin: Kinematics, J_out: np.ndarray, e_out: np.ndarray) -> None:
        """Write the masked Jacobian and error into preallocated rows (the solvers' hot path).

        :attr:`last_error` becomes ``e_out``. Subclasses may override this for speed; the result
        must equal :meth:`compute_jacobian` / :meth:`compute_error` masked.
        """
        if self._all:
            J_out[:] = self.compute_jacobian(kin)
            e_out[:] = self.compute_error(kin)
        else:
            J_out[:] = self.compute_jacobian(kin)[self._rows]
            e_out[:] = self.compute_error(kin)[self._rows]
        self.last_error = e_out

    def objective(self, kin: Kinematics) -> Objective:
        """Weighted least-squares cost of the task: w ‖J Δq − α e‖² = Δqᵀ H Δq + 2cᵀΔq + …"""
        J, e = self.compute(kin)
        Jw = J * self.weight[:, None]
        return Objective(Jw.T @ J, -self.gain * (Jw.T @ e))

    def error_norm(self) -> float:
        """‖e‖ at the last :meth:`compute`."""
        return float(np.linalg.norm(self.last_error))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r}, rows={self.rows}, gain={self.gain})"


def check_vector(task: Task, value, size: int, what: str = "target") -> np.ndarray:
    """Validate a finite vector of a given size for a task (raises :class:`TaskError`)."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):  # a string, None, a ragged list...
        raise TaskError(
            f"task {task.name!r}: {what} must be {size} numbers, got {value!r}"
        ) from None
    if v.shape != (size,):
        raise TaskError(f"task {task.name!r}: {what} must have shape ({size},), got {v.shape}")
    if not all(map(math.isfinite, v.tolist())):  # 4x np.isfinite(v).all() on short vectors
        raise TaskError(f"task {task.name!r}: {what} has non-finite values: {v}")
    return v


def check_rotation(task: Task, value, what: str = "target rotation") -> np.ndarray:
    """Validate a 3x3 rotation matrix (finite, orthonormal columns to 1e-6, det +1).

    This runs on every target update of the hot path: compiled when numba is available,
    else scalar arithmetic on the nine entries (numpy's allclose/det would cost tens of µs).
    """
    try:
        R = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TaskError(f"task {task.name!r}: {what} must be a 3x3 matrix, got {value!r}") from None
    if R.shape != (3, 3):
        raise TaskError(f"task {task.name!r}: {what} must be a 3x3 matrix, got {R.shape}")
    defect = _rotation_defect(R)
    if defect > 1e-6:
        if not np.isfinite(R).all():
            raise TaskError(f"task {task.name!r}: {what} has non-finite values")
        raise TaskError(f"task {task.name!r}: {what} is not a rotation matrix")
    return R


def _python_rotation_defect(R: np.ndarray) -> float:
    a, b, c, d, e, f, g, h, i = R.ravel().tolist()
    if not math.isfinite(a + b + c + d + e + f + g + h + i):  # NaN and ±inf propagate
        return math.inf
    gram = (
        a * a + d * d + g * g - 1.0, b * b + e * e + h * h - 1.0, c * c + f * f + i * i - 1.0,
        a * b + d * e + g * h, a * c + d * f + g * i, b * c + e * f + h * i,
    )  # fmt: skip
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return math.inf if det < 0 else max(map(abs, gram))


def _first_rotation_defect(R: np.ndarray) -> float:
    """Pick the compiled check if numba imports (once), else the Python one."""
    global _rotation_defect
    try:
        from ..compiled.checks import entry

        _rotation_defect = entry()
    except ImportError:
        _rotation_defect = _python_rotation_defect
    return _rotation_defect(R)


_rotation_defect = _first_rotation_defect
