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
  formed: ``(B_F Q)ᵀ = Qᵀ B_Fᵀ`` comes from the compact WY form of the reflectors (BLAS);
* multipliers ``A_Fᵀ λ = −g_F`` (g the gradient, same QR) and the bounds' reduced gradients
  ``μ_X = g_X + A_Xᵀ λ``: a variable at its upper bound is optimal iff μ ≤ 0, at its lower
  bound iff μ ≥ 0.

The active set is first updated by the primal-dual active set method (PDAS,
Hintermüller–Ito–Kunisch; block principal pivoting): a free variable beyond a bound is fixed at
it and a fixed one with the wrong multiplier sign is released, all at once. PDAS converges in a
few steps when the reduced Hessian is close to an M-matrix but can cycle otherwise (typically
p < d with a small ridge). When the number of infeasibilities stops falling, or an exchange makes
the equalities inconsistent, the solver switches to a dual active set method (Goldfarb–Idnani
on the bounds): from the current set less its wrong-signed bounds (a dual feasible point) it
adds the most violated bound, moving along the subproblem's solution, which is affine in the
value the added variable is held at, and releasing a bound whose multiplier reaches zero on the
way; when the added bound depends on the active ones and the equalities, a pure dual step
releases one of those instead. Each completed addition strictly raises the dual objective of a
strictly convex problem, so the method is finite.

``state`` is an int8 array (any integer dtype compiles too): -1 = at the lower bound, 0 = free,
+1 = at the upper bound. It is the warm start on input and the final active set on output; a
value pointing at an infinite bound counts as 0. Pinned variables (lower == upper) are always
fixed and reported as -1 or +1 after the sign of their multiplier.

Tolerances: the equalities are inconsistent when the dependent rows miss by more than
1e-9·(1 + ‖a‖ + ‖A_X x_X‖); a free variable is beyond a bound b by more than 1e-12·(1 + |b|)
(a returned solution is then clipped onto the box exactly); a multiplier has the wrong sign by
more than 1e-9 × the sum of the magnitudes of its terms.

Limits: ``max_iter`` counts subproblem solves (about 5 µs each at n = 24). From a cold start
PDAS needs 2–7 of them on well-conditioned levels; levels with p < d, a tiny ridge and many
active bounds can need 10–30 or more (that is where the dual method takes over); a warm start
from the previous tick's active set usually needs 1. With ridge = 0 the problem must be
strictly convex on the visited faces (B_F Z of full column rank): a singular normal form
returns NUMERICAL, and with p < d the row form returns the minimum-norm z, for which the
active set iteration is not guaranteed to settle (MAX_ITER). Pass float64 C-contiguous arrays:
other layouts or dtypes compile another specialisation (~10 s, cached afterwards).
"""

from __future__ import annotations

import numpy as np
from numba import njit

OK, MAX_ITER, INCONSISTENT, NUMERICAL = 0, 1, 2, 3

_X_TOL = 1e-12  # a free x_i is beyond a bound b when by more than _X_TOL·(1 + |b|)
_MU_TOL = 1e-9  # a multiplier has the wrong sign when by more than _MU_TOL × its terms' size
_EQ_TOL = 1e-9  # equalities are inconsistent when ‖residual‖ > _EQ_TOL·(1 + ‖a‖ + ‖A_X x_X‖)
_SING_TOL = 1e-13  # with ridge = 0, a Cholesky pivot ≤ _SING_TOL·max diagonal is singular
_SMALL_K = 8  # up to this rank VᵀV is formed by loops rather than BLAS

_SUB_OK, _SUB_INCONSISTENT, _SUB_SINGULAR = 0, 1, 2
_PDAS, _DUAL_START, _DUAL_ADD = 0, 1, 2

# Inner loops run over 1-d row views (numba vectorises those, not 2-d indexing; views of views
# in a loop are slow: their reference counts are not elided), and dot products allow
# reassociation so that they vectorise too; everything else is plain IEEE arithmetic.
_FAST = {"reassoc", "contract"}


@njit(cache=True, fastmath=_FAST)
def _dot(u, v, n):
    """u[:n]·v[:n] for 1-d arrays."""
    s = 0.0
    for c in range(n):
        s += u[c] * v[c]
    return s


@njit(cache=True)
def _copy(src, dst):
    """dst[:] = src (a loop: numba's slice assignment is slow on short arrays)."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@njit(cache=True)
def _fill(dst, value):
    for i in range(dst.shape[0]):
        dst[i] = value


@njit(cache=True)
def _pivoted_qr_rows(W, m, nf, tau, perm, nrm, nrm_ref, rank_rtol):
    """Householder QR with column pivoting of ``W[:m, :nf]ᵀ`` (the rows of W are the columns).

    On return rows are permuted (``perm`` follows), ``W[i, j] = R[j, i]`` for j ≤ i < m, j < k,
    and reflector j is ``I − tau[j] v vᵀ`` with ``v = (0…0, 1, W[j, j+1:nf])`` (τ = 2/‖v‖²).
    Returns the numerical rank k: the first pivot whose remaining norm is ≤ rank_rtol·|R_00|
    stops the factorisation.
    """
    kmax = min(m, nf)
    for i in range(m):
        wi = W[i]
        s = _dot(wi, wi, nf)
        nrm[i] = s
        nrm_ref[i] = s
    r00 = 0.0
    for j in range(kmax):
        piv = j
        best = nrm[j]
        for i in range(j + 1, m):
            if nrm[i] > best:
                best = nrm[i]
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
            itmp = perm[j]
            perm[j] = perm[piv]
            perm[piv] = itmp
            tmp = nrm[j]
            nrm[j] = nrm[piv]
            nrm[piv] = tmp
            tmp = nrm_ref[j]
            nrm_ref[j] = nrm_ref[piv]
            nrm_ref[piv] = tmp
        alpha = W[j, j]
        length = nf - j - 1
        vj = W[j, j + 1 : nf]  # the reflector's tail (after scaling)
        sigma = _dot(vj, vj, length)
        if sigma == 0.0:
            tau[j] = 0.0
        else:
            beta = np.sqrt(alpha * alpha + sigma)
            if alpha >= 0.0:
                beta = -beta
            inv = 1.0 / (alpha - beta)
            for c in range(length):
                vj[c] *= inv
            tj = (beta - alpha) / beta
            tau[j] = tj
            W[j, j] = beta
            for i in range(j + 1, m):
                ui = W[i, j + 1 : nf]
                s = tj * (W[i, j] + _dot(vj, ui, length))
                W[i, j] -= s
                for c in range(length):
                    ui[c] -= s * vj[c]
        for i in range(j + 1, m):  # downdate the remaining norms, recompute on cancellation
            nrm[i] -= W[i, j] * W[i, j]
            if nrm[i] <= 1.5e-8 * nrm_ref[i]:
                ui = W[i, j + 1 : nf]
                nrm[i] = _dot(ui, ui, length)
                nrm_ref[i] = nrm[i]
    return kmax


@njit(cache=True)
def _cholesky(N, dim, ridge):
    """In place N[:dim, :dim] = L Lᵀ (L in the lower triangle); False if not positive definite.

    With ridge = 0 a pivot ≤ _SING_TOL × the largest diagonal entry counts as singular.
    """
    dmax = 0.0
    for j in range(dim):
        dmax = max(dmax, N[j, j])
    for j in range(dim):  # column by column: the dots of one column are independent
        lj = N[j]
        piv = lj[j] - _dot(lj, lj, j)
        if not piv > 0.0 or (ridge == 0.0 and piv <= _SING_TOL * dmax):
            return False
        ljj = np.sqrt(piv)
        lj[j] = ljj
        inv = 1.0 / ljj
        for i in range(j + 1, dim):
            li = N[i]
            li[j] = (li[j] - _dot(li, lj, j)) * inv
    return True


@njit(cache=True)
def _cholesky_solve(N, dim, b):
    """Solve L Lᵀ w = b in place (L from :func:`_cholesky`)."""
    for i in range(dim):
        li = N[i]
        b[i] = (b[i] - _dot(li, b, i)) / li[i]
    for j in range(dim - 1, -1, -1):
        lj = N[j]
        f = b[j] / lj[j]
        b[j] = f
        for i in range(j):
            b[i] -= f * lj[i]


@njit(cache=True)
def _subproblem(A, a, B, r, ridge, lower, upper, fixed, x, mu, mu_tol, rank_rtol, ws):
    """Solve the equality-constrained subproblem for the fixed set ``fixed`` (-1/+1 = at bound).

    Writes x, and for fixed i the multiplier ``mu[i]`` with its tolerance ``mu_tol[i]``.
    Returns _SUB_OK, _SUB_INCONSISTENT or _SUB_SINGULAR.
    """
    W, BqT, Mbuf, fs, tau, nrm, nrm_ref, cvec, lam, rp, e, t, perm, free, fix = ws
    m, n = A.shape
    p = B.shape[0]
    nf = 0
    nx = 0
    for i in range(n):
        if fixed[i] == 0:
            free[nf] = i
            nf += 1
        else:
            x[i] = lower[i] if fixed[i] < 0 else upper[i]
            fix[nx] = i
            nx += 1
    # equalities restricted to F: A_F x_F = a − A_X x_X
    a_norm = 0.0
    ax_norm = 0.0
    for i in range(m):
        s = 0.0
        for c in range(nx):
            s += A[i, fix[c]] * x[fix[c]]
        cvec[i] = a[i] - s
        a_norm += a[i] * a[i]
        ax_norm += s * s
        perm[i] = i
        wi = W[i]
        ai = A[i]
        for c in range(nf):
            wi[c] = ai[free[c]]
    k = _pivoted_qr_rows(W, m, nf, tau, perm, nrm, nrm_ref, rank_rtol)
    # y₀ from R11ᵀ y₀ = (Πᵀ c)[:k]; the dependent rows must agree
    for i in range(k):
        wi = W[i]
        t[i] = (cvec[perm[i]] - _dot(wi, t, i)) / wi[i]
    res = 0.0
    for i in range(k, m):
        d_i = cvec[perm[i]] - _dot(W[i], t, k)
        res += d_i * d_i
    if np.sqrt(res) > _EQ_TOL * (1.0 + np.sqrt(a_norm) + np.sqrt(ax_norm)):
        return _SUB_INCONSISTENT
    d = nf - k
    # (B_F Q)ᵀ = Qᵀ B_Fᵀ = B_Fᵀ − V Tᵀ Vᵀ B_Fᵀ (compact WY form of Q = H_0 ⋯ H_{k-1})
    # Mc = M (p × d, C order) is kept alongside for the BLAS products below
    Mc = Mbuf[: p * d].reshape((p, d))
    for c in range(nf):
        fc = free[c]
        bq = BqT[c]
        for i in range(p):
            bq[i] = B[i, fc]
        if k == 0:
            for i in range(p):
                Mc[i, c] = bq[i]
    if k > 0 and p > 0:
        o = 0
        Vt = fs[o : o + k * nf].reshape((k, nf))
        o += k * nf
        V = fs[o : o + nf * k].reshape((nf, k))
        o += nf * k
        S = fs[o : o + k * k].reshape((k, k))
        o += k * k
        C = fs[o : o + k * p].reshape((k, p))
        o += k * p
        BV = fs[o : o + nf * p].reshape((nf, p))
        for j in range(k):
            vj = Vt[j]
            wj = W[j]
            for c in range(j):
                vj[c] = 0.0
                V[c, j] = 0.0
            vj[j] = 1.0
            V[j, j] = 1.0
            for c in range(j + 1, nf):
                vj[c] = wj[c]
                V[c, j] = wj[c]
        # T⁻¹ = S = strict upper part of VᵀV + diag(1/τ) (the UT transform, τ_j = 2/‖v_j‖²),
        # so C' = Tᵀ Vᵀ B_Fᵀ solves Sᵀ C' = Vᵀ B_Fᵀ
        if k <= _SMALL_K:
            for i in range(k):
                for j in range(i + 1, k):
                    S[i, j] = _dot(Vt[i, j:nf], Vt[j, j:nf], nf - j)
        else:
            np.dot(Vt, V, S)
        np.dot(Vt, BqT[:nf], C)
        for j in range(k):
            cj = C[j]
            for row in range(j):
                f = S[row, j]
                cr = C[row]
                for i in range(p):
                    cj[i] -= f * cr[i]
            f = tau[j]
            for i in range(p):
                cj[i] *= f
        np.dot(V, C, BV)  # C-ordered operands: OpenBLAS is slower on transposed ones
        for c in range(nf):
            bq = BqT[c]
            bv = BV[c]
            for i in range(p):
                bq[i] -= bv[i]
            if c >= k:
                for i in range(p):
                    Mc[i, c - k] = bq[i]
    # r' = r − B x₀, x₀ = (x_X, Y y₀)
    _copy(r, rp)
    for i in range(p):
        brow = B[i]
        s = 0.0
        for c in range(nx):
            s += brow[fix[c]] * x[fix[c]]
        rp[i] -= s
    for j in range(k):
        f = t[j]
        brow = BqT[j]
        for i in range(p):
            rp[i] -= f * brow[i]
    # null-space least squares for z (stored in t[k:nf]), and the residual e = B x − r
    if d > 0 and p >= d:
        N = fs[: d * d].reshape((d, d))
        np.dot(BqT[k:nf], Mc, N)  # MᵀM (BqT[k:nf] = Mᵀ)
        z = t[k:nf]
        for c in range(d):
            N[c, c] += ridge
            z[c] = _dot(BqT[k + c], rp, p)
        if not _cholesky(N, d, ridge):
            return _SUB_SINGULAR
        _cholesky_solve(N, d, z)
        for i in range(p):  # e = M z − r'
            e[i] = -rp[i]
        for c in range(d):
            f = z[c]
            brow = BqT[k + c]
            for i in range(p):
                e[i] += f * brow[i]
    elif d > 0:
        N = fs[: p * p].reshape((p, p))
        if p > 0:
            np.dot(Mc, BqT[k:nf], N)  # M Mᵀ
        for i in range(p):
            N[i, i] += ridge
            e[i] = rp[i]
        if not _cholesky(N, p, ridge):
            return _SUB_SINGULAR
        _cholesky_solve(N, p, e)  # w = (M Mᵀ + ridge I)⁻¹ r'
        for c in range(d):
            t[k + c] = _dot(BqT[k + c], e, p)  # z = Mᵀ w
        for i in range(p):  # e = M z − r' = −ridge·w, without the cancellation
            e[i] *= -ridge
    else:
        for i in range(p):
            e[i] = -rp[i]
    # λ' (permuted, basic): R11 λ' = −(Qᵀ g_F)[:k], (Qᵀ g_F)_j = (B_F Q)_jᵀ e + ridge·y₀_j
    for j in range(k):
        lam[j] = -(_dot(BqT[j], e, p) + ridge * t[j])
    for j in range(k - 1, -1, -1):
        s = lam[j]
        for i in range(j + 1, k):
            s -= W[i, j] * lam[i]
        lam[j] = s / W[j, j]
    # x_F = Q (y₀, z): the reflectors in reverse order
    for j in range(k - 1, -1, -1):
        tj = tau[j]
        if tj == 0.0:
            continue
        vj = W[j, j + 1 : nf]
        tt = t[j + 1 : nf]
        s = tj * (t[j] + _dot(vj, tt, nf - j - 1))
        t[j] -= s
        for c in range(nf - j - 1):
            tt[c] -= s * vj[c]
    for c in range(nf):
        x[free[c]] = t[c]
    # reduced gradients of the fixed variables: μ = B_iᵀ e + ridge x_i + A_iᵀ λ
    for c in range(nx):
        i = fix[c]
        g = 0.0
        for j in range(p):
            g += B[j, i] * e[j]
        size = abs(g) + ridge * abs(x[i])
        s = g + ridge * x[i]
        for j in range(k):
            term = lam[j] * A[perm[j], i]
            s += term
            size += abs(term)
        mu[i] = s
        mu_tol[i] = _MU_TOL * size
    return _SUB_OK


@njit(cache=True)
def _dependency(A, fixed, i, rank_rtol, nu, W, tau, nrm, nrm_ref, lam, t, perm, free):
    """ν with e_i = Aᵀλ' + Σ_X ν_j e_j, for a free i whose bound depends on the active ones.

    λ' solves A_Fᵀ λ' = e_i restricted to F (basic solution from the pivoted QR of A_Fᵀ), and
    ν_j = −(Aᵀλ')_j on the fixed variables (nu is 0 elsewhere). The other arrays are work
    space (shared with :func:`_subproblem`).
    """
    m, n = A.shape
    nf = 0
    pos = -1
    for j in range(n):
        nu[j] = 0.0
        if fixed[j] == 0:
            if j == i:
                pos = nf
            free[nf] = j
            nf += 1
    for row in range(m):
        perm[row] = row
        wr = W[row]
        ar = A[row]
        for c in range(nf):
            wr[c] = ar[free[c]]
    k = _pivoted_qr_rows(W, m, nf, tau, perm, nrm, nrm_ref, rank_rtol)
    for c in range(nf):  # u = Qᵀ e_pos (reflectors in order)
        t[c] = 0.0
    t[pos] = 1.0
    for j in range(k):
        tj = tau[j]
        if tj == 0.0:
            continue
        vj = W[j, j + 1 : nf]
        tt = t[j + 1 : nf]
        s = tj * (t[j] + _dot(vj, tt, nf - j - 1))
        t[j] -= s
        for c in range(nf - j - 1):
            tt[c] -= s * vj[c]
    for j in range(k - 1, -1, -1):  # R11 λ'' = u[:k]
        s = t[j]
        for row in range(j + 1, k):
            s -= W[row, j] * lam[row]
        lam[j] = s / W[j, j]
    for j in range(n):
        if fixed[j] != 0:
            s = 0.0
            for row in range(k):
                s += lam[row] * A[perm[row], j]
            nu[j] = -s


@njit(cache=True)
def _wrong_sign(fixed, mu, mu_tol, i):
    """True when the bound multiplier of fixed variable i has the wrong sign."""
    if fixed[i] > 0:
        return mu[i] > mu_tol[i]
    return mu[i] < -mu_tol[i]


@njit(cache=True)
def _violation(x, lower, upper, i):
    """How far x_i lies beyond its box relative to 1 + |bound| (0 inside, or within _X_TOL)."""
    if x[i] > upper[i] + _X_TOL * (1.0 + abs(upper[i])):
        return (x[i] - upper[i]) / (1.0 + abs(upper[i]))
    if x[i] < lower[i] - _X_TOL * (1.0 + abs(lower[i])):
        return (lower[i] - x[i]) / (1.0 + abs(lower[i]))
    return 0.0


@njit(cache=True)
def _finish(x, lower, upper, fixed, pinned, mu, state, clip):
    """Write the active set into state; with ``clip``, put the free variables (within _X_TOL of
    the box at a solution) exactly on it. Pinned variables report the sign of their multiplier."""
    for i in range(x.shape[0]):
        if pinned[i]:
            state[i] = -1 if mu[i] >= 0.0 else 1
        else:
            state[i] = fixed[i]
            if clip and fixed[i] == 0:
                x[i] = min(max(x[i], lower[i]), upper[i])


@njit(cache=True)
def _most_violated(x, lower, upper, fixed):
    """The free variable farthest beyond its box (relative to 1 + |bound|), or -1."""
    i_add = -1
    worst = 0.0
    for i in range(x.shape[0]):
        if fixed[i] == 0:
            v = _violation(x, lower, upper, i)
            if v > worst:
                worst = v
                i_add = i
    return i_add


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
    q = min(p, n)
    size_fs = max(2 * m * n + m * m + m * p + n * p, q * q + p * n)
    fbuf = np.empty(m * n + 2 * n * p + size_fs + 5 * m + 2 * p + 6 * n)
    W = fbuf[: m * n].reshape((m, n))
    o = m * n
    Mbuf = fbuf[o : o + n * p]
    o += n * p
    BqT = fbuf[o : o + n * p].reshape((n, p))
    o += n * p
    fs = fbuf[o : o + size_fs]
    o += size_fs
    tau = fbuf[o : o + m]
    nrm = fbuf[o + m : o + 2 * m]
    nrm_ref = fbuf[o + 2 * m : o + 3 * m]
    cvec = fbuf[o + 3 * m : o + 4 * m]
    lam = fbuf[o + 4 * m : o + 5 * m]
    o += 5 * m
    rp = fbuf[o : o + p]
    e = fbuf[o + p : o + 2 * p]
    o += 2 * p
    t = fbuf[o : o + n]
    mu = fbuf[o + n : o + 2 * n]
    mu_tol = fbuf[o + 2 * n : o + 3 * n]
    x0 = fbuf[o + 3 * n : o + 4 * n]
    mu0 = fbuf[o + 4 * n : o + 5 * n]
    nu = fbuf[o + 5 * n : o + 6 * n]
    ibuf = np.empty(m + 5 * n, dtype=np.int64)
    perm = ibuf[:m]
    free = ibuf[m : m + n]
    fix = ibuf[m + n : m + 2 * n]
    fixed = ibuf[m + 2 * n : m + 3 * n]
    prev = ibuf[m + 3 * n : m + 4 * n]
    pinned = ibuf[m + 4 * n :]
    ws = (W, BqT, Mbuf, fs, tau, nrm, nrm_ref, cvec, lam, rp, e, t, perm, free, fix)
    warm = False
    for i in range(n):
        if not lower[i] <= upper[i] or lower[i] == np.inf or upper[i] == -np.inf:
            raise ValueError("solve_level: need lower <= upper, no NaN, and finite if equal")
        mu[i] = 0.0
        pinned[i] = 0
        fixed[i] = 0
        if lower[i] == upper[i]:
            pinned[i] = 1
            fixed[i] = -1
        elif state[i] > 0 and upper[i] < np.inf:
            fixed[i] = 1
            warm = True
        elif state[i] < 0 and lower[i] > -np.inf:
            fixed[i] = -1
            warm = True
    # phases: PDAS; then, if it stalls, the dual active set method (Goldfarb–Idnani on the
    # bounds), which first releases wrong-signed bounds (DUAL_START) and then adds violated
    # bounds one at a time along the path of the subproblem's solution (DUAL_ADD). One call
    # site of _subproblem keeps the compiled code (and the compile time) small.
    phase = _PDAS
    best = n + 1  # fewest PDAS infeasibilities so far
    count = 0
    i_add = -1
    side = 0
    while True:
        if count >= max_iter:
            if phase == _DUAL_ADD:  # the last point on the path meets the equalities
                _copy(x0, x)
                _copy(mu0, mu)
            _finish(x, lower, upper, fixed, pinned, mu, state, False)
            return MAX_ITER, count
        count += 1
        sub = _subproblem(A, a, B, r, ridge, lower, upper, fixed, x, mu, mu_tol, rank_rtol, ws)
        if sub == _SUB_SINGULAR:
            _fill(x, np.nan)
            return NUMERICAL, count
        if phase == _PDAS:
            if sub == _SUB_INCONSISTENT:
                if count == 1 and warm:  # retry from a cold start
                    warm = False
                    max_iter += 1
                    for i in range(n):
                        fixed[i] = -1 if pinned[i] else 0
                    continue
                if best > n:  # even the cold start is inconsistent
                    _fill(x, np.nan)
                    for i in range(n):
                        state[i] = -1 if pinned[i] else 0
                    return INCONSISTENT, count
                # the last exchange fixed too many variables: back to the previous set (which
                # was consistent), and on with the dual method
                _copy(prev, fixed)
                phase = _DUAL_START
                continue
            n_inf = 0
            for i in range(n):
                if pinned[i]:
                    continue
                if fixed[i] == 0:
                    n_inf += _violation(x, lower, upper, i) > 0.0
                else:
                    n_inf += _wrong_sign(fixed, mu, mu_tol, i)
            if n_inf == 0:
                _finish(x, lower, upper, fixed, pinned, mu, state, True)
                return OK, count
            if n_inf < best:
                best = n_inf
                _copy(fixed, prev)
                for i in range(n):
                    if pinned[i]:
                        continue
                    if fixed[i] == 0:
                        if _violation(x, lower, upper, i) > 0.0:
                            fixed[i] = 1 if x[i] > upper[i] else -1
                    elif _wrong_sign(prev, mu, mu_tol, i):
                        fixed[i] = 0
                continue
            phase = _DUAL_START  # PDAS is not making progress (it may cycle)
        if phase == _DUAL_START:
            if sub == _SUB_INCONSISTENT:  # cannot happen: only releases since a consistent set
                _finish(x, lower, upper, fixed, pinned, mu, state, False)
                return MAX_ITER, count
            released = False  # a dual feasible start: no bound with the wrong multiplier sign
            for i in range(n):
                if fixed[i] != 0 and not pinned[i] and _wrong_sign(fixed, mu, mu_tol, i):
                    fixed[i] = 0
                    released = True
            if released:
                continue
            _copy(x, x0)
            _copy(mu, mu0)
            phase = _DUAL_ADD
        elif sub == _SUB_INCONSISTENT:
            # the bound being added is a combination e_i = Aᵀλ' + Σ_X ν_j e_j of the equalities
            # and the active bounds, so x cannot move: a pure dual step instead. Raising the
            # added multiplier by s·τ (s its right sign) shifts μ_j by −s·τ·ν_j; the first
            # active bound whose multiplier reaches zero is released
            fixed[i_add] = 0
            _dependency(A, fixed, i_add, rank_rtol, nu, W, tau, nrm, nrm_ref, lam, t, perm, free)
            sgn = -side
            tau_min = np.inf
            j_drop = -1
            for j in range(n):
                if fixed[j] == 0 or pinned[j]:
                    continue
                rate = fixed[j] * sgn * nu[j]  # d(−fixed_j μ_j)/dτ
                if rate < -1e-12 * (1.0 + abs(nu[j])):
                    tj = max(-fixed[j] * mu0[j], 0.0) / -rate
                    if tj < tau_min:
                        tau_min = tj
                        j_drop = j
            if j_drop < 0:  # the bounds and the equalities have no common point
                _copy(x0, x)
                _finish(x, lower, upper, fixed, pinned, mu0, state, False)
                return MAX_ITER, count
            for j in range(n):
                if fixed[j] != 0:
                    mu0[j] -= sgn * tau_min * nu[j]
            mu0[i_add] += sgn * tau_min
            fixed[j_drop] = 0
            fixed[i_add] = side
            continue
        else:
            # x, mu solve the problem with i_add on its bound; the segment from (x0, mu0) to
            # them is the path as x_i moves to the bound. Stop where a multiplier first
            # reaches zero (the bound is released there), else take the whole step
            theta = 1.0
            j_drop = -1
            for j in range(n):
                if fixed[j] == 0 or pinned[j] or j == i_add:
                    continue
                if _wrong_sign(fixed, mu, mu_tol, j):
                    # margins of the right sign (−fixed·μ ≥ 0), at the start and at the end
                    m0 = max(-fixed[j] * mu0[j], 0.0)
                    m1 = -fixed[j] * mu[j]
                    th = m0 / (m0 - m1)
                    if th < theta:
                        theta = th
                        j_drop = j
            if j_drop >= 0:
                for j in range(n):
                    x0[j] += theta * (x[j] - x0[j])
                    mu0[j] += theta * (mu[j] - mu0[j])
                fixed[j_drop] = 0
                continue
            _copy(x, x0)
            _copy(mu, mu0)
        # (DUAL_ADD) x0, mu0 solve the current set with the right signs: add the most violated
        # bound, or stop
        i_add = _most_violated(x0, lower, upper, fixed)
        if i_add < 0:
            wrong = False  # (guards against roundoff: the dual method keeps the signs right)
            for i in range(n):
                if fixed[i] != 0 and not pinned[i] and _wrong_sign(fixed, mu0, mu_tol, i):
                    fixed[i] = 0
                    wrong = True
            if wrong:
                phase = _DUAL_START
                continue
            _copy(x0, x)
            _copy(mu0, mu)
            _finish(x, lower, upper, fixed, pinned, mu, state, True)
            return OK, count
        side = 1 if x0[i_add] > upper[i_add] else -1
        fixed[i_add] = side
        mu0[i_add] = 0.0


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
