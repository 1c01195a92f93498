"""Limits and constraints: they only provide bounds or inequality rows on Δq.

Two kinds, mirroring pink: a :class:`BoxLimit` bounds each coordinate of Δq
(``lower <= Δq <= upper``, intersected over all box limits: :func:`box_bounds`); a
:class:`Constraint` gives inequality rows ``G Δq <= h``. Solvers stack them, independently of
the QP backend.

A box limit is written once, as a task is: a **bound kernel** (a numba function with the
kernels' one signature, :mod:`wbc.compiled.signature`) writes its lower and upper bounds;
:meth:`BoxLimit.bounds` calls it from Python (the numpy path), the compiled tick calls the
same kernel for every box limit of a stack, wherever its class is defined. The joint
position and velocity limits are two of them.

A constraint is written the same way: a **constraint kernel** (the same signature) writes
its rows h and G; :meth:`Constraint.compute` calls it. The ground clearance and the CoM
support polygon are two of them; a constraint without one (the self-collision pairs, a
:class:`~wbc.limits.LinearInequality`) overrides :meth:`Constraint.compute` instead.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from ..compiled.dispatch import refresh_kernel
from ..compiled.signature import OPTIONAL, KernelCall, check_arity, sources
from ..exceptions import ConfigurationError
from ..model import Kinematics

#: ``bounds(params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, lower,
#: upper) -> None``, compiled with ``numba.njit(cache=True)``: the kernels' one signature
#: (:mod:`wbc.compiled.signature`), ``params`` the limit's parameters packed in one vector
#: (the arrays named by :attr:`BoxLimit.param_fields`, in order), the outputs its bounds on
#: Δq (nv each; ±inf where it sets none)
BoundKernel = Callable[..., None]

#: ``rows(params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, h, G) ->
#: None``, compiled with ``numba.njit(cache=True)``: the kernels' one signature
#: (:mod:`wbc.compiled.signature`), ``params`` the constraint's parameters packed in one
#: vector (the arrays named by :attr:`Constraint.param_fields`, in order), the outputs its
#: rows G Δq <= h (:attr:`Constraint.rows` of them: h, then G)
ConstraintKernel = Callable[..., None]

#: the bound kernels of the package's own box limits, in definition order: every compiled
#: tick holds them (so that the usual stacks share one tick), plus those of its stack's others
PACKAGE_BOUND_KERNELS: list[BoundKernel] = []

#: the constraint kernels of the package's own constraints, in definition order (as
#: :data:`PACKAGE_BOUND_KERNELS`)
PACKAGE_CONSTRAINT_KERNELS: list[ConstraintKernel] = []


def way_back(violation: np.ndarray, fraction: float, most: float) -> np.ndarray:
    """h of the rows of a constraint violated by ``violation`` > 0 at the current
    configuration (a sole corner below the ground, two links inside their margin): the
    row −g'(q) Δq <= h asks a fraction ``fraction`` of the way back per step, at most
    ``most`` (m): h = −min(ξ · violation, most).

    Like a joint outside its range (moved back at the servo's speed, never further out), a
    start that violates a constraint is never asked to jump back in one step (which the
    velocity limits and the hard contacts may not allow), and the row is met from any
    start by a bounded motion."""
    return -np.minimum(fraction * np.asarray(violation, dtype=float), most)


class Bounds(NamedTuple):
    """lower <= Δq <= upper (nv each; ±inf where unbounded)."""

    lower: np.ndarray
    upper: np.ndarray


class Inequality(NamedTuple):
    """G Δq <= h."""

    G: np.ndarray
    h: np.ndarray


class BoxLimit:
    """A limit that bounds every coordinate of Δq.

    Written as a **bound kernel** (:data:`BoundKernel`, ``staticmethod(kernel)``) with the
    arrays it reads named in :attr:`param_fields` (owned by the limit, updated in place: the
    compiled tick reads them by address) and its frames in :meth:`frame_ids`: it then runs
    compiled, wherever its class is defined. A limit without one overrides :meth:`bounds`
    instead, and its stacks run on the numpy path.
    """

    name: str = "box"
    #: the limit's bounds (see :data:`BoundKernel`); None: :meth:`bounds` is overridden
    bound_kernel: BoundKernel | None = None
    #: the names of the arrays the kernel reads (its ``params``), in order
    param_fields: tuple[str, ...] = ()
    #: the optional kernel inputs it reads (:data:`wbc.compiled.signature.OPTIONAL`)
    kernel_inputs: frozenset[str] = frozenset()

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        _define_kernel_type(cls, "bound_kernel", "bounds", PACKAGE_BOUND_KERNELS, "box limit type")

    def frame_ids(self) -> tuple[int, ...]:
        """The frames the bound kernel reads (in its ``slots`` order)."""
        return ()

    def prepare(self, dt: float | None) -> None:
        """Set the parameters that depend on the time step ``dt`` (None: iterating to
        convergence), before the bounds of a solve with it (default: none do)."""
        return None

    def packed_params(self) -> np.ndarray:
        """The arrays of :attr:`param_fields` in one new vector (the kernel's ``params``)."""
        parts = [np.ravel(getattr(self, name)) for name in self.param_fields]
        return np.concatenate(parts).astype(float) if parts else np.zeros(0)

    def bounds(self, kin: Kinematics, dt: float | None) -> Bounds:
        """Bounds on Δq at the configuration of ``kin`` for a step of ``dt`` seconds
        (``dt=None``: iterating to convergence, no time step): the bound kernel's (the arrays
        returned are the limit's own, overwritten by the next call)."""
        kernel = type(self).bound_kernel
        if kernel is None:
            raise ConfigurationError(
                f"box limit type {type(self).__name__} defines neither a bound_kernel nor bounds"
            )
        self.prepare(dt)
        fids = self.frame_ids()
        params = sources(self, self.param_fields)
        call = self.__dict__.get("_kernel_call")
        if call is None or not call.matches(kin, fids, params):
            nv = kin.model.nv
            lower, upper = np.empty(nv), np.empty(nv)
            call = KernelCall(kernel, kin, fids, params, self.kernel_inputs, lower, upper)
            self._kernel_call = call
            self._result = Bounds(lower, upper)
        call(kin)
        return self._result


class _ParamField:
    """The attribute ``name`` of :attr:`BoxLimit.param_fields` (or
    :attr:`Constraint.param_fields`): bound once (in ``__init__``, a float64 array kept as it
    is, e.g. a view of the robot's limits), then an assignment writes into that array (the
    compiled tick and :meth:`BoxLimit.bounds` read it by address: a re-bound attribute would
    be ignored there). (Only ``__set__``: a read is a plain instance attribute read.)"""

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __set__(self, limit: BoxLimit | Constraint, value) -> None:
        own = limit.__dict__.get(self.name)
        if own is None:
            if not (isinstance(value, np.ndarray) and value.dtype == np.float64):
                value = np.array(value, dtype=np.float64)
            limit.__dict__[self.name] = value
            return
        v = np.asarray(value, dtype=float)
        if v.shape != own.shape:
            what = "box limit" if isinstance(limit, BoxLimit) else "constraint"
            raise ConfigurationError(
                f"{what} {limit.name!r}: {self.name} must have shape {own.shape}, got {v.shape}"
            )
        own[...] = v


def box_bounds(
    limits: Sequence[BoxLimit],
    kin: Kinematics,
    dt: float | None,
    lower: np.ndarray,
    upper: np.ndarray,
) -> None:
    """The box of a stack's limits (the joint position limit first) into ``lower``/``upper``:
    each limit's :meth:`BoxLimit.bounds` in turn intersected with what those before leave,
    where one leaves no room it wins, moved towards them (a joint outside its range comes
    back at the servo's speed): :func:`wbc.compiled.boxes.fold_boxes`, as the compiled tick."""
    from ..compiled.boxes import fold_boxes

    boxes = np.empty((len(limits), 2, lower.shape[0]))
    for k, limit in enumerate(limits):
        boxes[k, 0], boxes[k, 1] = limit.bounds(kin, dt)
    fold_boxes(boxes, len(limits), lower, upper)


class Constraint:
    """Linear inequality rows on Δq, usable at any priority level.

    Written as a **constraint kernel** (:data:`ConstraintKernel`, ``staticmethod(kernel)``)
    with the arrays it reads named in :attr:`param_fields` (owned by the constraint, updated
    in place), its frames in :meth:`frame_ids` and its number of rows in :attr:`rows`: the
    kernel writes h (``out1``) and G (``out2``), as a task's row kernel writes its error and
    Jacobian, with the same inputs (:mod:`wbc.compiled.signature`), wherever its class is
    defined. A constraint without one overrides :meth:`compute` instead.
    """

    #: the constraint's rows (see :data:`ConstraintKernel`); None: :meth:`compute` is overridden
    row_kernel: ConstraintKernel | None = None
    #: the names of the arrays the kernel reads (its ``params``), in order
    param_fields: tuple[str, ...] = ()
    #: the optional kernel inputs it reads (:data:`wbc.compiled.signature.OPTIONAL`)
    kernel_inputs: frozenset[str] = frozenset()

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        _define_kernel_type(
            cls, "row_kernel", "compute", PACKAGE_CONSTRAINT_KERNELS, "constraint type"
        )

    #: True if :meth:`split` holds only rows that Δq = 0 meets (h >= 0): every row violated
    #: at ``kin`` is a request, so the rows held never show a violation there (a converged
    #: pose's hard-level error then skips computing them:
    #: :meth:`wbc.solvers.base.StackSolver.solve_pose`)
    held_rows_met = False
    #: True (in the class's own body; a subclass does not inherit it) if the class keeps
    #: :attr:`layout_token`: then a plan checks the rows' layout by that one identity
    keeps_layout_token = False
    #: an object that stands for the constraint's :attr:`rows`, :meth:`frame_ids` and
    #: parameter arrays (their identity): the same object whenever they are the same as when
    #: it was set (e.g. one per frame of a constraint whose frame alternates), another when one
    #: changes; read only where :attr:`keeps_layout_token` (else every tick checks them)
    layout_token: object | None = None

    def __init__(self, name: str) -> None:
        self.name = name
        self._active = True

    @property
    def active(self) -> bool:
        """Inactive constraints are skipped by every solver (e.g. the swing sole's clearance
        in double support); switching re-plans the solvers' layouts."""
        return self._active

    @active.setter
    def active(self, value: bool) -> None:
        if bool(value) != self._active:
            self._active = bool(value)
            for stack in getattr(self, "_stacks", ()):
                stack.revision += 1

    def frame_ids(self) -> tuple[int, ...]:
        """The frames the constraint kernel reads (in its ``slots`` order)."""
        return ()

    @property
    def rows(self) -> int:
        """The number of rows the constraint kernel writes (after :meth:`prepare`)."""
        raise ConfigurationError(
            f"constraint type {type(self).__name__} has a row_kernel but no rows count"
        )

    def prepare(self, kin: Kinematics) -> None:
        """Set the parameters that the rows at ``kin`` need and that its kernel does not
        compute (e.g. a support polygon rebuilt after a support switch), before they are
        computed (default: none)."""
        return None

    def compute(self, kin: Kinematics) -> Inequality:
        """(G, h) at the configuration of ``kin``: the constraint kernel's (the arrays returned
        are the constraint's own, overwritten by the next call)."""
        kernel = type(self).row_kernel
        if kernel is None:
            raise ConfigurationError(
                f"constraint type {type(self).__name__} defines neither a row_kernel nor compute"
            )
        self.prepare(kin)
        fids = self.frame_ids()
        params = sources(self, self.param_fields)
        m = self.rows
        # one call per set of frames (a swing sole's clearance alternates between two)
        calls = self.__dict__.setdefault("_kernel_calls", {})
        call, result = calls.get(fids, (None, None))
        if call is None or not call.matches(kin, fids, params) or result.h.shape[0] != m:
            h, G = np.empty(m), np.empty((m, kin.model.nv))
            call = KernelCall(kernel, kin, fids, params, self.kernel_inputs, h, G)
            result = Inequality(G, h)
            calls[fids] = (call, result)
        call(kin)
        return result

    def split(self, kin: Kinematics, recovering: bool = False) -> tuple[Inequality, Inequality]:
        """The rows at ``kin`` as (rows to hold, requests): a request is a row that Δq = 0
        does not meet because the constraint is violated at ``kin`` itself (a start below the
        ground, links inside their margin) and that asks for the way back
        (:func:`way_back`). A solver that cannot meet the requests with its hard tasks ranks
        them below those, as the best achievable way back
        (:meth:`wbc.solvers.base.StackSolver.solve`). ``recovering``: the rows of the re-solve
        of an infeasible tick, where a constraint may hold its bare bound instead of a rate
        that only smooths its activation (the self-collision damper). Default: every row
        held, the same rows either way."""
        rows = self.compute(kin)
        return rows, Inequality(rows.G[:0], rows.h[:0])

    def forget_rows(self) -> None:
        """The next computation of the rows runs even at the configuration of the last (the
        same rows): a rehearsed first tick runs their code, not a kept answer
        (:meth:`wbc.solvers.base.StackSolver.rehearse`; default: nothing kept)."""
        return None

    def solved(self) -> None:
        """Called by the solvers after each control tick (a solve with a time step) with this
        constraint at a hard level (its rows computed at that tick's configuration): a
        constraint violated at the start and
        not brought back (a request the hard tasks keep unmet) raises
        :class:`~wbc.exceptions.InfeasibleError` here, naming what (default: nothing)."""
        return None

    def violation(self, kin: Kinematics, dq: np.ndarray) -> np.ndarray:
        """max(0, G Δq − h) per row (for diagnostics and tests)."""
        G, h = self.compute(kin)
        return np.maximum(G @ dq - h, 0.0)


def _define_kernel_type(cls, attr: str, own_python: str, package: list, kind: str) -> None:
    """What defining a box limit or a constraint type does: its kernel (class attribute
    ``attr``) checked against the one signature and cached, the package's own listed in
    ``package``; a class with its own Python ``own_python`` method drops an inherited kernel;
    its ``kernel_inputs`` checked; its ``param_fields`` made fields written in place."""
    kernel = cls.__dict__.get(attr)
    if isinstance(kernel, staticmethod):
        check_arity(kernel.__func__, f"{kind} {cls.__name__}: {attr}")
        refresh_kernel(kernel.__func__)
        if cls.__module__.startswith("wbc.") and kernel.__func__ not in package:
            package.append(kernel.__func__)
    elif own_python in cls.__dict__ and attr not in cls.__dict__:
        setattr(
            cls, attr, None
        )  # its own Python rows/bounds: an inherited kernel no longer applies
    unknown = set(cls.kernel_inputs) - OPTIONAL
    if unknown:
        raise ConfigurationError(
            f"{kind} {cls.__name__}: kernel_inputs {sorted(unknown)} unknown; "
            f"allowed: {sorted(OPTIONAL)}"
        )
    for name in cls.__dict__.get("param_fields", ()):
        if not isinstance(cls.__dict__.get(name), property):
            setattr(cls, name, _ParamField(name))
