"""Compiled (numba) kernels of the point-set primitives: farthest-point sampling in
Euclidean space (:func:`geoshape.geometry.sampling.euclidean_farthest_point_sampling`) and
the best-match costs of every sign vector of one column order
(:mod:`geoshape.correspondence.reorder`).

Imported lazily (numba takes a moment to import; machine code is cached in
``__pycache__``). Each kernel fuses what NumPy does in several passes over temporaries
into one loop, so it runs in cache: the arithmetic is the same up to the order of a few
additions (a near-tie may break the other way).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def farthest_point_order(X, first, n_samples):
    """Max-min order of the rows of ``X (m, k)`` starting at row ``first``: ``n_samples``
    indices, each next the row farthest from all chosen (first of equals on ties).

    O(m · n_samples · k) time, O(m) memory.
    """
    m, k = X.shape
    d = np.full(m, np.inf)
    out = np.empty(n_samples, np.int64)
    j = first
    for a in range(n_samples):
        out[a] = j
        best, nxt = -1.0, 0
        for i in range(m):
            s = 0.0
            for c in range(k):
                t = X[i, c] - X[j, c]
                s += t * t
            if s < d[i]:
                d[i] = s
            if d[i] > best:
                best, nxt = d[i], i
        j = nxt
    return out


@numba.njit(cache=True, nogil=True)
def _row_sq_norms(X):
    """``(X * X).sum(axis=1)``, summed in column order."""
    out = np.empty(X.shape[0])
    for i in range(X.shape[0]):
        s = 0.0
        for c in range(X.shape[1]):
            s += X[i, c] * X[i, c]
        out[i] = s
    return out


@numba.njit(cache=True, nogil=True)
def signed_match_costs(A, Bp):
    """``Σ_i min_j ‖A_i − s ∘ Bp_j‖`` for every sign vector ``s`` of
    ``itertools.product((1, -1), repeat=k)``, in that order: ``(2^k,)``.

    Per point pair the ``2^(k−1)`` signed sums ``Σ_c s_c A_ic Bp_jc`` with ``s_0 = +1`` are
    grown as a binary tree of prefix sums (each level adds ``±`` the next product to every
    sum so far: ``2^k`` additions instead of ``k 2^(k−1)`` multiply-adds, in the same order
    as a plain loop over ``c``), and each sum also gives the cost of the negated vector.
    O(n1 n2 2^k) time, O(n1 2^k) memory.
    """
    n1, k = A.shape
    n2 = Bp.shape[0]
    h = 1 << (k - 1)
    a2, b2 = _row_sq_norms(A), _row_sq_norms(Bp)
    best = np.full((n1, 2 * h), np.inf)
    prod = np.empty(k)
    sums = np.empty(h)
    for i in range(n1):
        row = best[i]
        for j in range(n2):
            base = a2[i] + b2[j]
            for c in range(k):
                prod[c] = A[i, c] * Bp[j, c]
            sums[0] = 0.0 + prod[0]
            width = 1
            for c in range(1, k):  # children of sum t: 2t (+ prod[c]) and 2t + 1 (− prod[c])
                for t in range(width - 1, -1, -1):
                    v = sums[t]
                    sums[2 * t] = v + prod[c]
                    sums[2 * t + 1] = v - prod[c]
                width *= 2
            for t in range(h):
                plus = base - 2.0 * sums[t]
                minus = base + 2.0 * sums[t]
                if plus < row[t]:
                    row[t] = plus
                if minus < row[2 * h - 1 - t]:  # −s sits at the mirrored position of the table
                    row[2 * h - 1 - t] = minus
    out = np.zeros(2 * h)
    for t in range(2 * h):
        s = 0.0
        for i in range(n1):
            s += np.sqrt(max(best[i, t], 0.0))
        out[t] = s
    return out


@numba.njit(cache=True, nogil=True)
def _squared_distances(x, points, rows, out):
    """``out[t] = Σ_a (points[rows[t], a] − x[a])²`` for ``x (k,)``, ``points (n, k)`` and the
    ``len(rows)`` indices ``rows``, each summed in coordinate order. Four rows are summed
    side by side: each sum is a chain of dependent additions, and four independent chains
    keep the adder busy (about twice as fast on the pipeline's read-offs,
    docs/correspondence3d.md) while every sum stays that of one row alone. O(len(rows) k)."""
    m = len(rows)
    m4 = m - m % 4
    for t in range(0, m4, 4):
        j0, j1, j2, j3 = rows[t], rows[t + 1], rows[t + 2], rows[t + 3]
        s0 = s1 = s2 = s3 = 0.0
        for a in range(len(x)):
            d0 = points[j0, a] - x[a]
            d1 = points[j1, a] - x[a]
            d2 = points[j2, a] - x[a]
            d3 = points[j3, a] - x[a]
            s0 += d0 * d0
            s1 += d1 * d1
            s2 += d2 * d2
            s3 += d3 * d3
        out[t], out[t + 1], out[t + 2], out[t + 3] = s0, s1, s2, s3
    for t in range(m4, m):
        s = 0.0
        for a in range(len(x)):
            d = points[rows[t], a] - x[a]
            s += d * d
        out[t] = s


@numba.njit(cache=True, nogil=True)
def nearest_among_candidates(queries, points, candidates):
    """For each row ``i`` of ``queries (q, k)``, the entry of ``candidates[i] (q, c)`` whose
    row of ``points (n, k)`` is nearest (the first of equals): ``(q,)`` int64.

    O(q c k) time, O(c) memory (NumPy would gather a ``(q, c, k)`` block first); the
    distances of :func:`_squared_distances`.
    """
    q, c = candidates.shape
    out = np.empty(q, np.int64)
    s = np.empty(c)
    for i in range(q):
        _squared_distances(queries[i], points, candidates[i], s)
        best, arg = np.inf, candidates[i, 0]
        for t in range(c):
            if s[t] < best:
                best, arg = s[t], candidates[i, t]
        out[i] = arg
    return out


@numba.njit(cache=True, nogil=True)
def soft_nearest_in_rows(queries, points, indptr, indices, rows, positions, temperature):
    """For each row ``i`` of ``queries (q, k)`` and its candidates, the entries of row
    ``rows[i]`` of a csr pattern (``indptr``, ``indices``; e.g. the ring around a current
    image): the mean of the candidates' ``positions (n, d)``, each weighted
    ``exp(-(s_t − s_min) / (temperature · s_min))`` where ``s_t`` is the squared distance from
    the query to the candidate's row of ``points (n, k)`` and ``s_min`` the smallest; then the
    candidate whose position is nearest that mean (the first of equals): ``(q,)`` int64. A
    query at distance 0 from a candidate takes it. The temperature is relative to ``s_min``,
    so the weights have no unit.

    O(q c (k + d)) time for rows of c entries, O(c) memory per query.
    """
    q = queries.shape[0]
    dim = positions.shape[1]
    out = np.empty(q, np.int64)
    longest = 0
    for r in range(len(indptr) - 1):
        longest = max(longest, indptr[r + 1] - indptr[r])
    s = np.empty(longest)
    mean = np.empty(dim)
    for i in range(q):
        lo, hi = indptr[rows[i]], indptr[rows[i] + 1]
        _squared_distances(queries[i], points, indices[lo:hi], s)
        s_min, arg = np.inf, rows[i]
        for t in range(lo, hi):
            if s[t - lo] < s_min:
                s_min, arg = s[t - lo], indices[t]
        spread = temperature * s_min
        if not spread > 0.0:  # a query on a candidate, or a temperature too small to divide by
            out[i] = arg
            continue
        scale = 1.0 / spread
        total = 0.0
        mean[:] = 0.0
        for t in range(lo, hi):
            w = np.exp(-(s[t - lo] - s_min) * scale)
            total += w
            j = indices[t]
            for a in range(dim):
                mean[a] += w * positions[j, a]
        best = np.inf
        for t in range(lo, hi):
            j = indices[t]
            acc = 0.0
            for a in range(dim):
                d = positions[j, a] - mean[a] / total
                acc += d * d
            if acc < best:
                best, arg = acc, j
        out[i] = arg
    return out
