"""Farthest-point ("max-min") sampling, in geodesic distance on a mesh (thesis App. B) or in
Euclidean distance between points.

Each new sample is the vertex whose geodesic distance to the nearest chosen sample is
largest. The first sample is found by a few farthest-point jumps from a seeded random
vertex, which places it near an extremity of the shape. The distance rows computed on the
way are returned, so the Nyström embedding gets its ``l x n`` block for free.
:func:`euclidean_farthest_point_sampling` does the same for the rows of any point array
(e.g. a spectral embedding) with straight-line distances.
"""

from __future__ import annotations

import numpy as np

from geoshape.errors import InvalidOptionError
from geoshape.io.interop import mesh_input

__all__ = ["farthest_point_sampling", "geodesic_voronoi_sampling", "euclidean_farthest_point_sampling"]


@mesh_input
def farthest_point_sampling(V, F, n_samples: int, *, method: str = "graph", p: int = 1,
                            seed: int = 0, n_jumps: int = 3, solver=None,
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Max-min sampling of ``n_samples`` vertices, with their geodesic distance rows.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    n_samples : int
        Number of samples ``l``, ``1 <= l <= n``.
    method : {"graph", "heat", "exact"}
        Geodesic backend (ignored when ``solver`` is given).
    p : int
        EMSTs of the structural graph.
    seed : int
        Seed of the random starting vertex.
    n_jumps : int
        Farthest-point jumps from the random vertex before the first sample is taken
        (0: the random vertex itself is the first sample).
    solver : GeodesicSolver, optional
        A solver already built for ``(V, F)``; reused as is.

    Returns
    -------
    samples : (l,) int64
        Vertex indices, in the order chosen; all distinct.
    D : (l, n) float64
        ``D[i]`` holds the geodesic distances from ``samples[i]`` to every vertex.

    Examples
    --------
    >>> import trimesh
    >>> m = trimesh.creation.icosphere(2)
    >>> samples, D = farthest_point_sampling(m.vertices, m.faces, 4)
    >>> D.shape, len(set(samples.tolist()))
    ((4, 162), 4)

    Notes
    -----
    ``l + n_jumps`` single-source geodesic runs: O((l + n_jumps) n log n) with the
    ``graph`` backend; memory O(l n).
    """
    from geoshape.geometry.geodesics import GeodesicSolver

    if solver is None:
        solver = GeodesicSolver(V, F, method, p=p)
    n = solver.n
    if not isinstance(n_samples, (int, np.integer)) or not 1 <= n_samples <= n:
        raise InvalidOptionError(
            f"n_samples must be an integer in [1, {n}] (the number of vertices), got {n_samples!r}"
        )
    if n_jumps < 0:
        raise InvalidOptionError(f"n_jumps must be >= 0, got {n_jumps}")
    rng = np.random.default_rng(seed)
    start = int(rng.integers(n))
    row = None
    for _ in range(n_jumps):
        row = solver.distances([start])[0]
        start = int(np.argmax(np.where(np.isfinite(row), row, -1.0)))
    samples = np.empty(n_samples, dtype=np.int64)
    D = np.empty((n_samples, n))
    mind = np.full(n, np.inf)
    chosen = np.zeros(n, dtype=bool)
    nxt = start
    for i in range(n_samples):
        samples[i] = nxt
        chosen[nxt] = True
        D[i] = solver.distances([nxt])[0]
        np.minimum(mind, D[i], out=mind)
        if i + 1 < n_samples:
            score = np.where(chosen, -1.0, mind)
            nxt = int(np.argmax(score))
    return samples, D


def geodesic_voronoi_sampling(graph, n_samples: int, *, seed: int = 0, n_jumps: int = 3,
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Max-min samples on a weighted graph and the geodesic Voronoi cell of every vertex.

    The same samples as :func:`farthest_point_sampling` with the ``graph`` backend, but no
    distance rows are kept: each new sample's Dijkstra run stops at the current covering
    radius (no vertex farther than that can change its nearest sample), so the work
    shrinks as the samples densify.

    Parameters
    ----------
    graph : (n, n) scipy.sparse matrix
        Symmetric edge lengths, e.g. :func:`geoshape.geometry.graph.structural_graph`.
    n_samples : int
        ``1 <= l <= n``.
    seed, n_jumps : int
        As :func:`farthest_point_sampling`.

    Returns
    -------
    samples : (l,) int64
        In the order chosen.
    owner : (n,) int64
        Position in ``samples`` of each vertex's nearest sample (its Voronoi cell).
    distance : (n,) float64
        Geodesic distance of each vertex to that sample.

    Notes
    -----
    About O(n log n) for the first rows plus O((n / l) log n) per later sample on an
    evenly sampled surface, instead of O(l n log n); memory O(n).
    """
    from scipy.sparse.csgraph import dijkstra

    n = graph.shape[0]
    if not isinstance(n_samples, (int, np.integer)) or not 1 <= n_samples <= n:
        raise InvalidOptionError(
            f"n_samples must be an integer in [1, {n}] (the number of vertices), got {n_samples!r}"
        )
    rng = np.random.default_rng(seed)
    start = int(rng.integers(n))
    for _ in range(n_jumps):
        row = dijkstra(graph, directed=True, indices=start)
        start = int(np.argmax(np.where(np.isfinite(row), row, -1.0)))
    samples = np.empty(n_samples, dtype=np.int64)
    owner = np.zeros(n, dtype=np.int64)
    distance = np.full(n, np.inf)
    nxt = start
    for i in range(n_samples):
        samples[i] = nxt
        finite = distance[np.isfinite(distance)]
        limit = np.inf if len(finite) < n else float(finite.max())
        row = dijkstra(graph, directed=True, indices=nxt, limit=limit)
        closer = row < distance
        distance[closer] = row[closer]
        owner[closer] = i
        distance[nxt] = 0.0
        if i + 1 < n_samples:
            score = np.where(np.isfinite(distance), distance, np.inf)
            score[samples[: i + 1]] = -1.0
            nxt = int(np.argmax(score))
    return samples, owner, distance


def euclidean_farthest_point_sampling(X, n_samples: int, seed: int = 0) -> np.ndarray:
    """Max-min samples of the rows of ``X`` in Euclidean distance.

    The first sample is the row farthest from a seeded random row (an extremity: less seed
    dependence); each next one is the row farthest from all chosen ones. Distances are
    invariant to permuting and sign-flipping the columns, so every signed eigenvector
    order of one spectral embedding gets the same samples.

    Parameters
    ----------
    X : (m, k) array_like of float
    n_samples : int
        Number of samples; ``n_samples >= m`` returns every row.
    seed : int

    Returns
    -------
    samples : (min(n_samples, m),) int64
        Row indices in the order chosen (``arange(m)`` when every row is taken).

    Notes
    -----
    O(m · n_samples · k) time, O(m) memory (one compiled loop per sample).

    >>> euclidean_farthest_point_sampling([[0.0], [1.0], [5.0], [2.0]], 2).tolist()
    [2, 0]
    """
    from geoshape.geometry._kernels import farthest_point_order

    X = np.ascontiguousarray(X, dtype=np.float64)
    m = len(X)
    if n_samples >= m:
        return np.arange(m)
    start = X[int(np.random.default_rng(seed).integers(m))]
    first = int(np.einsum("ij,ij->i", X - start, X - start).argmax())
    return farthest_point_order(X, first, int(n_samples))
