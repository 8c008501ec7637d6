"""Nearest neighbours in embedding spaces of any dimension.

Low dimensions (d <= 8) use a KD-tree (:mod:`geoshape.geometry.knn`, SciPy or Open3D);
higher dimensions, where KD-trees degrade to brute force anyway, use blocked BLAS
distance computations: ``|y|² - 2 x·y`` in blocks of queries, O(q n d) time,
O(block n) memory. The block products run in single precision (twice the BLAS speed,
half the memory traffic; the nearest point changes only between near-ties); the
returned distances are recomputed in double precision.
"""

from __future__ import annotations

import numpy as np

from geoshape.geometry.knn import KNNIndex

KD_TREE_MAX_DIM = 8


def nearest(points: np.ndarray, queries: np.ndarray, *, backend: str = "auto",
            block: int = 2048) -> tuple[np.ndarray, np.ndarray]:
    """For each query row, the nearest row of ``points``.

    Parameters
    ----------
    points : (n, d) float
    queries : (q, d) float

    Returns
    -------
    dist : (q,) float64, Euclidean distance to the nearest point
    idx : (q,) int64
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    queries = np.ascontiguousarray(queries, dtype=np.float64)
    if points.shape[1] <= KD_TREE_MAX_DIM:
        return KNNIndex(points, backend).query(queries, k=1)
    points32 = points.astype(np.float32)
    sq_p = np.einsum("ij,ij->i", points32, points32)
    idx = np.empty(len(queries), np.int64)
    for s in range(0, len(queries), block):
        d2 = queries[s : s + block].astype(np.float32) @ points32.T
        d2 *= -2.0
        d2 += sq_p[None, :]
        idx[s : s + block] = d2.argmin(axis=1)
    dist = np.linalg.norm(queries - points[idx], axis=1)
    return dist, idx


def k_nearest(points: np.ndarray, queries: np.ndarray, k: int, *, backend: str = "auto"):
    """The ``k`` nearest rows of ``points`` for each query: ``(dist (q, k), idx (q, k))``."""
    k = min(int(k), len(points))
    d, i = KNNIndex(points, backend).query(queries, k=k)
    return d.reshape(len(queries), k), i.reshape(len(queries), k)
