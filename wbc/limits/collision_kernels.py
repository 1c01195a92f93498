"""Box–box distances and the self-collision rows, compiled (numba).

The hot path of :class:`wbc.limits.SelfCollisionConstraint`, one call per tick:

* :func:`close_pairs` — the broad phase and the exact distances. Each pair keeps a lower
  bound on its distance, lowered at every call by Σ_i L_ki |Δq_i| (the joints' lever arms,
  :func:`wbc.limits.collision_boxes.lipschitz_bounds`); a pair whose bound stays above the
  query costs that product. The others get the bound of their boxes' bounding spheres
  (|c₁ − c₂| − r₁ − r₂), then the gap along the axis that separated the pair last (one axis of
  :func:`axis_gap`: turns away most far pairs), then the separating-axis bound (the largest
  gap between the two boxes' projections on their 15 candidate axes: a lower bound on the
  distance, exact when a face or an edge pair is closest), and only a pair still below the
  query its exact distance: :func:`box_distance`.
* :func:`box_distance` / :func:`exact_distance` — the signed distance of two boxes, exact to
  rounding: the separating-axis gap where the witness points along that axis lie on both
  boxes (a face and what faces it; the gap is a lower bound, two points that far apart an
  upper one), else GJK (support mapping, the closest point of each simplex by its
  sub-simplices' affine minimisers: exact for polytopes); for boxes that overlap, the
  penetration depth by the separating-axis theorem (exact for boxes: the minimum
  translation is along one of the 15 axes) with the contact features' points as witnesses
  (:func:`axis_witness`).
* :func:`plane_rows` — the velocity-damper rows of the close pairs: every box corner nearer
  than the trigger to the separating planes, with its projection brought onto the other box,
  and the witness pair where it is not a corner's row nor a tie (:func:`witness_tie`; see
  :func:`wbc.limits.collision_reference.separating_plane_rows`, the numpy form the tests compare),
  each row −nᵀ(J_b − J_a) Δq <= h(gap), nᵀJ_p = nᵀJ_v + (p × n)ᵀJ_ω over the point's
  joint support.
* :func:`collision_rows` — both in one call (what a tick calls, through
  :func:`wbc.limits.collision_packed.packed_rows`: its buffers by address).

Checked against coal (hpp-fcl) on random boxes and configurations:
``tests/test_limits_collision_kernels.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: GJK stops when its upper and lower bounds on the distance are this close (m)
GJK_TOL = 1e-12
#: GJK iterations at most (two boxes converge in a handful)
GJK_ITERATIONS = 64
#: below this |v| (m) GJK reports contact: the separating-axis depth takes over
CONTACT = 1e-10
#: edge pairs whose |u × w| is below this have no separating axis of their own (nearly
#: parallel: the face axes cover them; a lower bound either way, exact where its witnesses
#: check out, and GJK otherwise)
EDGE_PARALLEL = 1e-6
#: the damper's allowance h(d) never exceeds this fraction of the gap to the margin (d − m):
#: a tick whose rows hold to first order ends outside the margin, whatever d below the
#: trigger (:func:`damper_h`, :func:`wbc.limits.self_collision.damper_bound`)
MAX_CLOSURE = 0.9
#: a box axis within this (rad) of the separating plane is parallel to it; two boxes whose
#: features nearest the plane share such a direction (a face and a face or an edge, two
#: parallel edges) have no single witness (any point of their overlap): their rows are the
#: corners' (:func:`plane_rows`, :func:`witness_tie`)
PARALLEL = 1e-6


@njit(cache=True)
def place_box(g, Rf, pf, box_frame, box_R, box_p, Rw, cw) -> None:
    """World axes (Rw[g]: columns) and centre cw[g] of box g, from its parent frame's world
    placement (Rf, pf: every frame's) and its placement in that frame."""
    f = box_frame[g]
    for i in range(3):
        s = pf[f, i]
        for j in range(3):
            s += Rf[f, i, j] * box_p[g, j]
            acc = 0.0
            for m in range(3):
                acc += Rf[f, i, m] * box_R[g, m, j]
            Rw[g, i, j] = acc
        cw[g, i] = s


@njit(cache=True)
def _support(R, c, h, d0, d1, d2, out) -> None:
    """out = the corner of the box (axes R's columns, centre c, half sides h) farthest along d."""
    out[0], out[1], out[2] = c[0], c[1], c[2]
    for i in range(3):
        s = R[0, i] * d0 + R[1, i] * d1 + R[2, i] * d2
        k = h[i] if s >= 0.0 else -h[i]
        out[0] += k * R[0, i]
        out[1] += k * R[1, i]
        out[2] += k * R[2, i]


@njit(cache=True)
def _closest_on_simplex(W, n, lam, best_set, M, r, mu, idx) -> float:
    """The point of the convex hull of W[:n] (n <= 4) closest to the origin, where W[:n-1]
    held the closest point of their own hull: the smallest of the affine minimisers of the
    sub-simplices with the newest point W[n-1] that lie inside them (all barycentric
    coordinates > 0; that point alone always does). Writes the coordinates (``lam``, 0 outside the
    chosen subset) and the subset's bit mask (``best_set[0]``); returns |v|². ``M`` (3 x 3),
    ``r``, ``mu`` (3) and ``idx`` (4 ints): scratch."""
    best = np.inf
    newest = 1 << (n - 1)
    for mask in range(1, 1 << n):
        if not mask & newest:  # (the last simplex's closest point was the best without it)
            continue
        k = 0
        for i in range(n):
            if mask & (1 << i):
                idx[k] = i
                k += 1
        y0 = idx[0]
        if k == 1:
            vv = W[y0, 0] ** 2 + W[y0, 1] ** 2 + W[y0, 2] ** 2
            if vv < best:
                best = vv
                lam[:] = 0.0
                lam[y0] = 1.0
                best_set[0] = mask
            continue
        m = k - 1  # E = [y_i − y0], (EᵀE) μ = −Eᵀ y0
        scale = 0.0
        for a in range(m):
            ia = idx[a + 1]
            r[a] = 0.0
            for c in range(3):
                ea = W[ia, c] - W[y0, c]
                r[a] -= ea * W[y0, c]
            for b in range(m):
                ib = idx[b + 1]
                acc = 0.0
                for c in range(3):
                    acc += (W[ia, c] - W[y0, c]) * (W[ib, c] - W[y0, c])
                M[a, b] = acc
            scale = max(scale, M[a, a])
        if not _solve_small(M, r, mu, m, scale):
            continue  # affinely dependent: its faces cover it
        l0 = 1.0
        ok = True
        for a in range(m):
            l0 -= mu[a]
            if mu[a] <= 0.0:
                ok = False
        if not ok or l0 <= 0.0:
            continue
        v0 = v1 = v2 = 0.0
        for c in range(3):
            s = l0 * W[y0, c]
            for a in range(m):
                s += mu[a] * W[idx[a + 1], c]
            if c == 0:
                v0 = s
            elif c == 1:
                v1 = s
            else:
                v2 = s
        vv = v0 * v0 + v1 * v1 + v2 * v2
        if vv < best:
            best = vv
            lam[:] = 0.0
            lam[y0] = l0
            for a in range(m):
                lam[idx[a + 1]] = mu[a]
            best_set[0] = mask
    return best


@njit(cache=True)
def _solve_small(M, r, x, m, scale) -> bool:
    """x = M⁻¹ r for an m x m symmetric M (m <= 3), by Cramer's rule; False if M is singular
    relative to ``scale`` (its largest diagonal entry)."""
    if m == 1:
        if M[0, 0] <= 1e-14 * scale or M[0, 0] == 0.0:
            return False
        x[0] = r[0] / M[0, 0]
        return True
    if m == 2:
        det = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
        if abs(det) <= 1e-13 * scale * scale or det == 0.0:
            return False
        x[0] = (r[0] * M[1, 1] - M[0, 1] * r[1]) / det
        x[1] = (M[0, 0] * r[1] - r[0] * M[1, 0]) / det
        return True
    c00 = M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]
    c01 = M[1, 2] * M[2, 0] - M[1, 0] * M[2, 2]
    c02 = M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]
    det = M[0, 0] * c00 + M[0, 1] * c01 + M[0, 2] * c02
    if abs(det) <= 1e-12 * scale * scale * scale or det == 0.0:
        return False
    c10 = M[0, 2] * M[2, 1] - M[0, 1] * M[2, 2]
    c11 = M[0, 0] * M[2, 2] - M[0, 2] * M[2, 0]
    c12 = M[0, 1] * M[2, 0] - M[0, 0] * M[2, 1]
    c20 = M[0, 1] * M[1, 2] - M[0, 2] * M[1, 1]
    c21 = M[0, 2] * M[1, 0] - M[0, 0] * M[1, 2]
    c22 = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    x[0] = (c00 * r[0] + c10 * r[1] + c20 * r[2]) / det
    x[1] = (c01 * r[0] + c11 * r[1] + c21 * r[2]) / det
    x[2] = (c02 * r[0] + c12 * r[1] + c22 * r[2]) / det
    return True


@njit(cache=True, inline="always")
def axis_gap(R1, c1, h1, R2, c2, h2, k):
    """The gap between the two boxes' projections on their candidate axis number k (see
    :func:`separating_axis`; a lower bound on their distance), its unit axis (a0, a1, a2) and
    the centres' offset along it: (gap, a0, a1, a2, dist); gap −inf for an edge pair with
    |u × w| < :data:`EDGE_PARALLEL` (no axis of its own)."""
    if k < 3:
        a0, a1, a2 = R1[0, k], R1[1, k], R1[2, k]
    elif k < 6:
        a0, a1, a2 = R2[0, k - 3], R2[1, k - 3], R2[2, k - 3]
    else:
        i, j = (k - 6) // 3, (k - 6) % 3
        u0, u1, u2 = R1[0, i], R1[1, i], R1[2, i]
        w0, w1, w2 = R2[0, j], R2[1, j], R2[2, j]
        a0, a1, a2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
        norm = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        if norm < EDGE_PARALLEL:  # (nearly) parallel edges: the face axes cover them
            return -np.inf, a0, a1, a2, 0.0
        a0, a1, a2 = a0 / norm, a1 / norm, a2 / norm
    dist = a0 * (c2[0] - c1[0]) + a1 * (c2[1] - c1[1]) + a2 * (c2[2] - c1[2])
    r1 = 0.0
    r2 = 0.0
    for m in range(3):
        r1 += h1[m] * abs(R1[0, m] * a0 + R1[1, m] * a1 + R1[2, m] * a2)
        r2 += h2[m] * abs(R2[0, m] * a0 + R2[1, m] * a1 + R2[2, m] * a2)
    return abs(dist) - r1 - r2, a0, a1, a2, dist


@njit(cache=True)
def separating_axis(R1, c1, h1, R2, c2, h2, axis) -> float:
    """The largest gap between the projections of the two boxes on their 15 candidate axes
    (face normals of each, cross products of their edges: :func:`axis_gap`), ``axis[:3]``
    its unit axis (from box 1 towards box 2) and ``axis[3]`` its number (0–2: box 1's faces,
    3–5: box 2's, then the edge pairs 6 + 3 i + j: box 1's axis i × box 2's axis j).
    Positive: the boxes are that far apart at least (a lower bound on their distance);
    negative: they overlap, and −gap is their penetration depth."""
    best = -np.inf
    for k in range(15):
        gap, a0, a1, a2, dist = axis_gap(R1, c1, h1, R2, c2, h2, k)
        if gap > best:
            best = gap
            s = 1.0 if dist >= 0.0 else -1.0
            axis[0], axis[1], axis[2] = s * a0, s * a1, s * a2
            axis[3] = k
    return best


@njit(cache=True)
def box_distance(R1, c1, h1, R2, c2, h2, p1, p2, normal) -> float:
    """Signed distance between two boxes (axes R's columns, centres c, half sides h), the
    witness points p1 (box 1), p2 (box 2) and the unit normal from box 1 towards box 2:
    nᵀ(p2 − p1) = d. Separated: GJK (exact to rounding, :data:`GJK_TOL`); in contact or
    overlapping: minus the separating-axis penetration depth."""
    return _box_distance(
        R1, c1, h1, R2, c2, h2, p1, p2, normal, np.empty(SCRATCH), np.zeros(6, np.int64)
    )


#: floats of scratch that :func:`_box_distance` uses
SCRATCH = 68
#: the scratch of :func:`close_pairs` (its separating axis, then GJK's)
CLOSE_WORK = 4 + SCRATCH


@njit(cache=True)
def _box_distance(R1, c1, h1, R2, c2, h2, p1, p2, normal, F, Iw) -> float:
    """:func:`box_distance` with its scratch: ``F`` (:data:`SCRATCH` floats), ``Iw`` (6 ints)."""
    axis = F[64:68]
    gap = separating_axis(R1, c1, h1, R2, c2, h2, axis)
    return exact_distance(R1, c1, h1, R2, c2, h2, axis, gap, p1, p2, normal, F, Iw)


@njit(cache=True)
def exact_distance(R1, c1, h1, R2, c2, h2, axis, gap, p1, p2, normal, F, Iw) -> float:
    """The signed distance from the separating axis (``axis``, ``gap``: :func:`separating_axis`):
    overlapping boxes (gap <= 0), minus the depth with :func:`axis_witness`'s points; apart,
    the gap itself where those points lie on the boxes (the gap is a lower bound on the
    distance, and two points that far apart an upper one: the feet side by side, an arm
    along the torso — a face and what faces it), else GJK (``Iw[5]`` += 1)."""
    axis_witness(R1, c1, h1, R2, c2, h2, axis, gap, p1, p2, normal)
    if gap <= 0.0 or (on_box(p1, R1, c1, h1) and on_box(p2, R2, c2, h2)):
        return gap
    Iw[5] += 1
    return _gjk(R1, c1, h1, R2, c2, h2, p1, p2, normal, F, Iw)


@njit(cache=True)
def _gjk(R1, c1, h1, R2, c2, h2, p1, p2, normal, F, Iw) -> float:
    """GJK on two separated boxes (see :func:`box_distance`); ``F``, ``Iw``: scratch."""
    W = F[0:12].reshape((4, 3))
    A = F[12:24].reshape((4, 3))
    B = F[24:36].reshape((4, 3))
    lam = F[36:40]
    a = F[40:43]
    b = F[43:46]
    v = F[46:49]
    M = F[49:58].reshape((3, 3))
    r = F[58:61]
    mu = F[61:64]
    axis = F[64:68]
    best_set = Iw[0:1]
    idx = Iw[1:5]
    # start from the support points along the centres' difference
    v[0], v[1], v[2] = c1[0] - c2[0], c1[1] - c2[1], c1[2] - c2[2]
    _support(R1, c1, h1, -v[0], -v[1], -v[2], a)
    _support(R2, c2, h2, v[0], v[1], v[2], b)
    for c in range(3):
        A[0, c], B[0, c] = a[c], b[c]
        W[0, c] = a[c] - b[c]
        v[c] = W[0, c]
    lam[0] = 1.0
    n = 1
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    contact = False
    for _ in range(GJK_ITERATIONS):
        if vv <= CONTACT * CONTACT:
            contact = True
            break
        _support(R1, c1, h1, -v[0], -v[1], -v[2], a)
        _support(R2, c2, h2, v[0], v[1], v[2], b)
        w0, w1, w2 = a[0] - b[0], a[1] - b[1], a[2] - b[2]
        vw = v[0] * w0 + v[1] * w1 + v[2] * w2
        if vv - vw <= GJK_TOL * math.sqrt(vv):  # |v| − (v·w)/|v| <= tol: converged
            break
        duplicate = False
        for i in range(n):
            if W[i, 0] == w0 and W[i, 1] == w1 and W[i, 2] == w2:
                duplicate = True
        if duplicate or n == 4:
            break
        W[n, 0], W[n, 1], W[n, 2] = w0, w1, w2
        for c in range(3):
            A[n, c], B[n, c] = a[c], b[c]
        n += 1
        new = _closest_on_simplex(W, n, lam, best_set, M, r, mu, idx)
        if new >= vv:  # no progress (rounding): keep the last simplex
            n -= 1
            break
        # keep the subset that holds the closest point
        k = 0
        mask = best_set[0]
        for i in range(n):
            if mask & (1 << i):
                for c in range(3):
                    W[k, c], A[k, c], B[k, c] = W[i, c], A[i, c], B[i, c]
                lam[k] = lam[i]
                k += 1
        n = k
        for c in range(3):
            s = 0.0
            for i in range(n):
                s += lam[i] * W[i, c]
            v[c] = s
        vv = new
        if n == 4:  # the origin is inside the tetrahedron
            contact = True
            break
    if not contact:
        for c in range(3):
            s1 = 0.0
            s2 = 0.0
            for i in range(n):
                s1 += lam[i] * A[i, c]
                s2 += lam[i] * B[i, c]
            p1[c], p2[c] = s1, s2
        d = math.sqrt(vv)
        for c in range(3):
            normal[c] = (p2[c] - p1[c]) / d
        return d
    gap = separating_axis(R1, c1, h1, R2, c2, h2, axis)
    axis_witness(R1, c1, h1, R2, c2, h2, axis, gap, p1, p2, normal)
    return gap


@njit(cache=True)
def axis_witness(R1, c1, h1, R2, c2, h2, axis, gap, p1, p2, normal) -> None:
    """Witness points p1, p2 with p2 − p1 = gap · n along the separating axis (``axis`` and
    ``gap`` of :func:`separating_axis`; n = axis[:3]): the contact features' points along the
    axis, so that nᵀ(J_p2 − J_p1) is the gap's derivative (the axis turns with the boxes).
    Box 1's face: box 2's corner farthest along −n and its projection on that face; box 2's
    face: the converse; an edge of each: the closest points of the two edges' lines."""
    normal[0], normal[1], normal[2] = axis[0], axis[1], axis[2]
    k = int(axis[3])
    _support(R1, c1, h1, normal[0], normal[1], normal[2], p1)
    _support(R2, c2, h2, -normal[0], -normal[1], -normal[2], p2)
    if k < 3:
        for c in range(3):
            p1[c] = p2[c] - gap * normal[c]
    elif k < 6:
        for c in range(3):
            p2[c] = p1[c] + gap * normal[c]
    else:
        i, j = (k - 6) // 3, (k - 6) % 3
        u0, u1, u2 = R1[0, i], R1[1, i], R1[2, i]
        w0, w1, w2 = R2[0, j], R2[1, j], R2[2, j]
        r0, r1, r2 = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
        b = u0 * w0 + u1 * w1 + u2 * w2
        dd = u0 * r0 + u1 * r1 + u2 * r2
        e = w0 * r0 + w1 * r1 + w2 * r2
        x0, x1, x2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
        den = x0 * x0 + x1 * x1 + x2 * x2  # = 1 − b², >= EDGE_PARALLEL² (an edge axis)
        s = (b * e - dd) / den
        t = (e - b * dd) / den
        p1[0], p1[1], p1[2] = p1[0] + s * u0, p1[1] + s * u1, p1[2] + s * u2
        p2[0], p2[1], p2[2] = p2[0] + t * w0, p2[1] + t * w1, p2[2] + t * w2


@njit(cache=True)
def on_box(p, R, c, h) -> bool:
    """True if the point p lies in the box (to rounding: 1e-12 m)."""
    for i in range(3):
        x = R[0, i] * (p[0] - c[0]) + R[1, i] * (p[1] - c[1]) + R[2, i] * (p[2] - c[2])
        if abs(x) > h[i] + 1e-12:
            return False
    return True


def sparse_arms(L: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lever arms L (pairs x joints, :func:`~wbc.limits.collision_boxes.lipschitz_bounds`)
    by joint without their zeros, as :func:`close_pairs` reads them: each joint's first entry
    (n_joints + 1, int64), each entry's pair (int32) and arm (float64), pairs ascending within
    a joint. A bound lowered by these entries is the one the whole of L gives, bit for bit
    (a zero arm's term subtracts 0)."""
    by_joint = np.ascontiguousarray(L.T)
    joint, pair = np.nonzero(by_joint)
    start = np.zeros(by_joint.shape[0] + 1, np.int64)
    np.cumsum(np.bincount(joint, minlength=by_joint.shape[0]), out=start[1:])
    return start, pair.astype(np.int32), np.ascontiguousarray(by_joint[joint, pair])


@njit(cache=True)
def close_pairs(
    joints, last_joints, bound, L_start, L_pair, L_arm, Rf, pf, box_frame, box_R, box_p, half,
    radius, pair_a, pair_b, query, Rw, cw, placed, out_k, out_d, out_p1, out_p2, out_n, counts,
    last_axis, work, iwork,
) -> int:  # fmt: skip
    """The pairs closer than ``query`` (m), with their distances, witness points and normals
    (into ``out_*``, in pair order); returns how many. ``bound`` (per pair, a lower bound on its
    distance at ``last_joints``) is moved to ``joints`` (the lever arms L, joints x pairs, by
    joint without their zeros: :func:`sparse_arms`) and tightened by what this call learnt;
    the boxes it placed (``placed``) have their world axes Rw and centres cw; ``counts[0]``
    counts the exact distances computed, ``counts[1]`` the separating-axis bounds (15 axes;
    ``last_axis``: each pair's axis of its last one, -1 none, tried alone first),
    ``counts[3]`` the exact distances that took GJK. ``work``, ``iwork``: scratch (float64,
    int64; at least :data:`CLOSE_WORK` and 6 long)."""
    nj = joints.shape[0]
    moved = False
    for i in range(nj):
        if joints[i] != last_joints[i]:
            moved = True
            break
    K = pair_a.shape[0]
    if moved:  # (joint by joint: K independent sums, not one chain per pair; a zero lever
        # arm's term, which leaves the bound as it is, skipped: a third of L is read)
        for i in range(nj):
            step = abs(joints[i] - last_joints[i])
            if step != 0.0:
                for e in range(L_start[i], L_start[i + 1]):
                    bound[L_pair[e]] -= L_arm[e] * step
            last_joints[i] = joints[i]
    placed[:] = False
    axis = work[:4]
    F = work[4:CLOSE_WORK]
    Iw = iwork[:6]
    Iw[:] = 0
    count = 0
    for k in range(K):
        if bound[k] >= query:
            continue
        ga, gb = pair_a[k], pair_b[k]
        for g in (ga, gb):
            if not placed[g]:
                placed[g] = True
                place_box(g, Rf, pf, box_frame, box_R, box_p, Rw, cw)
        dc = 0.0
        for i in range(3):
            dc += (cw[ga, i] - cw[gb, i]) ** 2
        sphere = math.sqrt(dc) - radius[ga] - radius[gb]
        if sphere >= query:
            bound[k] = sphere
            continue
        if last_axis[k] >= 0:  # (the axis that separated them last: one axis's gap first)
            gap = axis_gap(Rw[ga], cw[ga], half[ga], Rw[gb], cw[gb], half[gb], last_axis[k])[0]
            if gap >= query:
                bound[k] = max(sphere, gap)
                continue
        counts[1] += 1
        sat = separating_axis(Rw[ga], cw[ga], half[ga], Rw[gb], cw[gb], half[gb], axis)
        last_axis[k] = int(axis[3])
        if sat >= query:
            bound[k] = max(sphere, sat)
            continue
        counts[0] += 1
        d = exact_distance(
            Rw[ga], cw[ga], half[ga], Rw[gb], cw[gb], half[gb], axis, sat,
            out_p1[count], out_p2[count], out_n[count], F, Iw,
        )  # fmt: skip
        bound[k] = d
        if d < query:
            out_k[count] = k
            out_d[count] = d
            count += 1
    counts[3] += Iw[5]
    return count


@njit(cache=True)
def damper_h(d, margin, trigger, damping) -> float:
    """h(d) of :func:`wbc.limits.self_collision.damper_bound`, for one gap."""
    if d >= trigger:
        return np.inf
    gap = d - margin
    if gap > 0.0:
        return min(damping * gap * (trigger - margin) / (trigger - d), MAX_CLOSURE * gap)
    return -min(damping * (-gap), damping * margin)


@njit(cache=True)
def _body_terms(Jw, support, other, common, n, A) -> None:
    """A body's terms of nᵀJ_p (p a point it carries), dense over the velocity coordinates:
    A[0] = nᵀJ_v, A[1:4] = J_ω on the columns of ``support`` (the joints carrying it; with
    ``common``, not those carrying the ``other`` body too: n fixed in their common frame), 0
    elsewhere (nᵀJ_v summed in :func:`_point_row`'s order)."""
    for k in range(Jw.shape[1]):
        if support[k] and not (common and other[k]):
            A[0, k] = n[0] * Jw[0, k] + n[1] * Jw[1, k] + n[2] * Jw[2, k]
            A[1, k] = Jw[3, k]
            A[2, k] = Jw[4, k]
            A[3, k] = Jw[5, k]
        else:
            A[0, k] = A[1, k] = A[2, k] = A[3, k] = 0.0


@njit(cache=True, inline="always")
def _write_row(A, i, pa, pb, n, G, r) -> None:
    """G[r] = −nᵀ(J_b − J_a), the row of close pair i for the points pa (on body a) and pb
    (body b), with nᵀJ_p = nᵀJ_v + (p × n)ᵀJ_ω (v_p = v_O + ω × p) from each body's dense
    terms ``A[i, side]`` (:func:`_body_terms`: 0 off its columns, so one pass over every
    column, vectorised, gives the row; a column carrying neither body is 0)."""
    a0 = pa[1] * n[2] - pa[2] * n[1]
    a1 = pa[2] * n[0] - pa[0] * n[2]
    a2 = pa[0] * n[1] - pa[1] * n[0]
    b0 = pb[1] * n[2] - pb[2] * n[1]
    b1 = pb[2] * n[0] - pb[0] * n[2]
    b2 = pb[0] * n[1] - pb[1] * n[0]
    Aa, Ab = A[i, 0], A[i, 1]
    g = G[r]
    for k in range(g.shape[0]):
        tb = Ab[0, k] + b0 * Ab[1, k] + b1 * Ab[2, k] + b2 * Ab[3, k]
        ta = Aa[0, k] + a0 * Aa[1, k] + a1 * Aa[2, k] + a2 * Aa[3, k]
        g[k] = (0.0 - tb) + ta


@njit(cache=True)
def _clamp_to_box(x, R, c, hh, out) -> None:
    """out = the point of the box (axes R's columns, centre c, half sides hh) nearest to x."""
    for m in range(3):
        out[m] = c[m]
    for i in range(3):
        s = R[0, i] * (x[0] - c[0]) + R[1, i] * (x[1] - c[1]) + R[2, i] * (x[2] - c[2])
        s = min(max(s, -hh[i]), hh[i])
        for m in range(3):
            out[m] += s * R[m, i]


@njit(cache=True)
def _along_plane(R, n):
    """How many of the box's axes (R's columns) are parallel to the plane of normal n (|aᵀn|
    <= :data:`PARALLEL`: 0, its feature nearest the plane is a corner, 1 an edge, 2 a face),
    and the number of the first (-1: none)."""
    k = 0
    first = -1
    for i in range(3):
        if abs(R[0, i] * n[0] + R[1, i] * n[1] + R[2, i] * n[2]) <= PARALLEL:
            if k == 0:
                first = i
            k += 1
    return k, first


@njit(cache=True)
def witness_tie(Ra, Rb, n) -> bool:
    """True if the two boxes' features nearest the separating plane (normal n) share a
    direction along it (to :data:`PARALLEL`): a face and a face or an edge, or two parallel
    edges — any point of their overlap is a witness."""
    ka, ia = _along_plane(Ra, n)
    kb, ib = _along_plane(Rb, n)
    if ka == 0 or kb == 0:
        return False
    if ka >= 2 or kb >= 2:
        return True
    u0, u1, u2 = Ra[0, ia], Ra[1, ia], Ra[2, ia]
    w0, w1, w2 = Rb[0, ib], Rb[1, ib], Rb[2, ib]
    x0, x1, x2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
    return math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) <= PARALLEL


@njit(cache=True)
def _is_corner(p, R, c, hh) -> bool:
    """True if p is a corner of the box (to 1e-9 m: the witness a corner's own row)."""
    dd = 0.0
    for i in range(3):
        s = R[0, i] * (p[0] - c[0]) + R[1, i] * (p[1] - c[1]) + R[2, i] * (p[2] - c[2])
        dd += (abs(s) - hh[i]) ** 2
    return dd <= 1e-18


def work_sizes(pairs: int, nv: int) -> tuple[int, int]:
    """The lengths of the float64 and int64 scratch that :func:`collision_rows` needs for
    ``pairs`` pairs and ``nv`` velocity coordinates (:func:`close_pairs`', then
    :func:`plane_rows`' for every pair close: 17 candidate rows a pair at most)."""
    most = 17 * pairs
    return CLOSE_WORK + pairs * 8 * nv + 8 * most + 6, 6 + most + pairs


#: a row is left out in the box only if its largest value there is below its bound by this
#: (m) times 1 + Σ|G_ik| (:func:`can_bind`): the solvers' Δq lie in the box to their
#: tolerance (:data:`wbc.types.CONSTRAINT_TOL`, 1e-9), so such a row is never violated by more
#: than that tolerance, the test that makes a row join (or block) a working set
CULL_TOL = 1e-8


@njit(cache=True, fastmath=True)
def box_most(g, mid, wide) -> float:
    """Σ_k g_k mid_k + |g_k| wide_k (``mid``: the box's centres, ``wide``: its half widths plus
    :data:`CULL_TOL`): the row's largest value over the box plus CULL_TOL Σ|g_k|
    (:func:`can_bind`). Summed in any order (fastmath: the reduction vectorised; the test's
    margin CULL_TOL covers the rounding)."""
    most = 0.0
    for k in range(g.shape[0]):
        most += g[k] * mid[k] + abs(g[k]) * wide[k]
    return most


@njit(cache=True, inline="always")
def can_bind(g, most, bound, free) -> bool:
    """False if no Δq of the box [lower, upper] violates the row g Δq <= bound:

        max_{lower <= Δq <= upper} g Δq + CULL_TOL (1 + Σ_k |g_k|) <= bound,

    the largest value Σ_k g_k mid_k + |g_k| rad_k (mid, rad: the box's centres and half
    widths) summed by :func:`box_most` into ``most`` with CULL_TOL Σ|g_k|; the first
    ``free`` columns (unbounded: the base's) must be 0 in g (else, and where ``most`` is not a
    number, the row is kept). Such a row never joins a working set (:data:`CULL_TOL`)."""
    for k in range(free):
        if g[k] != 0.0:
            return True
    return not most + CULL_TOL <= bound


@njit(cache=True)
def plane_rows(
    count, out_k, out_d, out_p1, out_p2, out_n, pair_a, pair_b, Rw, cw, half, support, Jw,
    margin, trigger, damping, unreachable, G, h, row_pair, row_gap, common, work, iwork,
    mid, wide, free, counts,
) -> int:  # fmt: skip
    """The damper rows of the ``count`` close pairs of :func:`close_pairs` into G, h (each
    row's pair, an index into the close pairs, and gap into ``row_pair``, ``row_gap``);
    returns the number of rows. The witness rows first (only where the witness stands for
    itself, see :func:`wbc.limits.collision_reference.separating_plane_rows`), then the
    corners of each pair's second box near the plane through p1, each with its projection
    on that plane brought onto the first box, then those of its first box near the plane
    through p2 likewise (the order of the numpy form). Each pair's bodies' terms are
    computed once (:func:`_body_terms`). With a box (``mid``, ``wide``: nv long, the centres
    and the half widths plus :data:`CULL_TOL` of the tick's bounds on Δq, 0 on the ``free``
    unbounded first columns; empty: none), the rows that cannot bind in it
    (:func:`can_bind`) are left out (``counts[4]`` += their number). ``work``, ``iwork``:
    scratch (float64, int64; :func:`plane_work`'s sizes at least: nothing allocated)."""
    nv = Jw.shape[1]
    most = 17 * count
    o = count * 8 * nv
    A = work[:o].reshape((count, 2, 4, nv))
    P = work[o : o + 6 * most].reshape((most, 2, 3))
    o += 6 * most
    gaps = work[o : o + most]
    H = work[o + most : o + 2 * most]
    corner = work[o + 2 * most : o + 2 * most + 3]
    foot = work[o + 2 * most + 3 : o + 2 * most + 6]
    which = iwork[:most]
    corner2 = iwork[most : most + count]  # (1: the witness on box 2 is one of its corners)
    for i in range(count):
        k = out_k[i]
        _body_terms(Jw, support[pair_a[k]], support[pair_b[k]], common, out_n[i], A[i, 0])
        _body_terms(Jw, support[pair_b[k]], support[pair_a[k]], common, out_n[i], A[i, 1])
    # the candidate rows first (pair, points, gap), then their bounds, then the rows: three
    # flat loops (the row loop vectorises; with h(gap) in it, it ran ~3x slower)
    nc = 0
    for i in range(count):
        k = out_k[i]
        ga, gb = pair_a[k], pair_b[k]
        n = out_n[i]
        corner2[i] = 1 if _is_corner(out_p2[i], Rw[gb], cw[gb], half[gb]) else 0
        if corner2[i] != 0 or _is_corner(out_p1[i], Rw[ga], cw[ga], half[ga]):
            continue  # (a corner's own row below)
        if witness_tie(Rw[ga], Rw[gb], n):
            continue  # (parallel features: any point of their overlap; the corners' rows)
        for m in range(3):
            P[nc, 0, m], P[nc, 1, m] = out_p1[i, m], out_p2[i, m]
        which[nc], gaps[nc] = i, out_d[i]
        nc += 1
    for side in range(2):  # 0: corners of box 2 vs the plane at p1; 1: box 1 vs p2
        for i in range(count):
            k = out_k[i]
            g = pair_b[k] if side == 0 else pair_a[k]
            o = pair_a[k] if side == 0 else pair_b[k]
            n = out_n[i]
            p1, p2 = out_p1[i], out_p2[i]
            R, c, hh = Rw[g], cw[g], half[g]
            for s in range(8):  # (x, y, z) = (±, ±, ±), z fastest
                sx = hh[0] if s & 4 else -hh[0]
                sy = hh[1] if s & 2 else -hh[1]
                sz = hh[2] if s & 1 else -hh[2]
                for m in range(3):
                    corner[m] = c[m] + R[m, 0] * sx + R[m, 1] * sy + R[m, 2] * sz
                gap = 0.0
                dd = 0.0
                for m in range(3):
                    gap += n[m] * ((corner[m] - p1[m]) if side == 0 else (p2[m] - corner[m]))
                    dd += (corner[m] - p1[m]) ** 2
                if not gap < trigger:
                    continue
                if side == 1 and corner2[i] != 0 and dd <= 1e-18:
                    continue  # (both witnesses corners: box 2's corner row is this one)
                sign = -1.0 if side == 0 else 1.0
                for m in range(3):
                    foot[m] = corner[m] + sign * gap * n[m]
                if side == 0:
                    _clamp_to_box(foot, Rw[o], cw[o], half[o], P[nc, 0])
                    for m in range(3):
                        P[nc, 1, m] = corner[m]
                else:
                    for m in range(3):
                        P[nc, 0, m] = corner[m]
                    _clamp_to_box(foot, Rw[o], cw[o], half[o], P[nc, 1])
                which[nc], gaps[nc] = i, gap
                nc += 1
    for j in range(nc):
        H[j] = damper_h(gaps[j], margin, trigger, damping)
    boxed = mid.shape[0] == nv
    r = 0
    left = 0
    for j in range(nc):
        if not H[j] < unreachable:  # (no row)
            continue
        i = which[j]
        _write_row(A, i, P[j, 0], P[j, 1], out_n[i], G, r)
        if boxed and not can_bind(G[r], box_most(G[r], mid, wide), H[j], free):
            left += 1  # (written over by the next row)
            continue
        h[r], row_pair[r], row_gap[r] = H[j], i, gaps[j]
        r += 1
    counts[4] += left
    return r


@njit(cache=True)
def collision_rows(
    joints, last_joints, bound, L_start, L_pair, L_arm, Rf, pf, box_frame, box_R, box_p, half,
    radius, pair_a, pair_b, support, Jw, margin, trigger, damping, unreachable, Rw, cw, placed,
    out_k, out_d, out_p1, out_p2, out_n, counts, G, h, row_pair, row_gap, common, last_axis,
    work, iwork, mid, wide, free,
) -> int:  # fmt: skip
    """:func:`close_pairs` below the trigger, then their :func:`plane_rows`, in one call
    (``mid``, ``wide``, ``free``: its box, or empty); returns the number of rows (``counts[2]``: the
    number of close pairs, ``counts[4]`` the rows left out; ``counts``: see
    :func:`close_pairs`; ``work``, ``iwork``: :func:`work_sizes`' scratch, nothing
    allocated)."""
    n = close_pairs(
        joints, last_joints, bound, L_start, L_pair, L_arm, Rf, pf, box_frame, box_R, box_p,
        half, radius, pair_a, pair_b, trigger, Rw, cw, placed, out_k, out_d, out_p1, out_p2,
        out_n, counts, last_axis, work, iwork,
    )  # fmt: skip
    counts[2] = n
    return plane_rows(
        n, out_k, out_d, out_p1, out_p2, out_n, pair_a, pair_b, Rw, cw, half, support, Jw,
        margin, trigger, damping, unreachable, G, h, row_pair, row_gap, common,
        work[CLOSE_WORK:], iwork[6:], mid, wide, free, counts,
    )  # fmt: skip
