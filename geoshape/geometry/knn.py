"""Nearest neighbours: the one home of geoshape's k-NN queries.

- :func:`nearest` — the nearest row of ``points`` for each query, in any dimension;
- :func:`k_nearest` — the ``k`` nearest rows, sorted by distance;
- :func:`nearest_searcher` — :func:`nearest` with the index built once, for repeated queries;
- :class:`KNNIndex` — a KD-tree index, queried many times;
- :func:`kd_tree` — the SciPy KD-tree itself, for tree-specific operations
  (``query_ball_point``, …).

Low dimensions (``d <=`` :data:`KD_TREE_MAX_DIM`) use a KD-tree. In higher dimensions,
where KD-trees degrade to brute force anyway, :func:`nearest` uses blocked BLAS distance
computations: the largest ``x·y − |y|²/2`` (one product with a lifted column) in blocks of
queries, O(q n d) time, O(block n) memory. The block products run in single precision
(twice the BLAS speed, half the memory traffic; the nearest point changes only between
near-ties); the returned distances are recomputed in double precision. :func:`k_nearest`
uses the KD-tree in every dimension.

Backends of the KD-tree (:data:`BACKENDS`): ``scipy`` (``cKDTree``, always available, any
dimension) and ``open3d`` (``open3d.core.nns.NearestNeighborSearch``, when the ``open3d``
extra is installed; all queries in one batched call, multi-threaded). Both find the same
neighbours except between exactly equidistant points, where the two libraries break ties
differently. ``"auto"`` is always ``scipy``: Open3D is faster only in some cases and by at
most about 20 % (``geoshape bench knn``, docs/RESULTS.md), and choosing it by size would
make maps depend on whether an optional extra is installed and change how ties resolve.

Cost: build O(n log n); k-NN query O(q (k + log n)) expected in low dimension.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError, MissingDependencyError

__all__ = ["BACKENDS", "KD_TREE_MAX_DIM", "KNNIndex", "available_backends", "kd_tree", "nearest",
           "k_nearest", "nearest_searcher"]

BACKENDS = ("scipy", "open3d")
#: above this dimension :func:`nearest` uses blocked BLAS products instead of a KD-tree
KD_TREE_MAX_DIM = 8


def available_backends() -> list[str]:
    """Backends importable in this environment, in preference order."""
    out = ["scipy"]
    try:
        import open3d  # noqa: F401
    except ImportError:
        pass
    else:
        out.append("open3d")
    return out


def kd_tree(points):
    """SciPy's ``cKDTree`` over ``points (n, d)``, for operations beyond k-NN queries."""
    from scipy.spatial import cKDTree

    return cKDTree(np.asarray(points, dtype=np.float64))


class KNNIndex:
    """A k-nearest-neighbour index over ``points`` (n, d).

    Parameters
    ----------
    points : (n, d) array_like of float
    backend : {"auto", "scipy", "open3d"}
        ``"auto"`` is ``"scipy"`` (see the module documentation).

    Examples
    --------
    >>> idx = KNNIndex(np.eye(3))
    >>> idx.query(np.array([[0.9, 0.1, 0.0]]), k=1)[1]
    array([0])
    """

    def __init__(self, points, backend: str = "auto"):
        check_choice("nearest-neighbour backend", backend, ("auto", *BACKENDS))
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        if self.points.ndim != 2 or len(self.points) == 0:
            raise InvalidOptionError(f"points must have shape (n, d) with n >= 1, got {self.points.shape}")
        self.backend = "scipy" if backend == "auto" else backend
        if self.backend == "scipy":
            self._tree = kd_tree(self.points)
        else:
            try:
                import open3d as o3d
            except ImportError as exc:
                raise MissingDependencyError(
                    "the 'open3d' nearest-neighbour backend needs open3d: pip install 'geoshape[open3d]'"
                ) from exc
            self._tree = o3d.core.nns.NearestNeighborSearch(o3d.core.Tensor.from_numpy(self.points))
            self._tree.knn_index()

    def query(self, queries, k: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Distances and indices of the ``k`` nearest points to each query.

        Returns ``(dist, idx)``, each of shape (q,) when ``k == 1``, else (q, k), sorted by
        distance along each row.
        """
        Q = np.ascontiguousarray(queries, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != self.points.shape[1]:
            raise InvalidOptionError(
                f"queries must have shape (q, {self.points.shape[1]}), got {Q.shape}"
            )
        k = int(k)
        if not 1 <= k <= len(self.points):
            raise InvalidOptionError(f"k must be in [1, {len(self.points)}], got {k}")
        if self.backend == "scipy":
            dist, idx = self._tree.query(Q, k=k)
            return np.asarray(dist), np.asarray(idx, dtype=np.int64)
        import open3d as o3d

        idx, d2 = self._tree.knn_search(o3d.core.Tensor.from_numpy(Q), k)
        idx = idx.numpy().astype(np.int64, copy=False).reshape(len(Q), k)
        dist = np.sqrt(d2.numpy().astype(np.float64, copy=False)).reshape(len(Q), k)
        if k == 1:
            return dist[:, 0], idx[:, 0]
        return dist, idx


def nearest(points: np.ndarray, queries: np.ndarray, *, backend: str = "auto",
            block: int = 2048) -> tuple[np.ndarray, np.ndarray]:
    """For each query row, the nearest row of ``points``.

    Parameters
    ----------
    points : (n, d) float
    queries : (q, d) float
    backend : KD-tree backend (``d <= KD_TREE_MAX_DIM``), see :class:`KNNIndex`
    block : queries per BLAS block (``d > KD_TREE_MAX_DIM``)

    Returns
    -------
    dist : (q,) float64, Euclidean distance to the nearest point
    idx : (q,) int64

    Examples
    --------
    >>> nearest(np.eye(3), np.array([[0.0, 0.2, 0.9]]))[1]
    array([2])
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    queries = np.ascontiguousarray(queries, dtype=np.float64)
    if points.shape[1] <= KD_TREE_MAX_DIM:
        return KNNIndex(points, backend).query(queries, k=1)
    # argmin |x − y|² = argmax (x·y − |y|²/2): one product with an extra column, one pass
    n, d = points.shape
    lifted = np.empty((n, d + 1), np.float32)
    lifted[:, :d] = points
    lifted[:, d] = -0.5 * np.einsum("ij,ij->i", points, points)
    lifted_t = np.ascontiguousarray(lifted.T)
    q32 = np.ones((min(block, len(queries)), d + 1), np.float32)
    idx = np.empty(len(queries), np.int64)
    for s in range(0, len(queries), block):
        b = min(block, len(queries) - s)
        q32[:b, :d] = queries[s : s + b]
        idx[s : s + b] = (q32[:b] @ lifted_t).argmax(axis=1)
    dist = np.linalg.norm(queries - points[idx], axis=1)
    return dist, idx


def k_nearest(points: np.ndarray, queries: np.ndarray, k: int, *, backend: str = "auto"):
    """The ``min(k, n)`` nearest rows of ``points`` for each query, nearest first.

    Returns ``(dist (q, k), idx (q, k))`` (2D even for ``k == 1``). KD-tree in any dimension.
    """
    k = min(int(k), len(points))
    d, i = KNNIndex(points, backend).query(queries, k=k)
    return d.reshape(len(queries), k), i.reshape(len(queries), k)


def nearest_searcher(points: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``f(queries) -> (q,) int64`` indices of the nearest rows of ``points``, as :func:`nearest`.

    The KD-tree (``d <= KD_TREE_MAX_DIM``) is built once, for many calls.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.shape[1] <= KD_TREE_MAX_DIM:
        index = KNNIndex(points)
        return lambda queries: np.asarray(index.query(np.ascontiguousarray(queries, dtype=np.float64),
                                                      k=1)[1], dtype=np.int64)
    return lambda queries: nearest(points, queries)[1]
