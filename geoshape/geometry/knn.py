"""Nearest-neighbour search behind a small backend registry.

``scipy`` (``cKDTree``, always available, vectorised over queries, any dimension) and
``open3d`` (``KDTreeFlann``, when the ``open3d`` extra is installed; points as columns,
shape (dim, n), any dimension; queried one point at a time). ``"auto"`` picks the first
available in :data:`BACKENDS` order. Both give the same neighbours (ties aside).

Cost: build O(n log n); k-NN query O(q (k + log n)) expected in low dimension.
"""

from __future__ import annotations

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError, MissingDependencyError

BACKENDS = ("scipy", "open3d")


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


class KNNIndex:
    """A k-nearest-neighbour index over ``points`` (n, d).

    Parameters
    ----------
    points : (n, d) array_like of float
    backend : {"auto", "scipy", "open3d"}

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
        self.backend = available_backends()[0] if backend == "auto" else backend
        if self.backend == "scipy":
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self.points)
        else:
            try:
                import open3d as o3d
            except ImportError as exc:
                raise MissingDependencyError(
                    "the 'open3d' nearest-neighbour backend needs open3d: pip install 'geoshape[open3d]'"
                ) from exc
            self._tree = o3d.geometry.KDTreeFlann(np.asfortranarray(self.points.T))

    def query(self, queries, k: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Distances and indices of the ``k`` nearest points to each query.

        Returns ``(dist, idx)``, each of shape (q,) when ``k == 1``, else (q, k).
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
        dist = np.empty((len(Q), k))
        idx = np.empty((len(Q), k), np.int64)
        for i, q in enumerate(Q):
            _, ii, d2 = self._tree.search_knn_vector_xd(q, k)
            idx[i], dist[i] = np.asarray(ii), np.sqrt(np.asarray(d2))
        if k == 1:
            return dist[:, 0], idx[:, 0]
        return dist, idx


def nearest_neighbors(points, queries, k: int = 1, backend: str = "auto"):
    """One-shot k-NN: ``KNNIndex(points, backend).query(queries, k)``."""
    return KNNIndex(points, backend).query(queries, k)
