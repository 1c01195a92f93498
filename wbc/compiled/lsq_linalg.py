"""The linear algebra of the compiled least-squares level solver (:mod:`wbc.compiled.lsq`):
dot products and updates on rows of 2-d arrays, Householder reflectors (pivoted QR of the
rows of a matrix, applied one or two at a time), the Gram matrix of the reflected rows and its
Cholesky factor, and the layout of the solver's work space.

Implementation: at these sizes (n ≈ 24, p ≈ 30) the time goes to loop overheads and memory
traffic rather than to arithmetic. Hence hand-written loops (a BLAS call costs more than it
saves); the work space in two blocks allocated once per call; the small kernels inlined into
their callers (``inline="always"``: numba links separately compiled functions, which LLVM does
not inline);
vectors kept as rows of 2-d arrays and indexed by row (a view created and handed to another
function costs two atomic reference count updates); column loops counted with unsigned
integers (numba wraps a negative signed index, which stops vectorisation); each loaded row
reused by four rows of output, and the reflectors applied two at a time.
"""

from __future__ import annotations

import numpy as np
from numba import njit, uint64

_SING_TOL = 1e-13  # with ridge = 0, a Cholesky pivot ≤ _SING_TOL·max diagonal is singular


# Work space, allocated once per call: float matrices W (reflectors, m × n), T ((B_F Q)ᵀ,
# n × p rounded up to a multiple of 4 and zero-padded, so that its rows vectorise without a
# scalar tail), N (Cholesky factor) and V, whose rows are the float vectors below (1/L_jj in
# V[_V_DINV], work rows V[_V_W], V[_V_W2]); an integer matrix ind whose rows are the index
# vectors below (row permutation of the QR, free and fixed variables, active set, its previous
# value in PDAS, pinned variables).
(_V_TAU, _V_NRM, _V_NRM_REF, _V_CVEC, _V_LAM, _V_RP, _V_E, _V_W, _V_W2, _V_T, _V_DINV,
 _V_MU, _V_MU_TOL, _V_X0, _V_MU0, _V_NU) = range(16)  # fmt: skip
_N_VEC = 16
_I_PERM, _I_FREE, _I_FIX, _I_FIXED, _I_PREV, _I_PINNED = range(6)
_N_IVEC = 6

# The linear algebra allows reassociation (so that reductions vectorise) and fused
# multiply-adds; numba inlines a function with its caller's flags, hence on the callers too.
# The active set logic (_solve) is plain IEEE arithmetic.
_FAST = {"reassoc", "contract"}
# Calls between kernels pass index constants and flags as np.int64(...)/np.bool_(...) values, and
# counters start as np.int64(0): numba compiles a callee once per literal argument type (a
# literal first value of a variable included), i.e. the whole call tree again (issue 13).


@njit(cache=True, fastmath=_FAST, inline="always")
def _dot(X, i, Y, j, c0, c1):
    """Σ X[i, c]·Y[j, c] over c0 ≤ c < c1."""
    s = 0.0
    for c in range(uint64(c0), uint64(c1)):
        s += X[i, c] * Y[j, c]
    return s


@njit(cache=True, fastmath=_FAST, inline="always")
def _r11_solve(W, k, V, src, dst):
    """V[dst, :k] = R11⁻¹ V[src, :k], R11 upper triangular stored transposed below W's
    diagonal (R11[j, i] = W[i, j]); back substitution, src may be dst."""
    for j in range(k - 1, -1, -1):
        s = V[src, j]
        for i in range(j + 1, k):
            s -= W[i, j] * V[dst, i]
        V[dst, j] = s / W[j, j]


@njit(cache=True, fastmath=_FAST, inline="always")
def _axpy(f, X, i, Y, j, c0, c1):
    """Y[j, c] += f·X[i, c] over c0 ≤ c < c1."""
    for c in range(uint64(c0), uint64(c1)):
        Y[j, c] += f * X[i, c]


@njit(cache=True, fastmath=_FAST, inline="always")
def _dot4(X, j, Y, i, c0, c1):
    """X[j]·Y[i + l] (l = 0…3) over columns c0 ≤ c < c1, in one pass."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    for c in range(uint64(c0), uint64(c1)):
        v = X[j, c]
        s0 += v * Y[i, c]
        s1 += v * Y[i + 1, c]
        s2 += v * Y[i + 2, c]
        s3 += v * Y[i + 3, c]
    return s0, s1, s2, s3


@njit(cache=True, fastmath=_FAST, inline="always")
def _axpy4(s0, s1, s2, s3, X, j, Y, i, c0, c1):
    """Y[i + l, c] −= s_l·X[j, c] (l = 0…3) over c0 ≤ c < c1, in one pass."""
    for c in range(uint64(c0), uint64(c1)):
        v = X[j, c]
        Y[i, c] -= s0 * v
        Y[i + 1, c] -= s1 * v
        Y[i + 2, c] -= s2 * v
        Y[i + 3, c] -= s3 * v


@njit(cache=True, fastmath=_FAST, inline="always")
def _sum4(f0, f1, f2, f3, X, i, Y, j, c1):
    """Y[j, c] += Σ_l f_l·X[i + l, c] over c < c1, in one pass."""
    for c in range(uint64(0), uint64(c1)):
        Y[j, c] += f0 * X[i, c] + f1 * X[i + 1, c] + f2 * X[i + 2, c] + f3 * X[i + 3, c]


@njit(cache=True, fastmath=_FAST, inline="always")
def _dot22(X, a, b, c1):
    """X[a + l]·X[b + l'] (l, l' = 0, 1) over c < c1, in one pass."""
    s00 = 0.0
    s01 = 0.0
    s10 = 0.0
    s11 = 0.0
    for c in range(uint64(0), uint64(c1)):
        x0 = X[a, c]
        x1 = X[a + 1, c]
        y0 = X[b, c]
        y1 = X[b + 1, c]
        s00 += x0 * y0
        s01 += x0 * y1
        s10 += x1 * y0
        s11 += x1 * y1
    return s00, s01, s10, s11


@njit(cache=True, fastmath=_FAST, inline="always")
def _sum24(W, j, X, c, Y, r, n):
    """Y[r] += Σ_q W[j, c+q]·X[c+q] and Y[r+1] += Σ_q W[j+1, c+q]·X[c+q] (q < 4), one pass."""
    f0 = W[j, c]
    f1 = W[j, c + 1]
    f2 = W[j, c + 2]
    f3 = W[j, c + 3]
    g0 = W[j + 1, c]
    g1 = W[j + 1, c + 1]
    g2 = W[j + 1, c + 2]
    g3 = W[j + 1, c + 3]
    for i in range(uint64(0), uint64(n)):
        x0 = X[c, i]
        x1 = X[c + 1, i]
        x2 = X[c + 2, i]
        x3 = X[c + 3, i]
        Y[r, i] += f0 * x0 + f1 * x1 + f2 * x2 + f3 * x3
        Y[r + 1, i] += g0 * x0 + g1 * x1 + g2 * x2 + g3 * x3


@njit(cache=True, fastmath=_FAST, inline="always")
def _sub24(W, j, Y, r, X, c, n):
    """X[c+q] −= W[j, c+q]·Y[r] + W[j+1, c+q]·Y[r+1] (q < 4), one pass."""
    f0 = W[j, c]
    f1 = W[j, c + 1]
    f2 = W[j, c + 2]
    f3 = W[j, c + 3]
    g0 = W[j + 1, c]
    g1 = W[j + 1, c + 1]
    g2 = W[j + 1, c + 2]
    g3 = W[j + 1, c + 3]
    for i in range(uint64(0), uint64(n)):
        a = Y[r, i]
        b = Y[r + 1, i]
        X[c, i] -= f0 * a + g0 * b
        X[c + 1, i] -= f1 * a + g1 * b
        X[c + 2, i] -= f2 * a + g2 * b
        X[c + 3, i] -= f3 * a + g3 * b


@njit(cache=True)
def _fill(dst, value):
    for i in range(dst.shape[0]):
        dst[i] = value


@njit(cache=True, fastmath=_FAST)
def _reflect_rows(W, j, nf, tj, i0, m):
    """Rows i0…m−1 of W times the reflector I − tj v vᵀ, v = (0…0, 1, W[j, j+1:nf])."""
    i = i0
    while i + 4 <= m:
        s0, s1, s2, s3 = _dot4(W, j, W, i, j + 1, nf)
        s0 = tj * (W[i, j] + s0)
        s1 = tj * (W[i + 1, j] + s1)
        s2 = tj * (W[i + 2, j] + s2)
        s3 = tj * (W[i + 3, j] + s3)
        W[i, j] -= s0
        W[i + 1, j] -= s1
        W[i + 2, j] -= s2
        W[i + 3, j] -= s3
        _axpy4(s0, s1, s2, s3, W, j, W, i, j + 1, nf)
        i += 4
    while i < m:
        s = tj * (W[i, j] + _dot(W, j, W, i, j + 1, nf))
        W[i, j] -= s
        _axpy(-s, W, j, W, i, j + 1, nf)
        i += 1


@njit(cache=True, fastmath=_FAST)
def _reflect_vector(W, j, nf, tj, V, row):
    """V[row, :nf] ← (I − tj v vᵀ) V[row, :nf], v = (0…0, 1, W[j, j+1:nf])."""
    s = tj * (V[row, j] + _dot(W, j, V, row, j + 1, nf))
    V[row, j] -= s
    _axpy(-s, W, j, V, row, j + 1, nf)


@njit(cache=True, fastmath=_FAST)
def _reflect_columns(T, W, j, nf, tj, V, pp):
    """Rows j…nf−1 of T (length pp) ← (I − tj v vᵀ) applied from the left,
    v = (1, W[j, j+1:nf]); V[_V_W] is work space."""
    for i in range(pp):  # w = tj·vᵀ T
        V[_V_W, i] = T[j, i]
    c = j + 1
    while c + 4 <= nf:
        _sum4(W[j, c], W[j, c + 1], W[j, c + 2], W[j, c + 3], T, c, V, _V_W, pp)
        c += 4
    while c < nf:
        _axpy(W[j, c], T, c, V, _V_W, 0, pp)
        c += 1
    for i in range(pp):
        V[_V_W, i] *= tj
        T[j, i] -= V[_V_W, i]
    c = j + 1  # T −= v w
    while c + 4 <= nf:
        _axpy4(W[j, c], W[j, c + 1], W[j, c + 2], W[j, c + 3], V, _V_W, T, c, 0, pp)
        c += 4
    while c < nf:
        _axpy(-W[j, c], V, _V_W, T, c, 0, pp)
        c += 1


@njit(cache=True, fastmath=_FAST)
def _reflect_columns2(T, W, j, nf, t1, t2, V, pp):
    """Rows j…nf−1 of T (length pp) ← H_{j+1} H_j T, two reflectors in one pass each way
    (compact WY): with u = v_jᵀ T, u' = v_{j+1}ᵀ T and γ = v_{j+1}·v_j,
    ``T −= v_j a + v_{j+1} b``, a = t1·u, b = t2·(u' − γ a). V[_V_W], V[_V_W2] are work space."""
    w = W[j, j + 1]  # v_j at row j+1 (v_{j+1} is 1 there)
    for i in range(pp):
        V[_V_W, i] = T[j, i] + w * T[j + 1, i]
        V[_V_W2, i] = T[j + 1, i]
    c = j + 2
    while c + 4 <= nf:
        _sum24(W, j, T, c, V, _V_W, pp)
        c += 4
    while c < nf:
        _axpy(W[j, c], T, c, V, _V_W, 0, pp)
        _axpy(W[j + 1, c], T, c, V, _V_W2, 0, pp)
        c += 1
    gamma = w + _dot(W, j + 1, W, j, j + 2, nf)
    for i in range(pp):
        a = t1 * V[_V_W, i]
        b = t2 * (V[_V_W2, i] - gamma * a)
        V[_V_W, i] = a
        V[_V_W2, i] = b
        T[j, i] -= a
        T[j + 1, i] -= w * a + b
    c = j + 2
    while c + 4 <= nf:
        _sub24(W, j, V, _V_W, T, c, pp)
        c += 4
    while c < nf:
        _axpy(-W[j, c], V, _V_W, T, c, 0, pp)
        _axpy(-W[j + 1, c], V, _V_W2, T, c, 0, pp)
        c += 1


@njit(cache=True, fastmath=_FAST)
def _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol):
    """Householder QR with column pivoting of ``W[:m, :nf]ᵀ`` (the rows of W are the columns).

    On return rows are permuted (``ind[_I_PERM]`` follows, from its initial value),
    ``W[i, j] = R[j, i]`` for j ≤ i < m, j < k,
    and reflector j is ``I − τ_j v vᵀ`` with ``v = (0…0, 1, W[j, j+1:nf])`` (τ = 2/‖v‖², in
    ``V[_V_TAU]``). Returns the numerical rank k: the first pivot whose remaining norm is
    ≤ rank_rtol·|R_00| stops the factorisation.
    """
    kmax = min(m, nf)
    for i in range(m):
        s = _dot(W, i, W, i, 0, nf)
        V[_V_NRM, i] = s
        V[_V_NRM_REF, i] = s
    r00 = 0.0
    for j in range(kmax):
        piv = j
        best = V[_V_NRM, j]
        for i in range(j + 1, m):
            if V[_V_NRM, i] > best:
                best = V[_V_NRM, i]
                piv = i
        norm = np.sqrt(max(best, 0.0))
        if j == 0:
            r00 = norm
            if r00 == 0.0:
                return 0
        elif norm <= rank_rtol * r00:
            return j
        if piv != j:
            for c in range(nf):
                tmp = W[j, c]
                W[j, c] = W[piv, c]
                W[piv, c] = tmp
            itmp = ind[_I_PERM, j]
            ind[_I_PERM, j] = ind[_I_PERM, piv]
            ind[_I_PERM, piv] = itmp
            for row in (_V_NRM, _V_NRM_REF):
                tmp = V[row, j]
                V[row, j] = V[row, piv]
                V[row, piv] = tmp
        alpha = W[j, j]
        sigma = _dot(W, j, W, j, j + 1, nf)
        if sigma == 0.0:
            V[_V_TAU, j] = 0.0
        else:
            beta = np.sqrt(alpha * alpha + sigma)
            if alpha >= 0.0:
                beta = -beta
            inv = 1.0 / (alpha - beta)
            for c in range(uint64(j + 1), uint64(nf)):
                W[j, c] *= inv
            tj = (beta - alpha) / beta
            V[_V_TAU, j] = tj
            W[j, j] = beta
            _reflect_rows(W, j, nf, tj, j + 1, m)
        for i in range(j + 1, m):  # downdate the remaining norms, recompute on cancellation
            V[_V_NRM, i] -= W[i, j] * W[i, j]
            if V[_V_NRM, i] <= 1.5e-8 * V[_V_NRM_REF, i]:
                V[_V_NRM, i] = _dot(W, i, W, i, j + 1, nf)
                V[_V_NRM_REF, i] = V[_V_NRM, i]
    return kmax


@njit(cache=True, fastmath=_FAST)
def _gram(T, k, d, pp, N):
    """Lower triangle of N[:d, :d] = M Mᵀ for the rows M = T[k:k+d] (length pp), 2 × 2 at once."""
    a = 0
    while a + 2 <= d:
        for b in range(0, a + 1, 2):
            s00, s01, s10, s11 = _dot22(T, k + a, k + b, pp)
            N[a, b] = s00
            N[a, b + 1] = s01  # (the upper entry N[a, a+1] when b = a: unused)
            N[a + 1, b] = s10
            N[a + 1, b + 1] = s11
        a += 2
    if a < d:
        for b in range(a + 1):
            N[a, b] = _dot(T, k + a, T, k + b, 0, pp)


@njit(cache=True, fastmath=_FAST)
def _cholesky(N, dim, ridge, V):
    """In place N[:dim, :dim] = L Lᵀ (L in the lower triangle, 1/L_jj in ``V[_V_DINV, j]``);
    False if not positive definite.

    With ridge = 0 a pivot ≤ _SING_TOL × the largest diagonal entry counts as singular.
    """
    dmax = 0.0
    for j in range(dim):
        dmax = max(dmax, N[j, j])
    for j in range(dim):  # column by column: the dots of one column are independent
        piv = N[j, j] - _dot(N, j, N, j, 0, j)
        if not piv > 0.0 or (ridge == 0.0 and piv <= _SING_TOL * dmax):
            return False
        ljj = np.sqrt(piv)
        N[j, j] = ljj
        inv = 1.0 / ljj
        V[_V_DINV, j] = inv
        i = j + 1
        while i + 4 <= dim:
            s0, s1, s2, s3 = _dot4(N, j, N, i, 0, j)
            N[i, j] = (N[i, j] - s0) * inv
            N[i + 1, j] = (N[i + 1, j] - s1) * inv
            N[i + 2, j] = (N[i + 2, j] - s2) * inv
            N[i + 3, j] = (N[i + 3, j] - s3) * inv
            i += 4
        while i < dim:
            N[i, j] = (N[i, j] - _dot(N, i, N, j, 0, j)) * inv
            i += 1
    return True


@njit(cache=True, fastmath=_FAST)
def _cholesky_solve(N, dim, V, row):
    """Solve L Lᵀ w = V[row, :dim] in place (L from :func:`_cholesky`)."""
    for i in range(dim):
        V[row, i] = (V[row, i] - _dot(N, i, V, row, 0, i)) * V[_V_DINV, i]
    for j in range(dim - 1, -1, -1):
        f = V[row, j] * V[_V_DINV, j]
        V[row, j] = f
        _axpy(-f, N, j, V, row, 0, j)
