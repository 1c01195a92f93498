"""Compiled solver for one least-squares level with equalities and box bounds.

One call solves::

    minimise   ½‖B x − r‖² + ½·ridge·‖x‖²
    subject to A x = a            (rows may be linearly dependent, m may be 0)
               lower ≤ x ≤ upper  (entries may be ±inf; lower == upper pins x_i)

with an active set on the bounds. For a guessed active set the variables split into fixed ones
X (held at a bound) and free ones F, and the equality-constrained least-squares subproblem is
solved in the null space of ``A_F``:

* pivoted Householder QR ``A_Fᵀ Π = Q [R; 0]``, rank k where ``|R_jj| > rank_rtol·|R_00|``,
  ``Q = [Y Z]``; the minimum-norm particular solution ``x_F = Y y₀`` solves the k independent
  rows, and the dependent rows must agree with it (else the equalities are inconsistent);
* ``x_F = Y y₀ + Z z`` with ``M = B_F Z``, ``r' = r − B_X x_X − B_F Y y₀``:
  ``(MᵀM + ridge·I) z = Mᵀ r'`` (normal form, p ≥ d = dim z) or
  ``z = Mᵀ (M Mᵀ + ridge·I)⁻¹ r'`` (row form, p < d: accurate for a tiny ridge when M has full
  row rank), by Cholesky; ``ridge·‖z‖²`` is the ridge on all of x_F since Y ⟂ Z. Z is never
  formed: ``(B_F Q)ᵀ = Qᵀ B_Fᵀ`` comes from the reflectors, applied two at a time (compact
  WY with blocks of two) to ``B_Fᵀ``, stored with its rows padded to a multiple of 4;
* multipliers ``A_Fᵀ λ = −g_F`` (g the gradient, same QR) and the bounds' reduced gradients
  ``μ_X = g_X + A_Xᵀ λ``: a variable at its upper bound is optimal iff μ ≤ 0, at its lower
  bound iff μ ≥ 0.

The active set is first updated by the primal-dual active set method (PDAS,
Hintermüller–Ito–Kunisch; block principal pivoting): a free variable beyond a bound is fixed at
it and a fixed one with the wrong multiplier sign is released, all at once. PDAS converges in a
few steps when the reduced Hessian is close to an M-matrix but can cycle otherwise (typically
p < d with a small ridge). When the number of infeasibilities stops falling, or an exchange makes
the equalities inconsistent, the solver switches to a dual active set method (Goldfarb–Idnani
on the bounds): from the set PDAS met with the fewest infeasibilities, less its wrong-signed
bounds (released one at a time, the largest multiplier first: a dual feasible point; on the
walk's hierarchy, 14 subproblems → 8 on the ticks where PDAS stalls), it adds the most
violated bound, moving along the subproblem's solution, which is affine in the
value the added variable is held at, and releasing a bound whose multiplier reaches zero on the
way; when the added bound depends on the active ones and the equalities (holding it drops the
rank of A_F), a pure dual step releases one of those instead, or, if none can go and the
variable meets its bound already to roundoff (a degenerate vertex), the bound is held with a
zero multiplier. Each completed addition strictly raises the dual objective of a strictly
convex problem, so the method is finite.

``state`` is an int8 array (any integer dtype compiles too): -1 = at the lower bound, 0 = free,
+1 = at the upper bound. It is the warm start on input and the final active set on output; a
value pointing at an infinite bound counts as 0. Pinned variables (lower == upper) are always
fixed and reported as -1 or +1 after the sign of their multiplier.

Tolerances: the equalities are inconsistent when the dependent rows miss by more than
1e-9·(1 + ‖a‖ + ‖A_X x_X‖); a free variable is beyond a bound b by more than 1e-12·(1 + |b|)
(a returned solution is then clipped onto the box exactly); a multiplier has the wrong sign by
more than 1e-9 × the sum of the magnitudes of its terms.

Limits: ``max_iter`` counts subproblem solves (about 3.5 µs each at n = 24, m = 6, p = 30).
From a cold start PDAS needs 2–7 of them on well-conditioned levels; levels with p < d, a tiny
ridge and many active bounds can need 10–30 or more (that is where the dual method takes
over); a warm start from the previous tick's active set usually needs 1. With ridge = 0 the
problem must be strictly convex on the visited faces (B_F Z of full column rank): a singular
normal form returns NUMERICAL, and with p < d the row form returns the minimum-norm z, for
which the active set iteration is not guaranteed to settle (MAX_ITER). Pass float64
C-contiguous arrays: other layouts or dtypes compile another specialisation (~15 s, cached
afterwards).

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

OK, MAX_ITER, INCONSISTENT, NUMERICAL = 0, 1, 2, 3

_X_TOL = 1e-12  # a free x_i is beyond a bound b when by more than _X_TOL·(1 + |b|)
_MU_TOL = 1e-9  # a multiplier has the wrong sign when by more than _MU_TOL × its terms' size
_EQ_TOL = 1e-9  # equalities are inconsistent when ‖residual‖ > _EQ_TOL·(1 + ‖a‖ + ‖A_X x_X‖)
_SING_TOL = 1e-13  # with ridge = 0, a Cholesky pivot ≤ _SING_TOL·max diagonal is singular

_SUB_OK, _SUB_INCONSISTENT, _SUB_SINGULAR = 0, 1, 2
_PDAS, _DUAL_START, _DUAL_ADD = 0, 1, 2

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


@njit(cache=True, fastmath=_FAST)
def _subproblem(A, a, B, r, ridge, lower, upper, x, rank_rtol, W, T, N, V, ind):
    """Solve the equality-constrained subproblem for the fixed set ``ind[_I_FIXED]`` (-1/+1 = at
    the lower/upper bound).

    Writes x, and for fixed i the multiplier ``V[_V_MU, i]`` with its tolerance
    ``V[_V_MU_TOL, i]``. Returns (_SUB_OK, _SUB_INCONSISTENT or _SUB_SINGULAR; the rank of A_F).
    """
    m, n = A.shape
    p = B.shape[0]
    pp = (p + 3) & ~3
    nf = np.int64(0)
    nx = 0
    for i in range(n):
        if ind[_I_FIXED, i] == 0:
            ind[_I_FREE, nf] = i
            nf += 1
        else:
            x[i] = lower[i] if ind[_I_FIXED, i] < 0 else upper[i]
            ind[_I_FIX, nx] = i
            nx += 1
    # equalities restricted to F: A_F x_F = a − A_X x_X
    a_norm = 0.0
    ax_norm = 0.0
    for i in range(m):
        s = 0.0
        for c in range(nx):
            s += A[i, ind[_I_FIX, c]] * x[ind[_I_FIX, c]]
        V[_V_CVEC, i] = a[i] - s
        a_norm += a[i] * a[i]
        ax_norm += s * s
        ind[_I_PERM, i] = i
        for c in range(nf):
            W[i, c] = A[i, ind[_I_FREE, c]]
    k = _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol)
    # y₀ from R11ᵀ y₀ = (Πᵀ c)[:k]; the dependent rows must agree
    for i in range(k):
        V[_V_T, i] = (V[_V_CVEC, ind[_I_PERM, i]] - _dot(W, i, V, _V_T, 0, i)) / W[i, i]
    res = 0.0
    for i in range(k, m):
        d_i = V[_V_CVEC, ind[_I_PERM, i]] - _dot(W, i, V, _V_T, 0, k)
        res += d_i * d_i
    if np.sqrt(res) > _EQ_TOL * (1.0 + np.sqrt(a_norm) + np.sqrt(ax_norm)):
        return _SUB_INCONSISTENT, k
    d = nf - k
    # T = (B_F Q)ᵀ = Qᵀ B_Fᵀ = H_{k−1} ⋯ H_0 B_Fᵀ: rows 0…k−1 are (B_F Y)ᵀ, rows k…nf−1 are Mᵀ
    i = 0
    while i + 4 <= p:  # (four rows of B at a time: a quarter of the loop overhead)
        for c in range(nf):
            fc = ind[_I_FREE, c]
            T[c, i] = B[i, fc]
            T[c, i + 1] = B[i + 1, fc]
            T[c, i + 2] = B[i + 2, fc]
            T[c, i + 3] = B[i + 3, fc]
        i += 4
    while i < p:
        for c in range(nf):
            T[c, i] = B[i, ind[_I_FREE, c]]
        i += 1
    for c in range(nf):
        for i in range(p, pp):
            T[c, i] = 0.0
    for j in range(0, k - 1, 2):
        _reflect_columns2(T, W, j, nf, V[_V_TAU, j], V[_V_TAU, j + 1], V, pp)
    if k % 2 == 1 and V[_V_TAU, k - 1] != 0.0:
        _reflect_columns(T, W, k - 1, nf, V[_V_TAU, k - 1], V, pp)
    # r' = r − B x₀, x₀ = (x_X, Y y₀)
    for i in range(p):
        s = 0.0
        for c in range(nx):
            s += B[i, ind[_I_FIX, c]] * x[ind[_I_FIX, c]]
        V[_V_RP, i] = r[i] - s
    for i in range(p, pp):
        V[_V_RP, i] = 0.0
    for j in range(k):
        _axpy(-V[_V_T, j], T, j, V, _V_RP, 0, pp)
    # null-space least squares for z (into t[k:nf]), and the residual e = B x − r
    if d > 0 and p >= d:  # normal form: (MᵀM + ridge·I) z = Mᵀ r'
        _gram(T, k, d, pp, N)
        for c in range(d):
            N[c, c] += ridge
            V[_V_W, c] = _dot(T, k + c, V, _V_RP, 0, pp)
        if not _cholesky(N, d, ridge, V):
            return _SUB_SINGULAR, k
        _cholesky_solve(N, d, V, np.int64(_V_W))
        for i in range(pp):  # e = M z − r'
            V[_V_E, i] = -V[_V_RP, i]
        for c in range(d):
            V[_V_T, k + c] = V[_V_W, c]
            _axpy(V[_V_W, c], T, k + c, V, _V_E, 0, pp)
    elif d > 0:  # row form: z = Mᵀ (M Mᵀ + ridge·I)⁻¹ r'
        for i in range(p):
            for i2 in range(i + 1):
                N[i, i2] = 0.0
        for c in range(d):
            for i in range(p):
                _axpy(T[k + c, i], T, k + c, N, i, 0, i + 1)
        for i in range(p):
            N[i, i] += ridge
            V[_V_E, i] = V[_V_RP, i]
        if not _cholesky(N, p, ridge, V):
            return _SUB_SINGULAR, k
        _cholesky_solve(N, p, V, np.int64(_V_E))  # w = (M Mᵀ + ridge I)⁻¹ r'
        for i in range(p, pp):
            V[_V_E, i] = 0.0
        for c in range(d):
            V[_V_T, k + c] = _dot(T, k + c, V, _V_E, 0, pp)  # z = Mᵀ w
        for i in range(p):  # e = M z − r' = −ridge·w, without the cancellation
            V[_V_E, i] *= -ridge
    else:
        for i in range(pp):
            V[_V_E, i] = -V[_V_RP, i]
    if nx > 0:  # λ' (permuted, basic): R11 λ' = −(Qᵀ g_F)[:k], (Qᵀ g_F)_j = T_j·e + ridge·y₀_j
        for j in range(k):
            V[_V_LAM, j] = -(_dot(T, j, V, _V_E, 0, pp) + ridge * V[_V_T, j])
        for j in range(k - 1, -1, -1):
            s = V[_V_LAM, j]
            for i in range(j + 1, k):
                s -= W[i, j] * V[_V_LAM, i]
            V[_V_LAM, j] = s / W[j, j]
    # x_F = Q (y₀, z): the reflectors in reverse order
    for j in range(k - 1, -1, -1):
        if V[_V_TAU, j] != 0.0:
            _reflect_vector(W, j, nf, V[_V_TAU, j], V, _V_T)
    for c in range(nf):
        x[ind[_I_FREE, c]] = V[_V_T, c]
    # reduced gradients of the fixed variables: μ = B_iᵀ e + ridge x_i + A_iᵀ λ
    for c in range(nx):
        i = ind[_I_FIX, c]
        g = 0.0
        for j in range(p):
            g += B[j, i] * V[_V_E, j]
        size = abs(g) + ridge * abs(x[i])
        s = g + ridge * x[i]
        for j in range(k):
            term = V[_V_LAM, j] * A[ind[_I_PERM, j], i]
            s += term
            size += abs(term)
        V[_V_MU, i] = s
        V[_V_MU_TOL, i] = _MU_TOL * size
    return _SUB_OK, k


@njit(cache=True, fastmath=_FAST)
def _dependency(A, i, rank_rtol, W, V, ind):
    """ν with e_i = Aᵀλ' + Σ_X ν_j e_j, for a free i whose bound depends on the active ones.

    λ' solves A_Fᵀ λ' = e_i restricted to F (basic solution from the pivoted QR of A_Fᵀ; F and
    X from ``ind[_I_FIXED]``), and ν_j = −(Aᵀλ')_j on the fixed variables (0 elsewhere), into
    ``V[_V_NU]``. The rest of the work space is shared with :func:`_subproblem`.
    """
    m, n = A.shape
    nf = np.int64(0)
    pos = np.int64(-1)
    for j in range(n):
        V[_V_NU, j] = 0.0
        if ind[_I_FIXED, j] == 0:
            if j == i:
                pos = nf
            ind[_I_FREE, nf] = j
            nf += 1
    for row in range(m):
        ind[_I_PERM, row] = row
        for c in range(nf):
            W[row, c] = A[row, ind[_I_FREE, c]]
    k = _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol)
    for c in range(nf):  # u = Qᵀ e_pos (reflectors in order)
        V[_V_T, c] = 0.0
    V[_V_T, pos] = 1.0
    for j in range(k):
        if V[_V_TAU, j] != 0.0:
            _reflect_vector(W, j, nf, V[_V_TAU, j], V, _V_T)
    for j in range(k - 1, -1, -1):  # R11 λ'' = u[:k]
        s = V[_V_T, j]
        for row in range(j + 1, k):
            s -= W[row, j] * V[_V_LAM, row]
        V[_V_LAM, j] = s / W[j, j]
    for j in range(n):
        if ind[_I_FIXED, j] != 0:
            s = 0.0
            for row in range(k):
                s += V[_V_LAM, row] * A[ind[_I_PERM, row], j]
            V[_V_NU, j] = -s


@njit(cache=True, fastmath=_FAST)
def _rank_with(A, i, rank_rtol, W, V, ind):
    """Numerical rank of A restricted to the free variables and variable i (W, V and ind are
    work space, as in :func:`_dependency`)."""
    m, n = A.shape
    nf = np.int64(0)
    for j in range(n):
        if ind[_I_FIXED, j] == 0 or j == i:
            ind[_I_FREE, nf] = j
            nf += 1
    for row in range(m):
        ind[_I_PERM, row] = row
        for c in range(nf):
            W[row, c] = A[row, ind[_I_FREE, c]]
    return _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol)


@njit(cache=True, inline="always")
def _wrong_sign(side, mu, tol):
    """True when the multiplier ``mu`` of a bound on ``side`` (±1) has the wrong sign."""
    if side > 0:
        return mu > tol
    return mu < -tol


@njit(cache=True, inline="always")
def _violation(xi, lo, up):
    """How far xi lies beyond [lo, up] relative to 1 + |bound| (0 inside, or within _X_TOL)."""
    if xi > up + _X_TOL * (1.0 + abs(up)):
        return (xi - up) / (1.0 + abs(up))
    if xi < lo - _X_TOL * (1.0 + abs(lo)):
        return (lo - xi) / (1.0 + abs(lo))
    return 0.0


@njit(cache=True)
def _finish(x, lower, upper, V, mu_row, ind, state, clip):
    """Write the active set into state; with ``clip``, put the free variables (within _X_TOL of
    the box at a solution) exactly on it. Pinned variables report the sign of their multiplier
    (``V[mu_row]``)."""
    for i in range(x.shape[0]):
        if ind[_I_PINNED, i]:
            state[i] = -1 if V[mu_row, i] >= 0.0 else 1
        else:
            state[i] = ind[_I_FIXED, i]
            if clip and ind[_I_FIXED, i] == 0:
                x[i] = min(max(x[i], lower[i]), upper[i])


@njit(cache=True)
def _solve(A, a, B, r, ridge, lower, upper, state, x, rank_rtol, max_iter):
    """The solver behind :func:`solve_level` (compiled once for float ridge/rank_rtol and an
    integer max_iter, however the public functions are called)."""
    m, n = A.shape
    p = B.shape[0]
    if a.shape[0] != m:
        raise ValueError("solve_level: a must have one entry per row of A")
    if B.shape[1] != n:
        raise ValueError("solve_level: B must have as many columns as A")
    if r.shape[0] != p:
        raise ValueError("solve_level: r must have one entry per row of B")
    if lower.shape[0] != n or upper.shape[0] != n or state.shape[0] != n or x.shape[0] != n:
        raise ValueError("solve_level: lower, upper, state and x must have n entries")
    if not ridge >= 0.0:
        raise ValueError("solve_level: ridge must be >= 0")
    pp = (p + 3) & ~3
    work = np.empty((4, max(m, n, _N_VEC), max(m, n, pp)))
    W = work[0]
    T = work[1]
    N = work[2]
    V = work[3]
    # (the vectors are used as rows of V and ind: a view per vector costs reference counting)
    ind = np.empty((_N_IVEC, max(m, n)), dtype=np.int64)
    warm = False
    for i in range(n):
        if not lower[i] <= upper[i] or lower[i] == np.inf or upper[i] == -np.inf:
            raise ValueError("solve_level: need lower <= upper, no NaN, and finite if equal")
        V[_V_MU, i] = 0.0
        ind[_I_PINNED, i] = 0
        ind[_I_FIXED, i] = 0
        if lower[i] == upper[i]:
            ind[_I_PINNED, i] = 1
            ind[_I_FIXED, i] = -1
        elif state[i] > 0 and upper[i] < np.inf:
            ind[_I_FIXED, i] = 1
            warm = True
        elif state[i] < 0 and lower[i] > -np.inf:
            ind[_I_FIXED, i] = -1
            warm = True
    # phases: PDAS; then, if it stalls, the dual active set method (Goldfarb–Idnani on the
    # bounds), which first releases wrong-signed bounds (DUAL_START) and then adds violated
    # bounds one at a time along the path of the subproblem's solution (DUAL_ADD). One call
    # site of _subproblem keeps the compiled code (and the compile time) small.
    phase = _PDAS
    best = n + 1  # fewest PDAS infeasibilities so far
    count = 0
    i_add = np.int64(-1)
    side = 0
    while True:
        if count >= max_iter:
            if phase == _DUAL_ADD:  # the last point on the path meets the equalities
                for i in range(n):
                    x[i] = V[_V_X0, i]
                    V[_V_MU, i] = V[_V_MU0, i]
            _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(False))
            return MAX_ITER, count
        count += 1
        sub, rank = _subproblem(A, a, B, r, ridge, lower, upper, x, rank_rtol, W, T, N, V, ind)
        if sub == _SUB_SINGULAR:
            _fill(x, np.nan)
            return NUMERICAL, count
        if phase == _PDAS:
            if sub == _SUB_INCONSISTENT:
                if count == 1 and warm:  # retry from a cold start
                    warm = False
                    max_iter += 1
                    for i in range(n):
                        ind[_I_FIXED, i] = -1 if ind[_I_PINNED, i] else 0
                    continue
                if best > n:  # even the cold start is inconsistent
                    _fill(x, np.nan)
                    for i in range(n):
                        state[i] = -1 if ind[_I_PINNED, i] else 0
                    return INCONSISTENT, count
                # the last exchange fixed too many variables: back to the previous set (which
                # was consistent), and on with the dual method
                for i in range(n):
                    ind[_I_FIXED, i] = ind[_I_PREV, i]
                phase = _DUAL_START
                continue
            n_inf = 0
            for i in range(n):
                if ind[_I_PINNED, i]:
                    continue
                if ind[_I_FIXED, i] == 0:
                    n_inf += _violation(x[i], lower[i], upper[i]) > 0.0
                else:
                    n_inf += _wrong_sign(ind[_I_FIXED, i], V[_V_MU, i], V[_V_MU_TOL, i])
            if n_inf == 0:
                _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(True))
                return OK, count
            if n_inf < best:
                best = n_inf
                for i in range(n):
                    ind[_I_PREV, i] = ind[_I_FIXED, i]
                    if ind[_I_PINNED, i]:
                        continue
                    if ind[_I_FIXED, i] == 0:
                        if _violation(x[i], lower[i], upper[i]) > 0.0:
                            ind[_I_FIXED, i] = 1 if x[i] > upper[i] else -1
                    elif _wrong_sign(ind[_I_FIXED, i], V[_V_MU, i], V[_V_MU_TOL, i]):
                        ind[_I_FIXED, i] = 0
                continue
            # PDAS is not making progress (it may cycle): the dual method, from the set with
            # the fewest infeasibilities (the last exchange made things worse)
            phase = _DUAL_START
            for i in range(n):
                ind[_I_FIXED, i] = ind[_I_PREV, i]
            continue
        if phase == _DUAL_START:
            if sub == _SUB_INCONSISTENT:  # cannot happen: only releases since a consistent set
                _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(False))
                return MAX_ITER, count
            # a dual feasible start: no bound with the wrong multiplier sign. The most wrong
            # one is released at a time (the others' signs may change with it)
            i_worst = -1
            worst_mu = 0.0
            for i in range(n):
                side_i = ind[_I_FIXED, i]
                if side_i != 0 and not ind[_I_PINNED, i]:
                    if _wrong_sign(side_i, V[_V_MU, i], V[_V_MU_TOL, i]):
                        if abs(V[_V_MU, i]) > worst_mu:
                            worst_mu = abs(V[_V_MU, i])
                            i_worst = i
            if i_worst >= 0:
                ind[_I_FIXED, i_worst] = 0
                continue
            for i in range(n):
                V[_V_X0, i] = x[i]
                V[_V_MU0, i] = V[_V_MU, i]
            phase = _DUAL_ADD
        elif sub == _SUB_INCONSISTENT or rank < _rank_with(A, i_add, rank_rtol, W, V, ind):
            # the bound being added is a combination e_i = Aᵀλ' + Σ_X ν_j e_j of the equalities
            # and the active bounds (holding x_i at it drops the rank of A_F; the subproblem is
            # inconsistent, or consistent only because x_i is at the bound to roundoff already,
            # and then its multipliers are not unique), so x cannot move: a pure dual step
            # instead. Raising the added multiplier by s·τ (s its right sign) shifts μ_j by
            # −s·τ·ν_j; the first active bound whose multiplier reaches zero is released
            ind[_I_FIXED, i_add] = 0
            _dependency(A, i_add, rank_rtol, W, V, ind)
            sgn = -side
            tau_min = np.inf
            j_drop = -1
            for j in range(n):
                side_j = ind[_I_FIXED, j]
                if side_j == 0 or ind[_I_PINNED, j]:
                    continue
                nu_j = V[_V_NU, j]
                rate = side_j * sgn * nu_j  # d(−fixed_j μ_j)/dτ
                if rate < -1e-12 * (1.0 + abs(nu_j)):
                    tj = max(-side_j * V[_V_MU0, j], 0.0) / -rate
                    if tj < tau_min:
                        tau_min = tj
                        j_drop = j
            if j_drop >= 0:
                for j in range(n):
                    if ind[_I_FIXED, j] != 0:
                        V[_V_MU0, j] -= sgn * tau_min * V[_V_NU, j]
                V[_V_MU0, i_add] += sgn * tau_min
                ind[_I_FIXED, j_drop] = 0
                ind[_I_FIXED, i_add] = side
                continue
            if sub == _SUB_INCONSISTENT:  # the bounds and the equalities have no common point
                for i in range(n):
                    x[i] = V[_V_X0, i]
                _finish(x, lower, upper, V, np.int64(_V_MU0), ind, state, np.bool_(False))
                return MAX_ITER, count
            # x_i meets its bound already (to roundoff): hold it there, with μ_i = 0
            ind[_I_FIXED, i_add] = side
            V[_V_MU0, i_add] = 0.0
            for i in range(n):
                V[_V_X0, i] = x[i]
        else:
            # x, mu solve the problem with i_add on its bound; the segment from (x0, mu0) to
            # them is the path as x_i moves to the bound. Stop where a multiplier first
            # reaches zero (the bound is released there), else take the whole step
            theta = 1.0
            j_drop = -1
            for j in range(n):
                side_j = ind[_I_FIXED, j]
                if side_j == 0 or ind[_I_PINNED, j] or j == i_add:
                    continue
                if _wrong_sign(side_j, V[_V_MU, j], V[_V_MU_TOL, j]):
                    # margins of the right sign (−fixed·μ ≥ 0), at the start and at the end
                    m0 = max(-side_j * V[_V_MU0, j], 0.0)
                    m1 = -side_j * V[_V_MU, j]
                    th = m0 / (m0 - m1)
                    if th < theta:
                        theta = th
                        j_drop = j
            if j_drop >= 0:
                for j in range(n):
                    V[_V_X0, j] += theta * (x[j] - V[_V_X0, j])
                    V[_V_MU0, j] += theta * (V[_V_MU, j] - V[_V_MU0, j])
                ind[_I_FIXED, j_drop] = 0
                continue
            for i in range(n):
                V[_V_X0, i] = x[i]
                V[_V_MU0, i] = V[_V_MU, i]
        # (DUAL_ADD) x0, mu0 solve the current set with the right signs: add the bound farthest
        # beyond (relative to 1 + |bound|), or stop
        i_add = np.int64(-1)
        worst = 0.0
        for i in range(n):
            if ind[_I_FIXED, i] == 0:
                v = _violation(V[_V_X0, i], lower[i], upper[i])
                if v > worst:
                    worst = v
                    i_add = i
        if i_add < 0:
            wrong = False  # (guards against roundoff: the dual method keeps the signs right)
            for i in range(n):
                side_i = ind[_I_FIXED, i]
                if side_i != 0 and not ind[_I_PINNED, i]:
                    if _wrong_sign(side_i, V[_V_MU0, i], V[_V_MU_TOL, i]):
                        ind[_I_FIXED, i] = 0
                        wrong = True
            if wrong:
                phase = _DUAL_START
                continue
            for i in range(n):
                x[i] = V[_V_X0, i]
                V[_V_MU, i] = V[_V_MU0, i]
            _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(True))
            return OK, count
        side = 1 if V[_V_X0, i_add] > upper[i_add] else -1
        ind[_I_FIXED, i_add] = side
        V[_V_MU0, i_add] = 0.0


@njit(cache=True)
def solve_level_iterations(
    A, a, B, r, ridge, lower, upper, state, x, rank_rtol=1e-9, max_iter=30
):  # fmt: skip
    """:func:`solve_level` that also returns how many subproblems it solved: (status, count).

    A warm start from the final active set of the same problem takes one subproblem.
    """
    return _solve(A, a, B, r, float(ridge), lower, upper, state, x, float(rank_rtol), int(max_iter))


@njit(cache=True)
def solve_level(A, a, B, r, ridge, lower, upper, state, x, rank_rtol=1e-9, max_iter=30):
    """Solve one least-squares level with equalities and box bounds (see the module docstring).

    Writes the minimiser into ``x`` (n,) and the final active set into ``state`` (n,) int8
    (-1 at lower, 0 free, +1 at upper; read as the warm start). Returns OK, MAX_ITER (no
    optimal active set within ``max_iter`` subproblem solves, or the bounds and equalities have
    no common point; x is the last iterate, which meets the equalities but maybe not the
    bounds: fall back to a general QP solver), INCONSISTENT (the equalities cannot be met with
    the pinned variables, even from a cold start; x is NaN) or NUMERICAL (a singular
    subproblem, possible only with ridge = 0; x is NaN). A, a, B, r, lower, upper are not
    modified.
    """
    status, _ = _solve(
        A, a, B, r, float(ridge), lower, upper, state, x, float(rank_rtol), int(max_iter)
    )
    return status


@njit(cache=True)
def equality_multipliers(A, state, g, lam, rank_rtol=1e-9) -> bool:
    """λ with ``A_Fᵀ λ = −g_F`` on the free variables F (``state == 0``): the multipliers of
    the equalities A x = a at a point whose gradient is g, a basic solution from the pivoted
    QR of A_Fᵀ (rows found dependent get λ = 0), into ``lam`` (m). False if the system has no
    solution (residual above 1e-7·(1 + ‖g_F‖)): the point is not stationary."""
    m, n = A.shape
    size = max(m, n, _N_VEC)
    work = np.empty((2, size, max(m, n)))
    W = work[0]
    V = work[1]
    ind = np.empty((_N_IVEC, max(m, n)), dtype=np.int64)
    nf = np.int64(0)
    for j in range(n):
        if state[j] == 0:
            ind[_I_FREE, nf] = j
            nf += 1
    for row in range(m):
        ind[_I_PERM, row] = row
        for c in range(nf):
            W[row, c] = A[row, ind[_I_FREE, c]]
    k = _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol) if m > 0 and nf > 0 else 0
    norm = 0.0
    for c in range(nf):  # u = Qᵀ (−g_F), the reflectors in order
        V[_V_T, c] = -g[ind[_I_FREE, c]]
        norm += V[_V_T, c] * V[_V_T, c]
    for j in range(k):
        if V[_V_TAU, j] != 0.0:
            _reflect_vector(W, j, nf, V[_V_TAU, j], V, _V_T)
    miss = 0.0
    for c in range(k, nf):
        miss += V[_V_T, c] * V[_V_T, c]
    if np.sqrt(miss) > 1e-7 * (1.0 + np.sqrt(norm)):
        return False
    for j in range(k - 1, -1, -1):  # R11 λ'' = u[:k]
        s = V[_V_T, j]
        for row in range(j + 1, k):
            s -= W[row, j] * V[_V_LAM, row]
        V[_V_LAM, j] = s / W[j, j]
    for i in range(m):
        lam[i] = 0.0
    for j in range(k):
        lam[ind[_I_PERM, j]] = V[_V_LAM, j]
    return True
