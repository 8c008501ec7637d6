"""Farthest-point ("max-min") sampling of mesh vertices in geodesic distance (thesis App. B).

Each new sample is the vertex whose geodesic distance to the nearest chosen sample is
largest. The first sample is found by a few farthest-point jumps from a seeded random
vertex, which places it near an extremity of the shape. The distance rows computed on the
way are returned, so the Nyström embedding gets its ``l x n`` block for free.
"""

from __future__ import annotations

import numpy as np

from geoshape.errors import InvalidOptionError

__all__ = ["farthest_point_sampling"]


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
