"""Compiled (numba) kernels: the cyclic DP matcher (:mod:`geoshape.contour.matching`) and the
segment-crossing and on-boundary tests of the visibility graph
(:mod:`geoshape.contour.inner_distance`).

Imported lazily (numba takes a moment to import, and the kernels compile on first use; the
machine code is cached in ``__pycache__``). The kernels repeat the floating-point operations
of the NumPy formulations they replace exactly (same order of additions, same minima, no
fused multiply-adds), so they return the same bits: the start ranking sums each cyclic
diagonal in NumPy's pairwise order, and the DP keeps the ``cumulative minimum of
(E − skip·j), plus skip·j`` form of the row update.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _block_sum(a, lo, n):
    """``a[lo:lo + n].sum()`` for ``n ≤ 128`` in NumPy's order (8 interleaved partial sums)."""
    if n < 8:
        r = 0.0
        for t in range(n):
            r += a[lo + t]
        return r
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    t = 8
    while t < n - n % 8:
        r0 += a[lo + t]
        r1 += a[lo + t + 1]
        r2 += a[lo + t + 2]
        r3 += a[lo + t + 3]
        r4 += a[lo + t + 4]
        r5 += a[lo + t + 5]
        r6 += a[lo + t + 6]
        r7 += a[lo + t + 7]
        t += 8
    r = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while t < n:
        r += a[lo + t]
        t += 1
    return r


@numba.njit(cache=True, nogil=True)
def _pairwise_sum(a):
    """``a.sum()`` in NumPy's order: blocks of at most 128 summed by :func:`_block_sum`, then
    halves (rounded down to a multiple of 8) added pairwise. Iterative (numba's cache does not
    support recursive functions)."""
    n = a.shape[0]
    if n <= 128:
        return _block_sum(a, 0, n)
    lo_stack = np.empty(64, dtype=np.int64)
    n_stack = np.empty(64, dtype=np.int64)
    phase = np.empty(64, dtype=np.int64)
    values = np.empty(64)
    top, n_values = 0, 0
    lo_stack[0], n_stack[0], phase[0] = 0, n, 0
    while top >= 0:
        lo, m = lo_stack[top], n_stack[top]
        if m <= 128:
            values[n_values] = _block_sum(a, lo, m)
            n_values += 1
            top -= 1
            continue
        half = m // 2
        half -= half % 8
        if phase[top] == 2:  # both halves summed: combine them
            values[n_values - 2] = values[n_values - 2] + values[n_values - 1]
            n_values -= 1
            top -= 1
            continue
        child_lo, child_n = (lo, half) if phase[top] == 0 else (lo + half, m - half)
        phase[top] += 1
        top += 1
        lo_stack[top], n_stack[top], phase[top] = child_lo, child_n, 0
    return values[0]


@numba.njit(cache=True, nogil=True)
def _smallest(values, k, out):
    """Indices of the ``k`` smallest ``values`` into ``out[:k]`` (ties: lowest index). O(k·n)."""
    n = values.shape[0]
    taken = np.zeros(n, dtype=np.bool_)
    for t in range(k):
        best = -1
        for s in range(n):
            if not taken[s] and (best < 0 or values[s] < values[best]):
                best = s
        taken[best] = True
        out[t] = best


@numba.njit(cache=True, nogil=True)
def _dp_total(Cv, off, skip, jl, D):
    """Order-preserving DP cost of ``Cv (N, M)`` with its columns rotated by ``off``. O(N·M)."""
    N, M = Cv.shape
    for j in range(M + 1):
        D[j] = jl[j]
    for i in range(N):
        prev = D[0]  # D of the previous row, column j − 1
        m = (prev + skip) - jl[0]  # running minimum of E − skip·j
        D[0] = m + jl[0]
        col = off
        for j in range(1, M + 1):
            up = D[j]
            e = min(prev + Cv[i, col], up + skip) - jl[j]
            prev = up
            if e < m:
                m = e
            D[j] = m + jl[j]
            col += 1
            if col == M:
                col = 0
    return D[M]


@numba.njit(cache=True, nogil=True)
def _dp_total_two(Cv0, off0, Cv1, off1, skip, jl, D0, D1, bound):
    """:func:`_dp_total` of two starts at once: the two running minima are independent
    dependency chains, so the processor overlaps them (about 1.3x faster than one by one).

    Early abandoning: every path to the last cell crosses each row, and the costs are ≥ 0, so
    a total is at least the smallest entry of any row of ``D``. Every 8 rows, when both rows'
    smallest entries exceed ``bound`` the two starts are abandoned and those (lower bounds
    above ``bound``) are returned instead of their totals; ``bound = inf`` never abandons."""
    N, M = Cv0.shape
    for j in range(M + 1):
        D0[j] = jl[j]
        D1[j] = jl[j]
    for i in range(N):
        row0, row1 = Cv0[i], Cv1[i]
        prev0, prev1 = D0[0], D1[0]
        m0, m1 = (prev0 + skip) - jl[0], (prev1 + skip) - jl[0]
        D0[0], D1[0] = m0 + jl[0], m1 + jl[0]
        col0, col1 = off0, off1
        for j in range(1, M + 1):
            up0, up1 = D0[j], D1[j]
            e0 = min(prev0 + row0[col0], up0 + skip) - jl[j]
            e1 = min(prev1 + row1[col1], up1 + skip) - jl[j]
            prev0, prev1 = up0, up1
            m0 = e0 if e0 < m0 else m0
            m1 = e1 if e1 < m1 else m1
            D0[j], D1[j] = m0 + jl[j], m1 + jl[j]
            col0 = col0 + 1 if col0 + 1 < M else 0
            col1 = col1 + 1 if col1 + 1 < M else 0
        if bound < np.inf and i % 8 == 7 and i + 1 < N:
            r0, r1 = D0[0], D1[0]
            for j in range(1, M + 1):
                r0 = D0[j] if D0[j] < r0 else r0
                r1 = D1[j] if D1[j] < r1 else r1
            if r0 > bound and r1 > bound:
                return r0, r1
    return D0[M], D1[M]


@numba.njit(cache=True, nogil=True)
def _add_rotated(out, row, shift, assign):
    """``out[s] (+)= row[(shift + s) mod M]`` for ``s < M``, with ``0 ≤ shift ≤ M``. O(M)."""
    M = row.shape[0]
    n_first = M - shift
    if assign:
        for s in range(n_first):
            out[s] = row[shift + s]
        for s in range(n_first, M):
            out[s] = row[s - n_first]
    else:
        for s in range(n_first):
            out[s] += row[shift + s]
        for s in range(n_first, M):
            out[s] += row[s - n_first]


@numba.njit(cache=True, nogil=True)
def _diagonal_sums(Cb, base, diag, acc, cells):
    """``diag[v·M + s]``: sum of ``Cb[v, i, (base[i] + s) mod M]`` over i, in NumPy's order.

    For N ≤ 128 the 8 partial sums advance row by row (contiguous reads); otherwise each
    diagonal is gathered and summed by :func:`_pairwise_sum`. O(V·N·M).
    """
    V, N, M = Cb.shape
    if N > 128:
        for v in range(V):
            for s in range(M):
                for i in range(N):
                    col = base[i] + s
                    cells[i] = Cb[v, i, col - M if col >= M else col]
                diag[v * M + s] = _pairwise_sum(cells)
        return
    n_blocked = N - N % 8 if N >= 8 else 0
    for v in range(V):
        out = diag[v * M:(v + 1) * M]
        if n_blocked == 0:
            out[:] = 0.0
        for i in range(n_blocked):
            _add_rotated(acc[i % 8, v * M:(v + 1) * M], Cb[v, i], base[i], i < 8)
        if n_blocked > 0:
            for s in range(v * M, (v + 1) * M):
                diag[s] = ((acc[0, s] + acc[1, s]) + (acc[2, s] + acc[3, s])) + (
                    (acc[4, s] + acc[5, s]) + (acc[6, s] + acc[7, s]))
        for i in range(n_blocked, N):  # the rest is added in order
            _add_rotated(out, Cb[v, i], base[i], False)


@numba.njit(cache=True, nogil=True)
def _pair_totals(Cb, base, skip, totals, starts, jl, D, diag, acc, cells, best_only):
    """Starts and DP totals of one pair ``Cb (V, N, M)`` into ``starts (k,)``, ``totals (k,)``.

    ``best_only``: only ``totals.min()`` is wanted, so starts (tried best diagonal first) that
    cannot beat the best total so far are abandoned early (:func:`_dp_total_two`); their
    entries are then lower bounds above it, and the minimum is the same. The margin of
    ``1e-9 · skip · M`` over the best total is far above the rounding the DP can accumulate
    (a few ulps per row), so an abandoned start could not have come out smaller."""
    V, N, M = Cb.shape
    k = starts.shape[0]
    if k == V * M:
        for t in range(k):
            starts[t] = t
    else:
        _diagonal_sums(Cb, base, diag, acc, cells)
        _smallest(diag, k, starts)
    bound = np.inf
    for t in range(0, k - 1, 2):
        v0, off0 = divmod(starts[t], M)
        v1, off1 = divmod(starts[t + 1], M)
        totals[t], totals[t + 1] = _dp_total_two(Cb[v0], off0, Cb[v1], off1, skip, jl, D[0], D[1],
                                                 bound)
        if best_only:
            bound = min(bound, totals[t] + 1e-9 * jl[M], totals[t + 1] + 1e-9 * jl[M])
    if k % 2:
        v, off = divmod(starts[k - 1], M)
        totals[k - 1] = _dp_total(Cb[v], off, skip, jl, D[0])


@numba.njit(cache=True, nogil=True)
def cyclic_dp_kernel(C, base, skip, totals, starts):
    """Best cyclic starts and their DP totals for a batch of cost matrices.

    ``C (B, V, N, M)``; ``base (N,)``: column of row ``i`` on the diagonal through (0, 0),
    in ``[0, M]``; fills ``starts (B, k)`` (flat ``v·M + s``) and ``totals (B, k)``.
    O(B·(V·M·N + k·N·M)).
    """
    B, V, N, M = C.shape
    jl, D, diag, acc, cells, _ = _workspace(V, N, M, skip)
    for b in range(B):
        _pair_totals(C[b], base, skip, totals[b], starts[b], jl, D, diag, acc, cells, False)


@numba.njit(cache=True, nogil=True)
def cyclic_dp_gram_kernel(G, n1, n2, base, skip, totals, starts):
    """:func:`cyclic_dp_kernel` on squared distances given by their parts.

    ``C[b, v, i, j] = max(n1[i] + n2[b, v, j] − 2·G[b, v, j, i], 0)`` (as
    :func:`geoshape.contour.methods.signature_cost_matrices` computes it, same bits) is filled
    pair by pair into a small buffer, so no ``(B, V, N, M)`` array is made.
    ``G (B, V, M, N)``, ``n1 (N,)``, ``n2 (B, V, M)``. Only the minimum of each pair's
    ``totals`` is exact (starts abandoned early hold lower bounds above it: :func:`_pair_totals`).
    """
    B, V, M, N = G.shape
    jl, D, diag, acc, cells, Cb = _workspace(V, N, M, skip)
    for b in range(B):
        for v in range(V):
            for j in range(M):
                for i in range(N):
                    Cb[v, i, j] = max((n1[i] + n2[b, v, j]) - 2.0 * G[b, v, j, i], 0.0)
        _pair_totals(Cb, base, skip, totals[b], starts[b], jl, D, diag, acc, cells, True)


@numba.njit(cache=True, nogil=True)
def _workspace(V, N, M, skip):
    """Buffers of the per-pair kernels: skip ramp ``jl (M + 1,)``, DP rows, diagonal sums and
    one pair's ``(V, N, M)`` cost matrices."""
    jl = skip * np.arange(M + 1).astype(np.float64)
    return (jl, np.empty((2, M + 1)), np.empty(V * M), np.empty((8, V * M)), np.empty(N),
            np.empty((V, N, M)))


@numba.njit(cache=True, nogil=True, inline="always")
def _cross(o0, o1, a0, a1, b0, b1):
    return (a0 - o0) * (b1 - o1) - (a1 - o1) * (b0 - o0)


@numba.njit(cache=True, nogil=True)
def _crosses(s0, s1, t1, a0, a1, b0, b1, t2):
    """Whether segment s0 s1 and edge a b cross properly (each one's ends strictly on both
    sides of the other, with margins ``t1``/``t2``)."""
    d1 = _cross(s0[0], s0[1], s1[0], s1[1], a0, a1)
    d2 = _cross(s0[0], s0[1], s1[0], s1[1], b0, b1)
    if not ((d1 > t1 and d2 < -t1) or (d1 < -t1 and d2 > t1)):
        return False
    d3 = _cross(a0, a1, b0, b1, s0[0], s0[1])
    d4 = _cross(a0, a1, b0, b1, s1[0], s1[1])
    return (d3 > t2 and d4 < -t2) or (d3 < -t2 and d4 > t2)


@numba.njit(cache=True, nogil=True)
def blocked_chords(P, iu, ju, eps):
    """``blocked[p]``: chord ``P[iu[p]] P[ju[p]]`` crosses an edge ``P[k] P[k + 1]`` not
    incident to either end, margins ``eps`` × length. O(pairs · N), stops at the first crossing."""
    N = P.shape[0]
    blocked = np.zeros(iu.shape[0], dtype=np.bool_)
    e_len = np.empty(N)
    for k in range(N):
        k1 = k + 1 if k + 1 < N else 0
        dx, dy = P[k1, 0] - P[k, 0], P[k1, 1] - P[k, 1]
        e_len[k] = np.sqrt(dx * dx + dy * dy)
    for p in range(iu.shape[0]):
        i, j = iu[p], ju[p]
        s0, s1 = P[i], P[j]
        dx, dy = s1[0] - s0[0], s1[1] - s0[1]
        t1 = eps * np.sqrt(dx * dx + dy * dy)
        for k in range(N):
            k1 = k + 1 if k + 1 < N else 0
            if k == i or k1 == i or k == j or k1 == j:
                continue
            if _crosses(s0, s1, t1, P[k, 0], P[k, 1], P[k1, 0], P[k1, 1], eps * e_len[k]):
                blocked[p] = True
                break
    return blocked


@numba.njit(cache=True, nogil=True)
def near_polygon(X, P, tol):
    """``near[m]``: point ``X[m]`` lies within ``tol`` of an edge ``P[k] P[k + 1]`` of the closed
    polygon ``P (N, 2)``. The distance is computed as the NumPy formulation it replaces
    (projection parameter clipped to [0, 1], then the Euclidean distance to the projection).
    O(M · N), stops at the first edge close enough."""
    N = P.shape[0]
    near = np.zeros(X.shape[0], dtype=np.bool_)
    for m in range(X.shape[0]):
        x0, x1 = X[m, 0], X[m, 1]
        for k in range(N):
            k1 = k + 1 if k + 1 < N else 0
            a0, a1 = P[k, 0], P[k, 1]
            e0, e1 = P[k1, 0] - a0, P[k1, 1] - a1
            denom = max(e0 * e0 + e1 * e1, 1e-300)
            t = ((x0 - a0) * e0 + (x1 - a1) * e1) / denom
            t = min(max(t, 0.0), 1.0)
            d0, d1 = x0 - (a0 + t * e0), x1 - (a1 + t * e1)
            if np.sqrt(d0 * d0 + d1 * d1) <= tol:
                near[m] = True
                break
    return near


@numba.njit(cache=True, nogil=True)
def cyclic_dp_l1_kernel(H1, H2T, base, skip, totals, starts):
    """:func:`cyclic_dp_kernel` on city-block point costs.

    ``C[b, v, i, j] = Σ_k |H1[i, k] − H2T[b, v, k, j]|`` (summed over ``k`` in order) is filled
    pair by pair into a small buffer (no ``(B, V, N, M)`` array is made). ``H1 (N, K)``,
    ``H2T (B, V, K, M)``: points last, so each row of costs is built by contiguous passes over
    ``j`` (which the compiler vectorises). O(B·V·N·M·K) for the costs plus the matcher's
    O(B·(V·M·N + k·N·M)). Only the minimum of each pair's ``totals`` is exact, as for
    :func:`cyclic_dp_gram_kernel`.
    """
    B, V, K, M = H2T.shape
    N = H1.shape[0]
    jl, D, diag, acc, cells, Cb = _workspace(V, N, M, skip)
    for b in range(B):
        for v in range(V):
            for i in range(N):
                row = Cb[v, i]
                row[:] = 0.0
                for k in range(K):
                    a = H1[i, k]
                    h = H2T[b, v, k]
                    for j in range(M):
                        row[j] += abs(a - h[j])
        _pair_totals(Cb, base, skip, totals[b], starts[b], jl, D, diag, acc, cells, True)
