"""The self-collision kernels' entry with the limit's buffers by address.

:func:`packed_rows` is what :class:`wbc.limits.SelfCollisionConstraint` calls once a tick:
:func:`~wbc.limits.collision_kernels.collision_rows` at a configuration, its ~30 buffers
passed as one array of addresses (:data:`PACKED`, :func:`pack`) — numba unboxes each array
argument (~50 ns): ~2.5 µs of a tick went to passing them one by one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import carray, njit

from ..compiled import boxes as _boxes
from ..compiled._cache import refresh
from ..compiled.boxes import fold_box
from ..compiled.checks import address
from ..compiled.dispatch import C_ROW
from .collision_kernels import CULL_TOL, collision_rows
from .joint_limits import position_box, speed_box

#: the buffers of :func:`packed_rows`, passed by address (numba unboxes ~50 ns per array
#: argument: ~2.5 µs of a tick went to passing :func:`collision_rows` its 32 arguments), in
#: order, as (name, dtype, ndim); every one C-contiguous
PACKED = (
    ("last_q", "float64", 1), ("last_joints", "float64", 1), ("bound", "float64", 1),
    ("L_start", "int64", 1), ("L_pair", "int32", 1), ("L_arm", "float64", 1),
    ("box_frame", "int64", 1), ("box_R", "float64", 3), ("box_p", "float64", 2),
    ("half", "float64", 2), ("radius", "float64", 1), ("pair_a", "int64", 1),
    ("pair_b", "int64", 1), ("support", "bool", 2), ("Rw", "float64", 3), ("cw", "float64", 2),
    ("placed", "bool", 1), ("out_k", "int64", 1),
    ("out_d", "float64", 1), ("out_p1", "float64", 2), ("out_p2", "float64", 2),
    ("out_n", "float64", 2), ("counts", "int64", 1), ("row_pair", "int64", 1),
    ("row_gap", "float64", 1), ("params", "float64", 1), ("closest", "float64", 1),
    ("last_axis", "int64", 1), ("work", "float64", 1), ("iwork", "int64", 1),
    ("box_min", "float64", 1), ("box_max", "float64", 1), ("box_step", "float64", 1),
    ("box", "float64", 2),
)  # fmt: skip


def _rows(*names: str) -> tuple[np.int64, ...]:
    """The rows of :data:`PACKED` named ``names``, as int64 scalars: a global numba reads as a
    plain int64, not a literal, so that each accessor (:func:`_f1`...) compiles once, not once
    per row it is called with (31 compilations in each compile worker before)."""
    order = [name for name, *_ in PACKED]
    return tuple(np.int64(order.index(name)) for name in names)


_LAST_Q, _LAST_JOINTS, _BOUND, _L_START, _L_PAIR, _L_ARM = _rows(
    "last_q", "last_joints", "bound", "L_start", "L_pair", "L_arm"
)
_BOX_FRAME, _BOX_R, _BOX_P, _HALF, _RADIUS = _rows("box_frame", "box_R", "box_p", "half", "radius")
_PAIR_A, _PAIR_B, _SUPPORT, _RW, _CW, _PLACED = _rows(
    "pair_a", "pair_b", "support", "Rw", "cw", "placed"
)
_OUT_K, _OUT_D, _OUT_P1, _OUT_P2, _OUT_N, _COUNTS = _rows(
    "out_k", "out_d", "out_p1", "out_p2", "out_n", "counts"
)
_ROW_PAIR, _ROW_GAP, _PARAMS, _CLOSEST, _LAST_AXIS, _WORK, _IWORK = _rows(
    "row_pair", "row_gap", "params", "closest", "last_axis", "work", "iwork"
)
_BOX_MIN, _BOX_MAX, _BOX_STEP, _BOX = _rows("box_min", "box_max", "box_step", "box")


def pack(buffers) -> tuple[np.ndarray, np.ndarray]:
    """The addresses (int64) and shapes (n x 3, int64) of the :data:`PACKED` buffers, each
    checked: C-contiguous, of its dtype and dimensions (the caller keeps them alive)."""
    shapes = np.zeros((len(PACKED), 3), dtype=np.int64)
    for k, ((name, dtype, ndim), a) in enumerate(zip(PACKED, buffers, strict=True)):
        if a.dtype != np.dtype(dtype) or a.ndim != ndim or not a.flags.c_contiguous:
            raise TypeError(f"self-collision buffer {name!r}: {a.dtype} {a.shape}")
        shapes[k, :ndim] = a.shape
    return np.array([a.ctypes.data for a in buffers], dtype=np.int64), shapes


@njit(cache=True)
def _f1(addresses, shapes, i):
    return carray(address(addresses[i]), (shapes[i, 0],), np.float64)


@njit(cache=True)
def _f2(addresses, shapes, i):
    return carray(address(addresses[i]), (shapes[i, 0], shapes[i, 1]), np.float64)


@njit(cache=True)
def _f3(addresses, shapes, i):
    return carray(address(addresses[i]), (shapes[i, 0], shapes[i, 1], shapes[i, 2]), np.float64)


@njit(cache=True)
def _i1(addresses, shapes, i):
    return carray(address(addresses[i]), (shapes[i, 0],), np.int64)


@njit(cache=True)
def _j1(addresses, shapes, i):
    return carray(address(addresses[i]), (shapes[i, 0],), np.int32)


@njit(cache=True)
def _b1(addresses, shapes, i):
    return carray(address(addresses[i]), (shapes[i, 0],), np.bool_)


@njit(cache=True)
def _b2(addresses, shapes, i):
    return carray(address(addresses[i]), (shapes[i, 0], shapes[i, 1]), np.bool_)


@njit(cache=True)
def joint_box(q, q_min, q_max, steps, lower, upper, speed) -> None:
    """The box of a stack whose box limits are the joint position limit then the joint
    velocity limit, the compiled tick's way: their boxes
    (:func:`~wbc.limits.joint_limits.position_box`, :func:`~wbc.limits.joint_limits.speed_box`:
    what their bound kernels write) folded by :func:`~wbc.compiled.boxes.fold_box`. ``speed``:
    2 x nv scratch."""
    position_box(q_min, q_max, q, lower, upper)
    speed_box(steps, speed[0], speed[1])
    fold_box(lower, upper, speed[0], speed[1])


@njit(cache=True)
def packed_rows(q, addresses, shapes, Rf, pf, Jw, G, h, r0) -> int:
    """:func:`collision_rows` at the configuration q (7 base coordinates, then the joints),
    with the limit's buffers by address (:data:`PACKED`; their owner keeps them alive:
    ``params`` = [margin, trigger, damping, unreachable, common frame]), the rows into
    ``G[r0:]``, ``h[r0:]`` (the limit's own buffers, or a compiled plan's: no copy); −1
    (nothing computed) if q equals ``last_q`` exactly, the configuration of the last call
    (NaN before the first call); −2 (nothing computed) if ``G`` or ``h`` has less room from
    ``r0`` than the most rows (17 a pair); else the number of rows, q into ``last_q`` and the
    smallest distance of the close pairs into ``closest[0]`` (+inf: none).

    With ``params[5]`` != 0 and the box's limits (``box_min``, ``box_max``, ``box_step``: the
    joints' position limits and steps) the rows that cannot bind in the tick's box
    (:func:`joint_box`, into ``box[0]``, ``box[1]``; ``box``: 6 x nv) are left out
    (:func:`~wbc.limits.collision_kernels.can_bind`); the rows of the last call are those of
    q only if they were made in the same box (``box[2]``, ``box[3]``: the last call's, NaN
    after a call without one)."""
    most = 17 * shapes[_PAIR_A, 0]  # (rows a pair at most: the witness and 8 + 8 corners)
    if r0 < 0 or G.shape[0] - r0 < most or h.shape[0] - r0 < most or G.shape[1] != Jw.shape[1]:
        return -2
    params = _f1(addresses, shapes, _PARAMS)
    box = _f2(addresses, shapes, _BOX)
    boxed = params[5] != 0.0 and shapes[_BOX_MIN, 0] > 0
    nv = Jw.shape[1]
    if boxed:
        joint_box(
            q, _f1(addresses, shapes, _BOX_MIN), _f1(addresses, shapes, _BOX_MAX),
            _f1(addresses, shapes, _BOX_STEP), box[0], box[1], box[4:6],
        )  # fmt: skip
    last_q = _f1(addresses, shapes, _LAST_Q)
    same = True
    for i in range(q.shape[0]):
        if q[i] != last_q[i]:
            same = False
            break
    if same and boxed:  # (the last rows made in this box)
        for i in range(nv):
            if box[0, i] != box[2, i] or box[1, i] != box[3, i]:
                same = False
                break
    elif same:  # (the last rows made without a box: box[2] NaN)
        same = box[2, 0] != box[2, 0]
    if same:
        return -1
    mid, wide = box[4, :0], box[5, :0]  # (no box: nothing left out)
    free = 0
    if boxed:  # (its centres and half widths + CULL_TOL, 0 on the free base columns)
        mid, wide = box[4], box[5]
        free = nv - shapes[_BOX_MIN, 0]
        for i in range(nv):
            if i < free:
                mid[i] = wide[i] = 0.0
            else:
                mid[i] = 0.5 * (box[0, i] + box[1, i])
                wide[i] = 0.5 * (box[1, i] - box[0, i]) + CULL_TOL
    a, s = addresses, shapes
    r = collision_rows(
        q[7:], _f1(a, s, _LAST_JOINTS), _f1(a, s, _BOUND), _i1(a, s, _L_START), _j1(a, s, _L_PAIR),
        _f1(a, s, _L_ARM), Rf, pf, _i1(a, s, _BOX_FRAME), _f3(a, s, _BOX_R), _f2(a, s, _BOX_P),
        _f2(a, s, _HALF), _f1(a, s, _RADIUS), _i1(a, s, _PAIR_A), _i1(a, s, _PAIR_B),
        _b2(a, s, _SUPPORT), Jw, params[0], params[1], params[2], params[3], _f3(a, s, _RW),
        _f2(a, s, _CW), _b1(a, s, _PLACED), _i1(a, s, _OUT_K), _f1(a, s, _OUT_D),
        _f2(a, s, _OUT_P1), _f2(a, s, _OUT_P2), _f2(a, s, _OUT_N), _i1(a, s, _COUNTS), G[r0:],
        h[r0:], _i1(a, s, _ROW_PAIR), _f1(a, s, _ROW_GAP), params[4] != 0.0, _i1(a, s, _LAST_AXIS),
        _f1(a, s, _WORK), _i1(a, s, _IWORK), mid, wide, free,
    )  # fmt: skip
    for i in range(q.shape[0]):
        last_q[i] = q[i]
    for i in range(nv):
        box[2, i] = box[0, i] if boxed else np.nan
        box[3, i] = box[1, i] if boxed else np.nan
    closest = _f1(addresses, shapes, _CLOSEST)
    out_d = _f1(addresses, shapes, _OUT_D)
    closest[0] = np.inf
    for i in range(_i1(addresses, shapes, _COUNTS)[2]):
        closest[0] = min(closest[0], out_d[i])
    return r


#: a plan's placement of the rows (:func:`placed_rows`, int64): their first row (−1: not
#: made in the tick), their count at the last call, 1 if that call made them (0: the rows of
#: the same configuration, where they were), their level, the number of levels L, then each
#: level's first row and the end without them (L + 1), the number n of the kernel constraints
#: after them and each one's row of ``cspec`` and first row without them (2 n)
P_ROW, P_COUNT, P_MADE, P_LEVEL, P_LEVELS, P_FIRST = range(6)


@njit(cache=True)
def placed_rows(q, addresses, shapes, Rf, pf, Jw, G, h, place, g_rows, cspec) -> int:
    """:func:`packed_rows` inside a compiled tick: the rows at q into ``G``, ``h`` from the
    row ``place[P_ROW]`` (nothing if it is −1), then every row after them moved by their
    count — each level's bounds in ``g_rows`` and the first row (``cspec[:, C_ROW]``) of
    each kernel constraint after them, from their places without these rows (:data:`P_ROW`...:
    the plan's layout). Returns the count, or −2 (no room: nothing moved).
    The rows of the last call (its −1) are where that call put them: the caller forgets
    them (``last_q``) when they are not at ``place[P_ROW]`` of these buffers."""
    r0 = place[P_ROW]
    if r0 < 0:
        return 0
    m = packed_rows(q, addresses, shapes, Rf, pf, Jw, G, h, r0)
    if m == -1:
        m = place[P_COUNT]
        place[P_MADE] = 0
    elif m < 0:
        place[P_COUNT] = m
        return m
    else:
        place[P_MADE] = 1
    place[P_COUNT] = m
    level, n = place[P_LEVEL], place[P_LEVELS]
    for k in range(n + 1):
        g_rows[k] = place[P_FIRST + k] + (m if k > level else 0)
    o = P_FIRST + n + 1
    for i in range(place[o]):
        cspec[place[o + 1 + 2 * i], C_ROW] = place[o + 2 + 2 * i] + m
    return m


#: the files :func:`placed_rows` calls into (a compiled tick that calls it digests them)
PLACED_SOURCES = tuple(
    str(Path(__file__).with_name(f))
    for f in ("collision_packed.py", "collision_kernels.py", "joint_limits.py")
)
#: the kernel the package's compiled tick calls first, and the files it calls
#: (:func:`wbc.compiled.dispatch.ticks`' ``placer``): the self-collision rows made in the tick
ROW_PLACER = (placed_rows, *PLACED_SOURCES)


# numba caches these on this file alone: flush them when the kernels they call change (the
# rows' kernels, the joint limits' boxes and their fold; before this, an edit of
# collision_kernels.py alone left packed_rows running the old rows)
refresh(
    [joint_box, packed_rows, placed_rows],
    [
        Path(__file__).with_name("collision_kernels.py"),
        Path(__file__).with_name("joint_limits.py"),
        Path(_boxes.__file__),
    ],
)
