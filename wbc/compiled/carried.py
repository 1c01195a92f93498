"""The damped last level's working rows kept at a tick's end and found again by value at the
next (:mod:`wbc.solvers.carry`): :func:`keep_rows`, :func:`carry_rows`."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def keep_rows(G, h, p, working, Gc, hc) -> int:
    """The rows of G[:p], h[:p] in ``working`` into Gc, hc (the damped last level's working
    set at the end of a tick, for the next: :func:`carry_rows`); returns their number (0 if
    Gc cannot hold them)."""
    n = 0
    for i in range(p):
        if working[i]:
            if n == Gc.shape[0]:
                return 0
            Gc[n] = G[i]
            hc[n] = h[i]
            n += 1
    return n


@njit(cache=True)
def carry_rows(Gc, hc, n, G, h, p, working, tol) -> int:
    """Each of the ``n`` rows kept (:func:`keep_rows`) into ``working`` (p bools) as the row
    of G[:p], h[:p] nearest to it, if within ``tol``: ‖G_i − G_c‖ + |h_i − h_c| <=
    tol (‖G_c‖ + |h_c|) — the same row a tick later, found by its values (a self-collision
    pair's row changes its index as pairs come and go, its G and h little in a tick).
    Returns how many rows it marked."""
    marked = 0
    for c in range(n):
        size = abs(hc[c])
        s = 0.0
        for j in range(Gc.shape[1]):
            s += Gc[c, j] * Gc[c, j]
        size += math.sqrt(s)
        best = -1
        nearest = tol * size
        for i in range(p):
            s = 0.0
            for j in range(Gc.shape[1]):
                d = G[i, j] - Gc[c, j]
                s += d * d
            d = math.sqrt(s) + abs(h[i] - hc[c])
            if d <= nearest:
                nearest = d
                best = i
        if best >= 0 and not working[best]:
            working[best] = True
            marked += 1
    return marked
