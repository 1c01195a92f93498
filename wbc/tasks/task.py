"""Base class of all tasks: an error e(q) and its Jacobian J(q), written once.

A task asks for ``J Δq = α e`` with ``e = x* − x`` (target minus current, the thesis's
``Δx = x* − x``) and gain ``α``. Solvers use the same task object as a weighted cost
``w ‖J Δq − α e‖²``, as a hard equality, or at any level of a hierarchy; the pseudo-inverse
baselines use it through the same :meth:`Task.compute`.

A task type is one class with one **row kernel** (a numba function, see :data:`RowKernel`):
it writes the full error and Jacobian into preallocated rows. The base class turns it into
:meth:`Task.compute_error`, :meth:`Task.compute_jacobian` and :meth:`Task.fill` (the numpy
path, the baselines, the tests), and the compiled tick calls the very same kernel for every
task of a stack (:mod:`wbc.solvers.plan`), whichever module defines the class. A task whose
rows cannot be a kernel (they keep state, e.g. :class:`~wbc.tasks.JointLimitDampingTask`)
overrides ``compute_error``/``compute_jacobian`` instead and runs on the numpy path.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

from ..compiled.checks import copy_finite, copy_rotation
from ..compiled.checks import entry as check_entry
from ..compiled.dispatch import refresh_kernel
from ..compiled.signature import OPTIONAL, KernelCall, check_arity, sources
from ..exceptions import TaskError
from ..model import Kinematics

#: ``rows(target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J) -> None``,
#: compiled with ``numba.njit(cache=True)``: the kernels' one signature
#: (:mod:`wbc.compiled.signature`), ``target`` the task's targets packed in one vector (the
#: arrays named by :attr:`Task.target_fields`, in order, rotations row-major), the outputs
#: the full (unmasked) error in ``e[:dim]`` and Jacobian in ``J[:dim]`` (the arrays may be
#: longer).
RowKernel = Callable[..., None]

#: the row kernels of the package's own task classes, in definition order (they join when
#: their class is defined): every compiled tick dispatches over all of them, plus the kernels
#: of any other task type its stack holds, so that the usual stacks share one compiled tick
PACKAGE_KERNELS: list[RowKernel] = []
#: the one table of task types a stack file (TOML) can name, ``type`` -> class: the package's
#: and a user's alike, entered by :func:`register` only (its one writer; a class that sets its
#: own :attr:`Task.stack_type` is registered when it is defined). Read-only here
_STACK_TYPES: dict[str, type[Task]] = {}
STACK_TYPES: Mapping[str, type[Task]] = MappingProxyType(_STACK_TYPES)
#: a task weight is 0 (its rows off) or within this range: the solvers' problems are scaled
#: for it (regularization 1e-6 beside weights up to 1e6; a weight of 1e30 made the weighted
#: Hessian's condition 1e36 and failed a walk's ticks as "infeasible", issue 28). Only the
#: ratios of a level's weights matter, so any intent scales into it
WEIGHT_RANGE = (1e-6, 1e6)


class Objective(NamedTuple):
    """Quadratic cost ½ Δqᵀ H Δq + cᵀ Δq."""

    H: np.ndarray
    c: np.ndarray


class Task:
    """A task of dimension ``dim`` (before masking).

    Args:
        name: unique name in a stack (used in errors and diagnostics).
        gain: α in ``J Δq = α e`` (1 = correct the whole error in one step).
        weight: w, scalar or one value per row of the full task (before masking).
        mask: which rows of the full task are used (bool sequence, default all).
    """

    dim: int = 0
    #: the task's rows (see :data:`RowKernel`), as ``staticmethod(kernel)``; None for a task
    #: that overrides :meth:`compute_error` and :meth:`compute_jacobian` instead
    row_kernel: RowKernel | None = None
    #: the optional kernel inputs the row kernel reads (:data:`wbc.compiled.signature.OPTIONAL`:
    #: "frame_velocities", "momentum", "velocity"), computed only for stacks that need them
    kernel_inputs: frozenset[str] = frozenset()
    #: names of the target arrays the kernel reads, in order (owned by the task, updated in
    #: place: a handle ``h = task.target`` stays valid on every path)
    target_fields: tuple[str, ...] = ()
    #: the ``type`` a stack file gives this task (None: not nameable there); its entry passes
    #: ``frame`` (a frame name), ``name``, ``weight``, ``gain``, ``mask`` and the keys of
    #: :attr:`stack_keys` to ``__init__`` as keywords
    stack_type: str | None = None
    stack_keys: tuple[str, ...] = ()
    #: how many of the first rows of the full error are lengths (m; the rest are angles): a
    #: stack built for a robot divides their weights by its length unit squared
    #: (:func:`wbc.roles.length_unit`, :func:`wbc.stacks.build_stack`)
    length_rows: int = 0
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

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        own = cls.__dict__
        kernel = own.get("row_kernel")
        if isinstance(kernel, staticmethod):
            check_arity(kernel.__func__, f"task type {cls.__name__}: row_kernel")
            refresh_kernel(kernel.__func__)
            if cls.__module__.startswith("wbc.") and kernel.__func__ not in PACKAGE_KERNELS:
                PACKAGE_KERNELS.append(kernel.__func__)
        unknown = set(cls.kernel_inputs) - OPTIONAL
        if unknown:
            raise TaskError(
                f"task type {cls.__name__}: kernel_inputs {sorted(unknown)} unknown; allowed: "
                f"{sorted(OPTIONAL)}"
            )
        if "row_kernel" not in own and any(
            name in own for name in ("compute_error", "compute_jacobian", "fill")
        ):
            cls.row_kernel = None  # its own Python rows: the inherited kernel no longer applies
        if own.get("stack_type") is not None:
            register(cls)
        for name in own.get("target_fields", ()):
            if not isinstance(own.get(name), property):  # (a class's own accessors stay)
                setattr(cls, name, _TargetField(name))

    # ------------------------------------------------------------------ parameters
    def _changed(self) -> None:
        """A parameter baked into the solvers' layouts changed (gain, mask or weight): a new
        layout (:attr:`params_version` is part of its key), re-planned by the stacks' solvers."""
        self.params_version = getattr(self, "params_version", 0) + 1
        self._restructured()

    def _restructured(self) -> None:
        """The task was switched on/off or moved to another frame: the solvers of the stacks
        holding it re-plan (into a layout they may have kept, e.g. per support phase)."""
        for stack in getattr(self, "_stacks", ()):
            stack.revision += 1

    @property
    def active(self) -> bool:
        """Inactive tasks are skipped by every solver (e.g. the swing task in double support)."""
        return self._active

    @active.setter
    def active(self, value: bool) -> None:
        if bool(value) != self._active:
            self._active = bool(value)
            self._restructured()

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
        lo, hi = WEIGHT_RANGE
        if np.any((w != 0) & ((w < lo) | (w > hi))):
            raise TaskError(
                f"task {self.name!r}: each weight must be 0 or within [{lo:g}, {hi:g}] (only "
                f"their ratios within a level matter: scale them into it), got {w}"
            )
        self._weight_full = w
        self._weight = w[self._rows]
        self._changed()

    # ------------------------------------------------------------------ rows
    def frame_ids(self) -> tuple[int, ...]:
        """The frames the row kernel reads (in its ``slots`` order)."""
        fid = getattr(self, "frame_id", None)
        return () if fid is None else (fid,)

    def packed_target(self) -> np.ndarray:
        """The target arrays of :attr:`target_fields` in one new vector (the kernel's layout)."""
        parts = [np.ravel(getattr(self, name)) for name in self.target_fields]
        return np.concatenate(parts) if parts else np.zeros(0)

    def _kernel_rows(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """(e, J), full, from the row kernel at the configuration of ``kin`` (the arrays of
        the task's :class:`~wbc.compiled.signature.KernelCall`, overwritten at its next call)."""
        kernel = type(self).row_kernel
        if kernel is None:
            raise TaskError(
                f"task type {type(self).__name__} defines neither a row_kernel nor "
                "compute_error/compute_jacobian"
            )
        fids = self.frame_ids()
        params = sources(self, self.target_fields)
        call = self.__dict__.get("_kernel_call")
        if call is None or not call.matches(kin, fids, params):
            e, J = np.zeros(self.dim), np.zeros((self.dim, kin.model.nv))
            call = KernelCall(kernel, kin, fids, params, self.kernel_inputs, e, J)
            self._kernel_call = call
        call(kin)
        return call.args[-2], call.args[-1]

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        """Full (unmasked) error e = x* − x at the configuration of ``kin``."""
        return self._kernel_rows(kin)[0].copy()

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        """Full (unmasked) Jacobian of x (so that ẋ = J v), shape (dim, nv)."""
        return self._kernel_rows(kin)[1].copy()

    # ------------------------------------------------------------------ used by solvers
    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """Masked (J, e) as new arrays; also stores e in :attr:`last_error`."""
        J = np.empty((self.rows, kin.model.nv))
        e = np.empty(self.rows)
        self.fill(kin, J, e)
        return J, e

    def fill(self, kin: Kinematics, J_out: np.ndarray, e_out: np.ndarray) -> None:
        """Write the masked Jacobian and error into preallocated rows; :attr:`last_error`
        becomes ``e_out``."""
        if type(self).row_kernel is not None:
            e, J = self._kernel_rows(kin)
        else:
            e, J = self.compute_error(kin), self.compute_jacobian(kin)
        if self._all:
            J_out[:] = J
            e_out[:] = e
        else:
            J_out[:] = J[self._rows]
            e_out[:] = e[self._rows]
        self.last_error = e_out

    def objective(self, kin: Kinematics) -> Objective:
        """Weighted least-squares cost of the task: w ‖J Δq − α e‖² = Δqᵀ H Δq + 2cᵀΔq + …"""
        J, e = self.compute(kin)
        Jw = J * self.weight[:, None]
        return Objective(Jw.T @ J, -self.gain * (Jw.T @ e))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r}, rows={self.rows}, gain={self.gain})"


def register(cls: type[Task]) -> type[Task]:
    """Enter ``cls`` in :data:`STACK_TYPES` under its :attr:`~Task.stack_type` (the one place
    that reads it); returns ``cls``. A class that sets its own ``stack_type`` is registered when
    it is defined; call this for one that inherits it. A name another class holds raises
    :class:`TaskError` naming both (a built-in is never shadowed); the same class again, or a
    class of the same module and qualified name (a notebook cell run again), replaces it."""
    if not (isinstance(cls, type) and issubclass(cls, Task)):
        raise TaskError(f"register takes a Task subclass, got {cls!r}")
    name = cls.stack_type
    where = f"{cls.__module__}.{cls.__qualname__}"
    if not isinstance(name, str) or not name.isidentifier():
        raise TaskError(f"{where}: stack_type must be a name (letters, digits and _), got {name!r}")
    keys = cls.stack_keys
    if not isinstance(keys, tuple) or not all(isinstance(k, str) for k in keys):
        raise TaskError(f"{where}: stack_keys must be a tuple of key names, got {keys!r}")
    held = _STACK_TYPES.get(name)
    if held is not None and held is not cls:
        same = (held.__module__, held.__qualname__) == (cls.__module__, cls.__qualname__)
        if not same:
            raise TaskError(
                f"stack_type {name!r} of {where} is already the type of "
                f"{held.__module__}.{held.__qualname__}: give one of them another stack_type"
            )
    _STACK_TYPES[name] = cls
    return cls


class _TargetField:
    """The attribute ``name`` of :attr:`Task.target_fields`: bound once (in ``__init__``), then
    an assignment ``task.<name> = value`` writes into that array (the compiled plans read it
    by address: a re-bound attribute would be ignored there and honoured on the numpy path),
    checked as the setters check it (finite; a 3x3 one a rotation): a value that fails raises
    :class:`TaskError` and leaves the array as it was. (Only ``__set__``: a read is a plain
    instance attribute read.)"""

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __set__(self, task: Task, value) -> None:
        own = task.__dict__.get(self.name)
        if own is None:
            task.__dict__[self.name] = value
            return
        if own.shape == (3, 3):  # a rotation, checked as the setters check one
            check_rotation(task, value, self.name, out=own)
        else:
            check_vector(task, value, own.size, self.name, out=own)


def check_vector(
    task: Task, value, size: int, what: str = "target", out: np.ndarray | None = None
) -> np.ndarray:
    """Validate a finite vector of a given size for a task (raises :class:`TaskError`);
    ``out``: the task's array to copy it into (in the same compiled call as the check),
    returned."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):  # a string, None, a ragged list...
        raise TaskError(
            f"task {task.name!r}: {what} must be {size} numbers, got {value!r}"
        ) from None
    if v.shape != (size,):
        raise TaskError(f"task {task.name!r}: {what} must have shape ({size},), got {v.shape}")
    if out is not None:
        if _copy_finite(v, out):
            return out
    elif all(map(math.isfinite, v.tolist())):  # 4x np.isfinite(v).all() on short vectors
        return v
    raise TaskError(f"task {task.name!r}: {what} has non-finite values: {v}")


def check_rotation(
    task: Task, value, what: str = "target rotation", out: np.ndarray | None = None
) -> np.ndarray:
    """Validate a 3x3 rotation matrix (finite, orthonormal columns to 1e-6, det +1);
    ``out``: the task's array to copy it into (in the same compiled call), returned."""
    try:
        R = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TaskError(f"task {task.name!r}: {what} must be a 3x3 matrix, got {value!r}") from None
    if R.shape != (3, 3):
        raise TaskError(f"task {task.name!r}: {what} must be a 3x3 matrix, got {R.shape}")
    defect = _rotation_defect(R) if out is None else _copy_rotation(R, out, ROTATION_TOL)
    if defect > ROTATION_TOL:
        if not np.isfinite(R).all():
            raise TaskError(f"task {task.name!r}: {what} has non-finite values")
        raise TaskError(f"task {task.name!r}: {what} is not a rotation matrix")
    return R if out is None else out


#: largest |RᵀR − I| of a target rotation
ROTATION_TOL = 1e-6
#: max |RᵀR − I| (+inf if not finite or det R < 0), compiled: the check runs on every target
#: update of the hot path (numpy's allclose/det would cost tens of µs)
_rotation_defect = check_entry()
#: the same check, copying R into the task's array if it passes; a vector's finiteness check
#: and copy
_copy_rotation = check_entry(copy_rotation)
_copy_finite = check_entry(copy_finite)
