"""Mesh graphs and the structural graph (thesis §4.4).

The *mesh graph* has one edge per triangle side, weighted by its Euclidean length. It is
disconnected when the mesh has several parts, and empty for a point cloud. The
*structural graph* adds to it only the edges of Yang's p-connected graph (the union of p
successive Euclidean minimum spanning trees, each computed after removing the edges of
the previous ones) that join two different connected components of the mesh graph. The
result is one connected graph for any input: a closed mesh (nothing added), a mesh in
several parts, a triangle soup, or a point cloud without faces.

All graphs are returned as symmetric ``scipy.sparse.csr_matrix`` of shape ``(n, n)`` whose
entries are edge lengths; zero-length edges (duplicate vertices) are given the length
``ZERO_LENGTH_EPS * bbox_diagonal`` so that no edge disappears as an implicit zero.

The EMST is computed on a k-nearest-neighbour candidate graph (``k = 10``), whose
components are then joined by exact nearest pairs (Borůvka rounds). It equals the true
EMST whenever the EMST is contained in the candidate graph, which is the case for surface
samplings in practice. Cost: O(n log n) time and O(n k) memory.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree

from geoshape.errors import InvalidOptionError
from geoshape.geometry.mesh import edges_graph, undirected_edges, unique_edges, vertex_components
from geoshape.io.validate import check_mesh

__all__ = [
    "emst_edges",
    "bridging_edges",
    "structural_graph",
]

_KNN_CANDIDATES = 10

def _knn_candidates(V: np.ndarray, k: int) -> np.ndarray:
    from geoshape.geometry.knn import k_nearest

    n = len(V)
    k = min(k, n - 1)
    if k < 1:
        return np.zeros((0, 2), dtype=np.int64)
    _, idx = k_nearest(V, V, k + 1)
    rows = np.repeat(np.arange(n), k)
    cols = idx[:, 1:].ravel()
    ok = cols < n
    return undirected_edges(np.column_stack([rows[ok], cols[ok]]), n)


def _nearest_outside(V: np.ndarray, members: np.ndarray, others: np.ndarray):
    """Closest pair (i in members, j in others) by brute force over a KD-tree."""
    from geoshape.geometry.knn import KNNIndex

    d, j = KNNIndex(V[others]).query(V[members], k=1)
    a = int(np.argmin(d))
    return int(members[a]), int(others[j[a]]), float(d[a])


def _join_components(V: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Edges joining the groups of ``labels`` into one: Borůvka on exact nearest pairs.

    Each round finds, for every group, its nearest pair to a point of another group (a
    KD-tree of the complement) and merges along those pairs; the number of groups at least
    halves per round. Cost: O(c n log n) for c groups in the first round — only used for
    the few groups left by the k-NN candidate graph.
    """
    labels = labels.copy()
    added: list[tuple[int, int]] = []
    n = len(V)
    while True:
        groups = np.unique(labels)
        if len(groups) <= 1:
            break
        best = {}
        for g in groups:
            members = np.flatnonzero(labels == g)
            others = np.flatnonzero(labels != g)
            best[g] = _nearest_outside(V, members, others)
        new = {tuple(sorted((i, j))) for i, j, _ in best.values()}
        added.extend(new)
        E = np.array(sorted(new), dtype=np.int64)
        # merge: groups joined by the new edges
        A = sp.coo_matrix((np.ones(len(E)), (labels[E[:, 0]], labels[E[:, 1]])), shape=(n, n))
        _, merged = connected_components(A, directed=False)
        labels = merged[labels]
    return np.array(sorted(added), dtype=np.int64).reshape(-1, 2)


def _mst_edges(V: np.ndarray, E: np.ndarray) -> np.ndarray:
    """Minimum spanning forest of candidate edges ``E``, completed into a spanning tree."""
    n = len(V)
    G = edges_graph(V, E)
    T = minimum_spanning_tree(G).tocoo()
    tree = np.sort(np.column_stack([T.row, T.col]), axis=1).astype(np.int64)
    n_comp, labels = connected_components(T, directed=False)
    if n_comp > 1:
        tree = np.concatenate([tree, _join_components(V, labels)])
    return tree.reshape(-1, 2) if n > 1 else np.zeros((0, 2), dtype=np.int64)


def emst_edges(V, p: int = 1, *, k: int = _KNN_CANDIDATES) -> np.ndarray:
    """Edges of Yang's p-connected graph: the union of p successive EMSTs.

    The first tree is the Euclidean minimum spanning tree of the points; each further tree
    is the minimum spanning tree of what remains after the previous trees' edges are
    removed from the candidate graph (k nearest neighbours, completed by exact nearest
    pairs when it is disconnected).

    Parameters
    ----------
    V : (n, 3) float
        Points (faces are ignored).
    p : int
        Number of trees, ``p >= 1``.
    k : int
        Nearest neighbours per point in the candidate graph.

    Returns
    -------
    E : (e, 2) int64
        Undirected edges, ``E[:, 0] < E[:, 1]``; ``e <= p (n - 1)``.

    Notes
    -----
    Time O(p n k log n), memory O(n k).
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    if p < 1:
        raise InvalidOptionError(f"p (number of spanning trees) must be >= 1, got {p}")
    cand = _knn_candidates(V, k)
    trees = []
    for _ in range(p):
        T = _mst_edges(V, cand)
        trees.append(T)
        if len(cand):
            keyc = cand[:, 0] * len(V) + cand[:, 1]
            keyt = T[:, 0] * len(V) + T[:, 1]
            cand = cand[~np.isin(keyc, keyt)]
    return undirected_edges(np.concatenate(trees), len(V))


def bridging_edges(V, F, p: int = 1) -> np.ndarray:
    """Edges of the p-connected graph that join two different mesh components.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int, may be empty (a point cloud: every EMST edge is a bridge)
    p : int
        Number of EMSTs (thesis: 1 or 2). ``p = 0`` is accepted only when the mesh is
        already connected.

    Returns
    -------
    B : (b, 2) int64
        Bridging edges, empty when the mesh graph is connected (no EMST is computed then).

    Raises
    ------
    InvalidOptionError
        ``p < 0``, or ``p = 0`` on a mesh with several components.
    """
    V, F = check_mesh(V, F, allow_no_faces=True, min_vertices=1)
    if p < 0:
        raise InvalidOptionError(f"p (number of spanning trees) must be >= 0, got {p}")
    n_comp, labels = vertex_components(len(V), F)
    if n_comp <= 1:
        return np.zeros((0, 2), dtype=np.int64)
    if p == 0:
        raise InvalidOptionError(
            f"the mesh has {n_comp} connected components and p = 0 adds no bridging "
            "edges; use p = 1 or 2 to connect them"
        )
    E = emst_edges(V, p)
    return E[labels[E[:, 0]] != labels[E[:, 1]]]


def structural_graph(V, F, p: int = 1) -> sp.csr_matrix:
    """The structural graph: mesh edges plus the bridging edges of p EMSTs (thesis §4.4).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
        Triangles; may be empty (point cloud) or a soup of unconnected triangles.
    p : int
        Number of Euclidean minimum spanning trees (1 or 2 in the thesis).

    Returns
    -------
    G : (n, n) csr_matrix
        Symmetric, edge lengths as weights, connected.

    Raises
    ------
    InvalidMeshError, InvalidOptionError

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0]], float)
    >>> G = structural_graph(V, [[0, 1, 2], [3, 4, 5]])
    >>> from scipy.sparse.csgraph import connected_components
    >>> connected_components(G)[0]
    1

    Notes
    -----
    O(n + m) for a connected mesh; O(p n k log n) time and O(n k) memory otherwise.
    """
    V, F = check_mesh(V, F, allow_no_faces=True, min_vertices=1)
    E = unique_edges(F, len(V))
    B = bridging_edges(V, F, p)
    if len(B):
        E = undirected_edges(np.concatenate([E, B]), len(V))
    return edges_graph(V, E)
