"""Inner distance and the inner-distance shape context (Ling & Jacobs 2007).

The inner distance between two contour points is the length of the shortest path between
them that stays inside the silhouette. Here it is computed on the visibility graph of the
contour points: two points are joined when the segment between them lies inside the closed
polygon (it crosses no edge and its midpoint is inside or on the boundary), weighted by its
length; shortest paths are Dijkstra's. The inner angle at point ``i`` towards ``j`` is the
direction of the first segment of that path, measured from the contour tangent at ``i``.
Both are insensitive to articulation as long as parts bend at narrow joints.
"""

from __future__ import annotations

import numpy as np

from geoshape.contour.shape_context import contour_tangent_angles, log_polar_histograms
from geoshape.io.validate import check_contour

__all__ = ["visibility_graph", "inner_distances", "mirrored_inner_distances", "inner_distance_shape_context"]


def visibility_graph(P, *, tol: float = 1e-6) -> np.ndarray:
    """Which pairs of contour points see each other through the interior of the polygon.

    Parameters
    ----------
    P : (N, 2) array_like
        Closed simple polygon.
    tol : float
        Relative tolerance (× perimeter) for touching and on-boundary tests.

    Returns
    -------
    visible : (N, N) bool, symmetric; consecutive points are always visible.

    Notes
    -----
    O(N³) time at worst (every pair against every edge, in compiled loops that stop at the
    first crossing or the first edge near a midpoint), O(N²) memory.
    """
    from matplotlib.path import Path

    from geoshape.contour._kernels import blocked_chords, near_polygon

    P = check_contour(P)
    N = len(P)
    L = float(np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1).sum())
    eps = tol * L
    iu, ju = np.triu_indices(N, k=1)
    S0, S1 = P[iu], P[ju]  # (M, 2)
    # A chord is blocked when it properly crosses an edge not incident to its ends.
    blocked = blocked_chords(np.ascontiguousarray(P, dtype=np.float64), iu, ju, eps)
    mid = 0.5 * (S0 + S1)
    path = Path(np.vstack([P, P[:1]]), closed=True)
    ok = ~blocked
    cand = np.flatnonzero(ok)
    inside = path.contains_points(mid[cand])
    # Midpoints on the boundary itself (e.g. along a straight part) count as inside.
    rest = cand[~inside]
    on_boundary = near_polygon(np.ascontiguousarray(mid[rest]), np.ascontiguousarray(P), 2 * eps + 1e-12)
    ok[rest[~on_boundary]] = False
    vis = np.zeros((N, N), dtype=bool)
    vis[iu, ju] = ok
    vis |= vis.T
    nxt = (np.arange(N) + 1) % N
    vis[np.arange(N), nxt] = True
    vis[nxt, np.arange(N)] = True
    return vis


def inner_distances(P) -> tuple[np.ndarray, np.ndarray]:
    """Inner distances between all contour points and the first hop of each shortest path.

    Returns
    -------
    D : (N, N) float64
        Shortest-path length inside the polygon.
    first_hop : (N, N) int64
        ``first_hop[i, j]``: the point after ``i`` on the shortest path from ``i`` to ``j``
        (``j`` itself when ``j`` is visible from ``i``).

    Notes
    -----
    O(N³) for the visibility test, O(N² log N) for Dijkstra from every point.
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import shortest_path

    P = check_contour(P)
    vis = visibility_graph(P)
    E = np.linalg.norm(P[:, None, :] - P[None, :, :], axis=2)
    W = csr_matrix(np.where(vis, np.maximum(E, 1e-12), 0.0))
    D, pred = shortest_path(W, method="D", directed=False, return_predecessors=True)
    # Path j -> i ends with pred[j, i] -> i, so the first hop from i towards j is pred[j, i].
    first_hop = pred.T.copy()
    N = len(P)
    diag = np.arange(N)
    first_hop[diag, diag] = diag
    unreachable = first_hop < 0
    if unreachable.any():  # cannot happen on a closed polygon; keep the direct direction
        first_hop[unreachable] = np.broadcast_to(diag[None, :], (N, N))[unreachable]
        D = np.where(np.isfinite(D), D, E)
    return D, first_hop.astype(np.int64)


def mirrored_inner_distances(D: np.ndarray, first_hop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`inner_distances` of ``mirror_contour(P)`` from those of ``P``, re-indexed. O(N²).

    A reflection keeps every length and the visibility of every pair, so the mirror image has
    the same shortest paths; its point ``i`` is point ``σ(i) = (−i) mod N`` of ``P``
    (:func:`geoshape.geometry.contour.mirror_contour`), and ``σ`` is its own inverse.
    """
    N = len(D)
    sigma = (-np.arange(N)) % N
    return D[np.ix_(sigma, sigma)], sigma[first_hop[np.ix_(sigma, sigma)]]


def inner_distance_shape_context(P, *, n_r: int = 8, n_theta: int = 12, r_inner: float = 0.125,
                                 r_outer: float = 2.0, normalize_by: str = "mean",
                                 inner: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Inner-distance shape context of every point of a contour.

    Log-polar histograms (as :func:`geoshape.contour.shape_context.shape_context`) of
    the inner distances (normalised by their mean, as in the paper, or with
    ``normalize_by="median"`` by their median) and inner angles (first path segment, measured
    from the tangent at the point). ``inner``: the ``(D, first_hop)`` of :func:`inner_distances`
    when already known (the mirror image's: :func:`mirrored_inner_distances`).

    Returns
    -------
    H : (N, n_r·n_theta) float64, rows sum to 1.
    """
    P = check_contour(P)
    D, hop = inner_distances(P) if inner is None else inner
    direction = P[hop] - P[:, None, :]  # (N, N, 2)
    angle = np.arctan2(direction[..., 1], direction[..., 0]) - contour_tangent_angles(P)[:, None]
    return log_polar_histograms(D, angle, n_r=n_r, n_theta=n_theta, r_inner=r_inner,
                                r_outer=r_outer, normalize_by=normalize_by)
