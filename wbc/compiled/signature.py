"""The one signature of every kernel: a task's rows, a box limit's bounds, a constraint's rows.

A kernel is a numba function (``numba.njit(cache=True)``) that the compiled tick calls for
each task or box limit of a stack, and that the numpy path calls from Python with the same
inputs (:meth:`wbc.tasks.Task.compute_error`, :meth:`wbc.limits.BoxLimit.bounds`,
:meth:`wbc.limits.Constraint.compute`, which every path calls for a constraint)::

    kernel(params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, out1, out2)

Inputs (every kernel gets all of them; read what you need):

* ``params`` — the object's own numbers packed in one vector: a task's targets (the arrays of
  :attr:`~wbc.tasks.Task.target_fields`, in order, matrices row-major), a limit's parameters
  (:attr:`~wbc.limits.BoxLimit.param_fields`, :attr:`~wbc.limits.Constraint.param_fields`);
* ``slots`` — for each frame of its ``frame_ids()``, in order, the frame's index ``s`` into the
  four frame arrays:
* ``Rs[s]`` (3 x 3), ``ps[s]`` (3) — the frame's world rotation and position;
* ``vs[s]`` (6) — its velocity [linear; angular], world axes at the frame origin (J_f v);
* ``supports[s]`` (nv bools) — the dofs that move it: its Jacobian (6 x nv, world axes at
  its origin) is ``wbc.compiled.rows.frame_jacobian(Jw, supports[s], ps[s], Jf)``;
* ``Jw`` (6 x nv) — Pinocchio's joint Jacobians ``data.J`` (spatial, world frame);
* ``com`` (3), ``Jcom`` (3 x nv) — the centre of mass and its Jacobian (world axes);
* ``hg`` (6), ``Ag`` (6 x nv) — the centroidal momentum [linear; angular] about the CoM and
  the centroidal momentum matrix (hg = Ag v);
* ``q`` (nq: 7 base coordinates, then the joints), ``v`` (nv) — the configuration and the
  velocity (``kin.v`` of the kinematics, if they carry one; else zero);
* ``Jf`` (6 x nv) — scratch.

Outputs: a task's row kernel writes its full (unmasked) error e = x* − x into ``out1[:dim]``
and its Jacobian into ``out2[:dim]`` (the arrays may be longer); a box limit's bound kernel
writes its lower and upper bounds on Δq (nv each, ±inf where it sets none) into ``out1`` and
``out2``; a constraint's kernel writes its rows G Δq <= h, h into ``out1`` and G into
``out2`` (:attr:`~wbc.limits.Constraint.rows` of each, exactly).

``vs``, ``hg``, ``Ag`` and ``v`` cost a tick something, so they are computed only for a
stack whose tasks or limits declare them (their class's ``kernel_inputs``, a subset of
:data:`OPTIONAL`); undeclared, they hold zeros. Everything else is always there.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence

import numpy as np

from ..exceptions import ModelError

#: the kernels' inputs, in order (then their two outputs)
INPUTS = (
    "params", "slots", "Rs", "ps", "vs", "supports", "Jw", "com", "Jcom", "hg", "Ag", "q", "v",
    "Jf",
)  # fmt: skip
#: the inputs computed only for a stack whose tasks or limits declare them (``kernel_inputs``):
#: the frames' velocities ``vs``; the centroidal momentum ``hg``, ``Ag``; the velocity ``v``
#: (which the other two read too)
OPTIONAL = frozenset({"frame_velocities", "momentum", "velocity"})


def velocity(kin) -> np.ndarray:
    """The velocity of the kinematics ``kin`` (``kin.v``, nv), zero if they carry none."""
    v = getattr(kin, "v", None)
    nv = kin.model.nv
    if v is None:
        return np.zeros(nv)
    v = np.ascontiguousarray(v, dtype=np.float64)
    if v.shape != (nv,):
        raise ModelError(f"kin.v must have {nv} entries (the robot's nv), got shape {v.shape}")
    return v


def momentum_into(kin, v: np.ndarray, hg: np.ndarray, Ag: np.ndarray) -> None:
    """The centroidal momentum matrix Ag (6 x nv) at ``kin``'s configuration and hg = Ag v,
    into ``hg``/``Ag`` (Pinocchio's ``computeCentroidalMap``, on data of its own: the
    kinematics' data, which every other input reads, is left as it is)."""
    import pinocchio as pin

    data = getattr(kin, "_momentum_data", None)
    if data is None:
        data = kin._momentum_data = kin.model.createData()
    np.copyto(Ag, pin.computeCentroidalMap(kin.model, data, kin.q))
    np.dot(Ag, v, out=hg)


def arguments(
    kin, frame_ids: Sequence[int], params: np.ndarray, inputs: Collection[str] = ()
) -> tuple:
    """A kernel's inputs (:data:`INPUTS`, in order) at the configuration of ``kin``, for a
    call from Python (the numpy path): the frames of ``frame_ids`` in slots 0, 1, ...;
    ``inputs``: the optional ones declared (:data:`OPTIONAL`; the others hold zeros)."""
    from .rows import frame_velocities

    nv = kin.model.nv
    n = max(len(frame_ids), 1)
    Rs = np.zeros((n, 3, 3))
    ps = np.zeros((n, 3))
    supports = np.zeros((n, nv), dtype=np.bool_)
    for s, fid in enumerate(frame_ids):
        Rs[s] = kin.rotation(fid)
        ps[s] = kin.translation(fid)
        supports[s] = kin.robot.frame_support(fid)
    slots = np.arange(len(frame_ids), dtype=np.int64)
    vs = np.zeros((n, 6))
    hg = np.zeros(6)
    Ag = np.zeros((6, nv))
    Jf = np.zeros((6, nv))
    v = velocity(kin) if inputs else np.zeros(nv)
    if "frame_velocities" in inputs:
        frame_velocities(kin.data.J, supports, ps, len(frame_ids), v, Jf, vs)
    if "momentum" in inputs:
        momentum_into(kin, v, hg, Ag)
    return (
        params, slots, Rs, ps, vs, supports, kin.data.J, kin.data.com[0], kin.com_jacobian, hg,
        Ag, kin.q, v, Jf,
    )  # fmt: skip


class KernelCall:
    """A kernel called from Python (the numpy path) at the configurations of one kinematics
    object, for an item (a task, a box limit, a constraint) whose parameters are the arrays
    ``sources`` (bound once, read by address) and whose frames are ``frame_ids``: its inputs
    allocated once and refreshed in place at each call (q and the parameters gathered in one
    compiled call, the frames' placements copied), then its compiled entry point (no type
    dispatch of 16 arguments: the numpy path calls every task's kernel at every tick). The
    outputs are the call's own ``out1``/``out2``, overwritten by the next call."""

    def __init__(
        self,
        kernel,
        kin,
        frame_ids: Sequence[int],
        sources: Sequence[np.ndarray],
        inputs: Collection[str],
        out1: np.ndarray,
        out2: np.ndarray,
    ) -> None:
        from .checks import entry, gather

        self.kernel, self.kin = kernel, kin
        self.frame_ids, self.sources, self.inputs = tuple(frame_ids), list(sources), inputs
        self.addresses = np.array([a.ctypes.data for a in self.sources], dtype=np.int64)
        self.sizes = np.array([a.size for a in self.sources], dtype=np.int64)
        self.params = np.zeros(int(self.sizes.sum()))
        self.q = np.array(kin.q, dtype=np.float64)
        self.gather = entry(gather)
        args = list(arguments(kin, self.frame_ids, self.params))
        args[11] = self.q  # (the kinematics' q is re-bound at each update: a copy)
        self.args = (*args, out1, out2)
        self.frames = [(s, kin.rotation(f), kin.translation(f)) for s, f in enumerate(frame_ids)]
        self.entry = None

    def __getstate__(self) -> dict:
        return {}  # a copy is no call (its addresses would be the original's): rebuilt

    def __setstate__(self, state: dict) -> None:
        self.kin = None

    def matches(self, kin, frame_ids: Sequence[int], sources: Sequence[np.ndarray]) -> bool:
        """True if this call serves ``kin`` with these frames and parameter arrays."""
        return (
            kin is self.kin
            and tuple(frame_ids) == self.frame_ids
            and len(sources) == len(self.sources)
            and all(a is b for a, b in zip(sources, self.sources, strict=True))
        )

    def __call__(self, kin) -> None:
        self.gather(self.addresses, self.sizes, self.params, kin.q, self.q)
        Rs, ps = self.args[2], self.args[3]
        for s, R, p in self.frames:
            Rs[s] = R
            ps[s] = p
        if self.inputs:
            fresh = arguments(kin, self.frame_ids, self.params, self.inputs)
            for k in (4, 9, 10, 12):  # vs, hg, Ag, v
                np.copyto(self.args[k], fresh[k])
        if self.entry is not None:
            self.entry(*self.args)
            return
        from .entry import entry_point

        self.kernel(*self.args)
        self.entry = entry_point(self.kernel, self.args)


def sources(item, fields: Sequence[str]) -> list[np.ndarray]:
    """The arrays named by ``fields`` on ``item`` (its targets or parameters), as contiguous
    float64 vectors: views of its own arrays where they are so, else copies (then read at the
    call that made them only: :meth:`KernelCall.matches` fails on the next)."""
    out = []
    for name in fields:
        a = getattr(item, name)
        if a.dtype != np.float64 or not a.flags.c_contiguous:
            a = np.ascontiguousarray(a, dtype=np.float64)
        out.append(a)
    return out


def check_arity(kernel, what: str) -> None:
    """A kernel must take the signature's positional arguments (:data:`INPUTS`, then its two
    outputs); else one :class:`~wbc.exceptions.ModelError` line naming ``what`` and the
    signature, at class definition rather than deep in numba's typing at the first tick."""
    import inspect

    func = getattr(kernel, "py_func", kernel)
    try:
        params = inspect.signature(func).parameters.values()
    except (TypeError, ValueError):  # a builtin without a readable signature: numba decides
        return
    if any(p.kind is p.VAR_POSITIONAL for p in params):
        return
    n = sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params)
    if n != len(INPUTS) + 2:
        raise ModelError(
            f"{what} {getattr(func, '__name__', func)!r} takes {n} arguments; every kernel "
            f"takes {len(INPUTS) + 2}: ({', '.join(INPUTS)}, out1, out2) (wbc.compiled.signature)"
        )
