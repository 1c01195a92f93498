"""Input checks of the hot path in compiled code (a target rotation is checked on every
update: ~0.2 µs here against ~1.2 µs in Python), the checked copy of a target into the
task's own array in the same call, and reading buffers by address (a tick's inputs)."""

from __future__ import annotations

import math

import numpy as np
from numba import carray, njit, types
from numba.extending import intrinsic


@njit("float64(float64[:])", cache=True)
def squares(v: np.ndarray) -> float:
    """Σ vᵢ²: finite if and only if every entry is, unless a huge finite entry overflows it
    (one pass, no branch per entry: the quick finiteness check of the hot path)."""
    s = 0.0
    for i in range(v.shape[0]):
        s += v[i] * v[i]
    return s


@njit("boolean(float64[:])", cache=True)
def finite(v: np.ndarray) -> bool:
    """Every entry of v finite (:func:`squares`, then entry by entry only if it overflows)."""
    if math.isfinite(squares(v)):
        return True
    for i in range(v.shape[0]):
        if not math.isfinite(v[i]):
            return False
    return True


@njit("void(float64[:], float64[:])", cache=True)
def copy_vector(v: np.ndarray, out: np.ndarray) -> None:
    """v into ``out`` (at least as long), entry by entry."""
    for i in range(v.shape[0]):
        out[i] = v[i]


@njit("void(float64[:, :], float64[:, :])", cache=True)
def copy_matrix(R: np.ndarray, out: np.ndarray) -> None:
    """A 3x3 matrix R into ``out``, entry by entry."""
    for i in range(3):
        for j in range(3):
            out[i, j] = R[i, j]


@njit("float64(float64[:, :])", cache=True)
def rotation_defect(R: np.ndarray) -> float:
    """The largest deviation of RᵀR from I; +inf if an entry is not finite or det R < 0."""
    s = 0.0
    for i in range(3):
        for j in range(3):
            s += R[i, j]
    if not math.isfinite(s):
        return math.inf
    worst = 0.0
    for i in range(3):
        for j in range(i, 3):
            g = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j]
            worst = max(worst, abs(g - 1.0) if i == j else abs(g))
    det = (
        R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1])
        - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
        + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0])
    )
    return math.inf if det < 0.0 else worst


@njit("float64(float64[:, :], float64[:, :], float64)", cache=True)
def copy_rotation(R: np.ndarray, out: np.ndarray, tol: float) -> float:
    """:func:`rotation_defect` of R, and R copied into ``out`` if the defect is <= tol."""
    defect = rotation_defect(R)
    if defect <= tol:
        copy_matrix(R, out)
    return defect


@njit("boolean(float64[:], float64[:])", cache=True)
def copy_finite(v: np.ndarray, out: np.ndarray) -> bool:
    """v copied into ``out`` (same size) if every entry is finite; False (out untouched) if
    one is not."""
    if not finite(v):
        return False
    copy_vector(v, out)
    return True


@njit("float64(float64[:], float64[:, :], float64[:], float64[:, :], float64)", cache=True)
def copy_pose(
    p: np.ndarray, R: np.ndarray, out_p: np.ndarray, out_R: np.ndarray, tol: float
) -> float:
    """A pose checked as :func:`copy_finite` and :func:`copy_rotation` check its position and
    rotation, and copied into ``out_p`` and ``out_R`` if both pass (neither otherwise): R's
    :func:`rotation_defect`, +inf if p is not finite."""
    if not finite(p):
        return math.inf
    defect = rotation_defect(R)
    if defect <= tol:
        copy_vector(p, out_p)
        copy_matrix(R, out_R)
    return defect


@njit("float64(float64[:])", cache=True)
def quaternion_defect(q: np.ndarray) -> float:
    """|‖q[3:7]‖² − 1| (a free-flyer configuration's base quaternion); +inf if an entry of q
    is not finite."""
    if not finite(q):
        return math.inf
    return abs(q[3] * q[3] + q[4] * q[4] + q[5] * q[5] + q[6] * q[6] - 1.0)


@njit("boolean(float64[:], float64[:], float64[:])", cache=True)
def outside(q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray) -> bool:
    """True if a joint of the configuration q (7 base coordinates, then the joints) is outside
    [q_min, q_max] (a NaN joint is not: as numpy's comparisons; every tick asks this, ~0.2 µs
    here against ~3 µs in numpy)."""
    for i in range(q_min.shape[0]):
        if q[7 + i] < q_min[i] or q[7 + i] > q_max[i]:
            return True
    return False


def entry(check=rotation_defect):
    """A compiled check's entry point (any strided float64 arrays), skipping dispatch."""
    return check.overloads[check.signatures[0]].entry_point


@intrinsic
def _float64_pointer(typingctx, address):
    """The float64 pointer at an integer address."""
    signature = types.CPointer(types.float64)(address)

    def codegen(context, builder, sig, args):
        return builder.inttoptr(args[0], context.get_value_type(sig.return_type))

    return signature, codegen


@intrinsic
def address(typingctx, value):
    """The memory at an integer address, as a void pointer (for ``numba.carray(ptr, shape,
    dtype)``: a view of a buffer that its owner keeps alive)."""
    signature = types.voidptr(value)

    def codegen(context, builder, sig, args):
        return builder.inttoptr(args[0], context.get_value_type(sig.return_type))

    return signature, codegen


@njit("void(int64[:], int64[:], float64[:], float64[:], float64[:])", cache=True)
def gather(addresses: np.ndarray, sizes: np.ndarray, out: np.ndarray, q, q_out) -> None:
    """The float64 vectors at ``addresses`` (``sizes[k]`` entries each, contiguous) one after
    the other into ``out``, and q into ``q_out``: a compiled plan's inputs of a tick in one
    call (a plan's targets: views of the tasks' own arrays, which it keeps alive)."""
    if sizes.shape[0] != addresses.shape[0] or sizes.sum() > out.shape[0]:
        raise ValueError("gather: the sizes do not fit out")
    if q.shape[0] != q_out.shape[0]:
        raise ValueError("gather: q and q_out differ in size")
    o = 0
    for k in range(addresses.shape[0]):
        src = carray(_float64_pointer(addresses[k]), (sizes[k],))
        for i in range(sizes[k]):
            out[o + i] = src[i]
        o += sizes[k]
    for i in range(q.shape[0]):
        q_out[i] = q[i]
