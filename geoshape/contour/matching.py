"""Matching two contours from point descriptors: best match, proximity heuristic, Hungarian, DP.

Every matcher takes a batch of point-to-point cost matrices ``C (B, N, M)`` (cost of
matching point i of contour 1 with point j of contour 2) and returns one cost per pair;
the single-pair versions also return the map ``p2p_12 (N,)``. Batching is what makes the
all-pairs retrieval matrix fast: one NumPy operation serves hundreds of pairs.

Matchers
--------
``best``
    ``match(i) = argmin_j C[i, j]`` (thesis eq. 3.2); cost = mean over i of the minimum.
``proximity``
    The thesis' guiding heuristic (section 3.1.3): two anchor pairs, then
    ``C + c1·(d¹₁(i) − d¹₂(j))² + c2·(d²₁(i) − d²₂(j))²`` and best match on that; ``d`` is the
    distance along the contour from the anchor, divided by the perimeter.
``hungarian``
    One-to-one assignment of minimum total cost (``scipy.optimize.linear_sum_assignment``).
``dp``
    Order-preserving cyclic matching by dynamic programming, as used with the inner-distance
    shape context: points may be left unmatched at a fixed cost ``skip_cost`` each. The cyclic
    start is searched over the ``n_starts`` most promising offsets (ranked by the summed cost
    along each cyclic diagonal); each start costs one O(N·M) DP, in compiled loops (numba).

All costs are per point (divided by N, or by (N + M)/2 for ``dp``), so values of different
pairs compare directly.
"""

from __future__ import annotations

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError

__all__ = [
    "MATCHERS",
    "best_match",
    "proximity_anchors",
    "proximity_match",
    "hungarian_match",
    "cyclic_dp_match",
    "cyclic_dp_variants",
    "cyclic_dp_gram_costs",
    "cyclic_dp_l1_costs",
    "batch_match_costs",
]

MATCHERS = ("best", "proximity", "hungarian", "dp")


def _as_batch(C) -> tuple[np.ndarray, bool]:
    C = np.asarray(C, dtype=np.float64)
    if C.ndim == 2:
        return C[None], True
    if C.ndim != 3:
        raise InvalidOptionError(f"cost matrices must have shape (N, M) or (B, N, M), got {C.shape}")
    return C, False


def best_match(C) -> tuple[np.ndarray, np.ndarray]:
    """Best match of every point: ``p2p_12 (…, N)`` and the per-point mean cost ``(…,)``. O(N·M)."""
    C, single = _as_batch(C)
    p2p = C.argmin(axis=2)
    cost = C.min(axis=2).mean(axis=1)
    return (p2p[0], cost[0]) if single else (p2p, cost)


def _cyclic_dist(s: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Distance along a unit-perimeter cycle between positions ``s (B, N)`` and anchors ``a (B,)``."""
    d = np.abs(s - a[:, None])
    return np.minimum(d, 1.0 - d)


def proximity_anchors(C, s1, s2):
    """The two anchor pairs of the proximity heuristic.

    Parameters
    ----------
    C : (N, M) or (B, N, M) array
        Descriptor dissimilarities ``A_S``.
    s1 : (N,) or (B, N) array
        Arc-length position of each point of contour 1 divided by its perimeter (in [0, 1)).
    s2 : (M,) or (B, M) array
        Same for contour 2.

    Returns
    -------
    anchors : (2, 2) int or (B, 2, 2) int
        ``anchors[k] = (i, j)``: k-th anchor pair. The first is the global minimum of ``C``;
        the second minimises ``C / mean(C) − ½(d1(i) + d2(j)) / mean(½(d1 + d2))``, where
        ``d`` is the distance along the contour from the first anchor (both terms scaled to
        mean 1, so neither dominates).
    d1, d2 : distances from the anchors, shapes ``(…, 2, N)`` and ``(…, 2, M)``.
    """
    C, single = _as_batch(C)
    B, N, M = C.shape
    s1 = np.broadcast_to(np.asarray(s1, dtype=np.float64), (B, N))
    s2 = np.broadcast_to(np.asarray(s2, dtype=np.float64), (B, M))
    flat = C.reshape(B, -1).argmin(axis=1)
    i1, j1 = np.divmod(flat, M)
    rows = np.arange(B)
    d11, d21 = _cyclic_dist(s1, s1[rows, i1]), _cyclic_dist(s2, s2[rows, j1])
    pen = 0.5 * (d11[:, :, None] + d21[:, None, :])
    c_scale = np.maximum(C.mean(axis=(1, 2)), 1e-300)[:, None, None]
    p_scale = np.maximum(pen.mean(axis=(1, 2)), 1e-300)[:, None, None]
    flat2 = (C / c_scale - pen / p_scale).reshape(B, -1).argmin(axis=1)
    i2, j2 = np.divmod(flat2, M)
    d12, d22 = _cyclic_dist(s1, s1[rows, i2]), _cyclic_dist(s2, s2[rows, j2])
    anchors = np.stack([np.stack([i1, j1], 1), np.stack([i2, j2], 1)], 1)
    d1 = np.stack([d11, d12], 1)
    d2 = np.stack([d21, d22], 1)
    if single:
        return anchors[0], d1[0], d2[0]
    return anchors, d1, d2


def proximity_match(C, s1, s2, *, c1: float = 1.0, c2: float = 1.0):
    """Best match under the proximity heuristic (thesis eqs. 3.5–3.6).

    ``C_new = C + c1·(d¹₁(i) − d¹₂(j))² + c2·(d²₁(i) − d²₂(j))²`` with distances in units of the
    perimeter (so ``(d₁ − d₂)² ≤ ¼``). Returns ``p2p_12`` and the per-point cost of
    ``C_new`` at the matches (SimCost / N), batched like :func:`best_match`. O(N·M).
    """
    C, single = _as_batch(C)
    _, d1, d2 = proximity_anchors(C, s1, s2)
    C_new = C + c1 * (d1[:, 0, :, None] - d2[:, 0, None, :]) ** 2 \
        + c2 * (d1[:, 1, :, None] - d2[:, 1, None, :]) ** 2
    p2p, cost = best_match(C_new)
    return (p2p[0], cost[0]) if single else (p2p, cost)


def hungarian_match(C) -> tuple[np.ndarray, float]:
    """Minimum-cost one-to-one assignment of one pair; ``p2p_12 (N,)`` and mean cost.

    With ``N > M`` the unassigned rows take their best match (and do not count in the cost).
    O(N³) (``scipy.optimize.linear_sum_assignment``).
    """
    from scipy.optimize import linear_sum_assignment

    C = np.asarray(C, dtype=np.float64)
    rows, cols = linear_sum_assignment(C)
    p2p = C.argmin(axis=1)
    p2p[rows] = cols
    return p2p, float(C[rows, cols].mean())


def cyclic_dp_match(C, *, skip_cost: float = 0.3, n_starts: int = 4, return_map: bool = True):
    """Order-preserving cyclic matching by dynamic programming.

    Parameters
    ----------
    C : (N, M) or (B, N, M) array
        Point-to-point costs; both contours run in the same (counter-clockwise) direction.
    skip_cost : float
        Cost of leaving one point (of either contour) unmatched.
    n_starts : int
        Cyclic offsets tried per pair (the best diagonals); ``M`` tries them all (exact).
    return_map : bool
        Backtrack and return ``p2p_12`` (single pair only).

    Returns
    -------
    p2p_12 : (N,) int (single pair, ``return_map``), unmatched points take the partner of
        the previous matched point.
    cost : float or (B,) array
        Minimum total cost divided by ``(N + M) / 2``.

    Notes
    -----
    O(n_starts·N·M) time per pair (compiled, see :func:`cyclic_dp_variants`), O(B·n_starts)
    memory beyond the input; the map's backtracking is O(N·M) Python steps.
    """
    C, single = _as_batch(C)
    B, N, M = C.shape
    totals, starts = cyclic_dp_variants(C[:, None], skip_cost=skip_cost, n_starts=n_starts)
    best = totals.argmin(axis=1)
    cost = totals[np.arange(B), best] / ((N + M) / 2.0)
    if not (single and return_map):
        return cost[0] if single else cost
    s = int(starts[0, best[0]])
    p2p = _dp_backtrack(np.roll(C[0], -s, axis=1), skip_cost)
    p2p = (p2p + s) % M
    return p2p, float(cost[0])


def cyclic_dp_variants(C: np.ndarray, *, skip_cost: float = 0.3, n_starts: int = 4):
    """DP totals for the best starts over several variants of each pair.

    Parameters
    ----------
    C : (B, V, N, M) array
        ``V`` cost matrices per pair (e.g. against a shape and against its mirror image).
    skip_cost, n_starts : as in :func:`cyclic_dp_match`; ``n_starts`` counts over all variants.

    Returns
    -------
    totals : (B, k) float64
        Un-normalised DP cost of each tried start.
    starts : (B, k) int64
        Flat start ``v·M + s`` (variant ``v``, offset ``s``): point 0 of contour 1 with point
        ``s`` of variant ``v``. The ``k = min(n_starts, V·M)`` starts with the smallest summed
        cost along the cyclic diagonal through them (all starts when ``k = V·M``).

    Notes
    -----
    Compiled loops (:mod:`geoshape.contour._kernels`, numba): O(B·(V·M·N + k·N·M)) time,
    O(M) memory beyond the input; about 15–25 µs per 100 × 100 start on one core.
    """
    from geoshape.contour._kernels import cyclic_dp_kernel

    _check_dp_options(skip_cost, n_starts)
    C = np.ascontiguousarray(C, dtype=np.float64)
    B, V, N, M = C.shape
    k = min(n_starts, V * M)
    totals = np.empty((B, k))
    starts = np.empty((B, k), dtype=np.int64)
    cyclic_dp_kernel(C, _diagonal_base(N, M), float(skip_cost), totals, starts)
    return totals, starts


def cyclic_dp_gram_costs(G: np.ndarray, n1: np.ndarray, n2: np.ndarray, *, skip_cost: float = 0.3,
                         n_starts: int = 4) -> np.ndarray:
    """Per-pair DP costs ``(B,)`` for squared-distance cost matrices given by their parts.

    ``C[b, v, i, j] = max(n1[i] + n2[b, v, j] − 2·G[b, v, j, i], 0)`` with ``G (B, V, M, N)``,
    ``n1 (N,)``, ``n2 (B, V, M)``: the same values as ``batch_match_costs(C, "dp", …)``, bit for
    bit, without storing the ``(B, V, N, M)`` cost matrices (each is built in a small buffer
    by the compiled kernel). O(B·(V·M·N + n_starts·N·M)). ``G`` may be single precision
    (kept as is: the cheap first pass of the coarse-to-fine retrieval search); everything
    else is double.
    """
    from geoshape.contour._kernels import cyclic_dp_gram_kernel

    _check_dp_options(skip_cost, n_starts)
    G = np.asarray(G)
    G = np.ascontiguousarray(G, dtype=np.float32 if G.dtype == np.float32 else np.float64)
    B, V, M, N = G.shape
    inputs = (G, np.ascontiguousarray(n1, dtype=np.float64), np.ascontiguousarray(n2, dtype=np.float64))
    return _best_costs(cyclic_dp_gram_kernel, inputs, (B, V, N, M), skip_cost, n_starts)


def cyclic_dp_l1_costs(H1: np.ndarray, H2T: np.ndarray, *, skip_cost: float,
                       n_starts: int) -> np.ndarray:
    """Per-pair DP costs ``(B,)`` for city-block point costs ``Σ_k |H1[i, k] − H2T[b, v, k, j]|``.

    ``H1 (N, K)``, ``H2T (B, V, K, M)``: the other shapes' descriptors with the points last
    (``V`` variants of each shape, e.g. it and its mirror image; ``n_starts`` counts over all
    of them). The same values as
    ``batch_match_costs(C, "dp", …)`` on those cost matrices, which are never stored (each is
    built in a small buffer by the compiled kernel). O(B·V·N·M·K + B·n_starts·N·M).
    """
    from geoshape.contour._kernels import cyclic_dp_l1_kernel

    _check_dp_options(skip_cost, n_starts)
    H1 = np.ascontiguousarray(H1, dtype=np.float64)
    H2T = np.ascontiguousarray(H2T, dtype=np.float64)
    B, V, _, M = H2T.shape
    return _best_costs(cyclic_dp_l1_kernel, (H1, H2T), (B, V, len(H1), M), skip_cost, n_starts)


def _best_costs(kernel, inputs: tuple, shape: tuple, skip_cost: float, n_starts: int) -> np.ndarray:
    """Run a per-pair compiled DP ``kernel(*inputs, base, skip, totals, starts)`` on a batch of
    ``shape = (B, V, N, M)`` and return each pair's best total divided by ``(N + M) / 2``."""
    B, V, N, M = shape
    k = min(n_starts, V * M)
    totals = np.empty((B, k))
    starts = np.empty((B, k), dtype=np.int64)
    kernel(*inputs, _diagonal_base(N, M), float(skip_cost), totals, starts)
    return totals.min(axis=1) / ((N + M) / 2.0)


def _check_dp_options(skip_cost: float, n_starts: int) -> None:
    if not skip_cost > 0 or n_starts < 1:
        raise InvalidOptionError(f"need skip_cost > 0 and n_starts ≥ 1, got {skip_cost}, {n_starts}")


def _diagonal_base(N: int, M: int) -> np.ndarray:
    """Column of row ``i`` on the cyclic diagonal through (0, 0): ``round(i·M/N)``, ``(N,)``."""
    return np.round(np.arange(N) * M / N).astype(np.int64)


def _dp_backtrack(Cr: np.ndarray, skip: float) -> np.ndarray:
    N, M = Cr.shape
    D = np.empty((N + 1, M + 1))
    D[0] = skip * np.arange(M + 1)
    D[:, 0] = skip * np.arange(N + 1)
    for i in range(1, N + 1):
        for j in range(1, M + 1):
            D[i, j] = min(D[i - 1, j - 1] + Cr[i - 1, j - 1], D[i - 1, j] + skip, D[i, j - 1] + skip)
    p2p = np.full(N, -1, dtype=np.int64)
    i, j = N, M
    while i > 0 and j > 0:
        if np.isclose(D[i, j], D[i - 1, j - 1] + Cr[i - 1, j - 1]):
            p2p[i - 1] = j - 1
            i, j = i - 1, j - 1
        elif np.isclose(D[i, j], D[i - 1, j] + skip):
            i -= 1
        else:
            j -= 1
    # Unmatched points follow the previous matched partner (cyclically).
    if (p2p < 0).all():
        return Cr.argmin(axis=1)
    last = p2p[np.flatnonzero(p2p >= 0)[-1]]
    for i in range(N):
        if p2p[i] < 0:
            p2p[i] = last
        last = p2p[i]
    return p2p


def batch_match_costs(C, matcher: str, *, s1=None, s2=None, symmetric: bool = True,
                      **options) -> np.ndarray:
    """Per-pair costs ``(B,)`` of a batch of cost matrices ``(B, N, M)`` with one matcher.

    ``C`` may also be ``(B, V, N, M)``: ``V`` variants per pair (and ``s2 (B, V, M)``); the
    cost of a pair is then its best variant (for ``dp`` the start search runs over all
    variants at once, so a variant costs one cost matrix, not one more DP).

    ``best`` and ``proximity`` are not symmetric; with ``symmetric`` the cost is the average
    of both directions (the retrieval distance). ``hungarian`` and ``dp`` are symmetric by
    construction (up to ties and the start search). ``s1 (B, N)``/``s2 (B, M)`` are the
    arc-length positions needed by ``proximity``.
    """
    check_choice("matcher", matcher, MATCHERS)
    C = np.asarray(C, dtype=np.float64)
    if C.ndim == 4 and matcher != "dp":
        # Variants (e.g. mirror images): the best variant of each pair.
        return np.stack([batch_match_costs(C[:, v], matcher, s1=s1,
                                           s2=None if s2 is None else s2[:, v],
                                           symmetric=symmetric, **options)
                         for v in range(C.shape[1])]).min(axis=0)
    if C.ndim == 2:
        C = C[None]
    if matcher == "best":
        cost = best_match(C)[1]
        return 0.5 * (cost + best_match(C.transpose(0, 2, 1))[1]) if symmetric else cost
    if matcher == "proximity":
        c1, c2 = options.get("c1", 1.0), options.get("c2", 1.0)
        cost = proximity_match(C, s1, s2, c1=c1, c2=c2)[1]
        if symmetric:
            back = proximity_match(C.transpose(0, 2, 1), s2, s1, c1=c1, c2=c2)[1]
            cost = 0.5 * (cost + back)
        return cost
    if matcher == "hungarian":
        return np.array([hungarian_match(c)[1] for c in C])
    if C.ndim == 3:
        C = C[:, None]
    totals, _ = cyclic_dp_variants(C, skip_cost=options.get("skip_cost", 0.3),
                                   n_starts=options.get("n_starts", 4))
    N, M = C.shape[2:]
    return totals.min(axis=1) / ((N + M) / 2.0)
