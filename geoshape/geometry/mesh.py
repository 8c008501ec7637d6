"""Per-mesh primitives, one home each: face areas and normals, vertex normals (outward),
vertex areas, unique edges,
connected components and the edge graph of a triangle mesh.

Every function takes the arrays as they are (``V (n, 3)`` float, ``F (m, 3)`` int, as
returned by :func:`geoshape.io.validate.check_mesh`) and is vectorised: O(m) or
O(m log m) time, O(n + m) memory.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from geoshape.errors import InvalidOptionError
from geoshape.io.validate import check_face_indices, check_mesh

__all__ = [
    "ZERO_LENGTH_EPS",
    "face_normals",
    "vertex_normals",
    "outward_sign",
    "outward_vertex_normals",
    "face_areas",
    "vertex_areas",
    "degenerate_faces",
    "duplicate_face_count",
    "unique_edges",
    "undirected_edges",
    "vertex_components",
    "edges_graph",
    "edge_graph",
    "laplacian_matrices",
]

#: zero-length edges of a graph weigh this times the bounding-box diagonal
ZERO_LENGTH_EPS = 1e-12


def face_normals(V: np.ndarray, F: np.ndarray, *, unit: bool = True) -> np.ndarray:
    """Normals of the triangles, oriented by their winding.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    unit : bool
        ``True``: unit vectors (degenerate faces keep their zero vector). ``False``: the
        area-weighted normals ``(v1 - v0) × (v2 - v0)``, of length twice the face area.

    Returns
    -------
    N : (m, 3) float64

    Notes
    -----
    O(m) time and memory.
    """
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    if unit:
        N = N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
    return N


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n, 3) area-weighted unit vertex normals (the winding's side), O(m)."""
    N = np.zeros_like(V)
    fn = face_normals(V, F, unit=False)
    for c in range(3):
        np.add.at(N, F[:, c], fn)
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)


def outward_sign(V: np.ndarray, F: np.ndarray) -> float:
    """+1 if the faces are wound so normals point out of the enclosed volume, else −1."""
    return 1.0 if signed_volume(V, F) >= 0 else -1.0


def outward_vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n, 3) unit vertex normals pointing out of the enclosed volume, O(m)."""
    return vertex_normals(V, F) * outward_sign(V, F)


def face_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Triangle areas, ``(m,)`` float64; O(m).

    >>> face_areas(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    array([0.5])
    """
    return 0.5 * np.linalg.norm(face_normals(V, F, unit=False), axis=1)


def vertex_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Lumped (barycentric) vertex areas: a third of the area of every incident face.

    Returns
    -------
    a : (n,) float64
        Sums to the surface area; 0 for vertices in no face. O(n + m).
    """
    a = face_areas(V, F)
    return np.bincount(F.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(V))


def degenerate_faces(V: np.ndarray, F: np.ndarray, *, area_eps: float = 0.0) -> np.ndarray:
    """(m,) bool: faces that repeat a vertex, or whose area is at most ``area_eps × diag²``
    (diag = bounding-box diagonal; ``area_eps = 0`` flags exactly zero areas). O(m).

    >>> degenerate_faces(np.eye(3), np.array([[0, 1, 2], [0, 0, 1]])).tolist()
    [False, True]
    """
    F = np.asarray(F, dtype=np.int64)
    repeated = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))) if len(V) else 0.0
    return repeated | ~(face_areas(V, F) > area_eps * max(diag, 1e-300) ** 2)


def duplicate_face_count(F: np.ndarray) -> int:
    """Faces that repeat the vertex set of an earlier face (any order). O(m log m)."""
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    return len(F) - len(np.unique(np.sort(F, axis=1), axis=0))


def undirected_edges(E: np.ndarray, n: int | None = None, *, return_counts: bool = False):
    """Sorted unique undirected edges of a list of vertex pairs, without self-loops.

    Parameters
    ----------
    E : (e, 2) int
        Vertex pairs, in any order and orientation, repeats allowed.
    n : int, optional
        Number of vertices (default ``E.max() + 1``).
    return_counts : bool
        Also return how often each edge occurs in ``E``.

    Returns
    -------
    edges : (u, 2) int64
        ``edges[:, 0] < edges[:, 1]``, sorted lexicographically.
    counts : (u,) int64
        Only with ``return_counts``.

    Notes
    -----
    O(e log e): one sort of 1-D keys ``i * n + j`` (much faster than ``np.unique(axis=0)``).
    """
    if len(E) == 0:
        edges = np.zeros((0, 2), dtype=np.int64)
        return (edges, np.zeros(0, dtype=np.int64)) if return_counts else edges
    n = int(E.max()) + 1 if n is None else int(n)
    lo = np.minimum(E[:, 0], E[:, 1])
    hi = np.maximum(E[:, 0], E[:, 1])
    keys = (lo * n + hi)[lo != hi]
    if return_counts:
        key, counts = np.unique(keys, return_counts=True)
        return np.column_stack([key // n, key % n]), counts
    key = np.unique(keys)
    return np.column_stack([key // n, key % n])


def unique_edges(F, n: int | None = None, *, return_counts: bool = False):
    """Unique undirected edges of a triangle list (and how many faces use each).

    Parameters
    ----------
    F : (m, 3) int
    n : int, optional
        Number of vertices (default ``F.max() + 1``).
    return_counts : bool
        Also return the number of faces using each edge (1: boundary, > 2: non-manifold).

    Returns
    -------
    edges : (e, 2) int64
        ``edges[:, 0] < edges[:, 1]``, sorted lexicographically; faces that repeat a
        vertex contribute no self-loop.
    counts : (e,) int64
        Only with ``return_counts``.

    Notes
    -----
    O(m log m) time, O(m) memory.

    >>> unique_edges(np.array([[0, 1, 2], [0, 2, 3]])).tolist()
    [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    """
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    return undirected_edges(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), n,
                            return_counts=return_counts)


def vertex_components(n: int, F) -> tuple[int, np.ndarray]:
    """Connected components of the vertices joined by face edges.

    Parameters
    ----------
    n : int
        Number of vertices; vertices in no face are singleton components.
    F : (m, 3) int

    Returns
    -------
    n_components : int
    labels : (n,) int32
        Component of each vertex, numbered in the order of their smallest vertex.

    Notes
    -----
    O(n + m) time and memory.
    """
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    A = sp.coo_matrix((np.ones(len(E), dtype=np.int8), (E[:, 0], E[:, 1])), shape=(n, n))
    return connected_components(A.tocsr(), directed=False)


def signed_volume(V: np.ndarray, F: np.ndarray) -> float:
    """Signed volume enclosed by ``F (m, 3)`` on ``V (n, 3)``: positive when faces wind outward. O(m)."""
    return float(np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6.0)


def drop_unreferenced(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(V', F')`` without the vertices no face uses, the others kept in order. O(n + m).

    >>> V, F = drop_unreferenced(np.eye(4, 3), np.array([[0, 2, 3]]))
    >>> len(V), F.tolist()
    (3, [[0, 1, 2]])
    """
    used = np.zeros(len(V), dtype=bool)
    used[F.ravel()] = True
    remap = np.cumsum(used) - 1
    return V[used], remap[F]


def largest_component(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The connected component with the most faces, as ``(V', F')`` with vertices kept in order.

    O(n + m) (:func:`vertex_components`).
    """
    _, label = vertex_components(len(V), F)
    keep = np.bincount(label[F[:, 0]]).argmax()
    return drop_unreferenced(V, F[label[F[:, 0]] == keep])


def _length_eps(V: np.ndarray) -> float:
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))) if len(V) else 0.0
    return ZERO_LENGTH_EPS * (diag if diag > 0 else 1.0)


def edges_graph(V: np.ndarray, E: np.ndarray, *, raw_lengths: bool = False) -> sp.csr_matrix:
    """Symmetric sparse graph of the unique edges ``E``, weighted by their lengths.

    Parameters
    ----------
    V : (n, 3) float
    E : (e, 2) int
        Unique undirected edges (e.g. from :func:`unique_edges`).
    raw_lengths : bool
        ``False`` (default): zero-length edges (duplicate vertices) weigh
        ``ZERO_LENGTH_EPS * bbox_diagonal``, so that no edge can vanish as an implicit
        zero. ``True``: they stay explicit zeros (still edges for ``scipy.sparse.csgraph``).

    Returns
    -------
    G : (n, n) csr_matrix, float64

    Notes
    -----
    O(n + e log e) time, O(n + e) memory.
    """
    n = V.shape[0]
    if E.shape[0] == 0:
        return sp.csr_matrix((n, n), dtype=np.float64)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    if not raw_lengths:
        w = np.maximum(w, _length_eps(V))
    return _symmetric_edge_matrix(E, n, w)


def _symmetric_edge_matrix(E: np.ndarray, n: int, values: np.ndarray) -> sp.csr_matrix:
    """``(n, n)`` csr with ``values[e]`` at both (i, j) and (j, i) of each unique edge ``E[e]``."""
    rows = np.concatenate([E[:, 0], E[:, 1]])
    cols = np.concatenate([E[:, 1], E[:, 0]])
    # E holds unique pairs i < j, so no entry is summed twice
    return sp.coo_matrix((np.concatenate([values, values]), (rows, cols)), shape=(n, n)).tocsr()


def edge_graph(V, F, *, raw_lengths: bool = False) -> sp.csr_matrix:
    """The mesh graph: one edge per triangle side, weighted by its length.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int (may be empty: a graph with no edges)
    raw_lengths : bool
        Keep zero-length edges at 0 instead of a tiny length (see :func:`edges_graph`).

    Returns
    -------
    G : (n, n) csr_matrix, symmetric, float64

    Notes
    -----
    O(n + m log m) time, O(n + m) memory.

    Examples
    --------
    >>> G = edge_graph([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> G.nnz
    6
    """
    V, F = check_mesh(V, F, allow_no_faces=True, min_vertices=1)
    return edges_graph(V, unique_edges(F), raw_lengths=raw_lengths)


def vertex_rings(F, n: int, rings: int) -> sp.csr_matrix:
    """Which vertices are at most ``rings`` edges from each vertex (itself included): an
    ``(n, n)`` boolean csr pattern, row ``i`` listing the ``rings``-ring of vertex ``i``.

    Parameters
    ----------
    F : (m, 3) int (may be empty: each vertex's ring is itself)
    n : int, the vertex count
    rings : int, at least 0

    Raises
    ------
    InvalidMeshError
        A face index outside ``[0, n − 1]`` (:func:`~geoshape.io.validate.check_face_indices`).
    InvalidOptionError
        ``rings < 0``.

    Notes
    -----
    ``rings`` sparse products with the adjacency: O(n r̄ d) time for rings of r̄ vertices and
    valence d; O(n r̄) memory (about 37 vertices per 3-ring on a regular triangle mesh).

    Examples
    --------
    >>> vertex_rings([[0, 1, 2], [1, 2, 3]], 5, 1).sum(axis=1).A1.tolist()
    [3, 4, 4, 3, 1]
    """
    if rings < 0:
        raise InvalidOptionError(f"rings must be at least 0, got {rings!r}")
    F = check_face_indices(F, n, name="vertex_rings")
    E = unique_edges(F, n)
    identity = sp.identity(n, dtype=bool, format="csr")
    step = _symmetric_edge_matrix(E, n, np.ones(len(E), dtype=bool)) + identity
    ring = identity
    for _ in range(rings):
        ring = ring @ step
    ring.sort_indices()
    return ring


def laplacian_matrices(V, F, *, name: str = "mesh",
                       matrices: tuple | None = None) -> tuple[sp.spmatrix, sp.spmatrix]:
    """``(L, M)``: the intrinsic-Delaunay cotangent Laplacian (positive semi-definite, ``L x =
    −M Δx``) and the lumped mass matrix of ``V (n, 3)``, ``F (m, 3)``, at the mesh's own scale;
    a mesh without faces gets the point-cloud Laplacian. The one place geoshape builds them, so
    a caller that needs both a basis and the curvature builds them once: ``matrices``, when
    given, are that earlier build, checked against the mesh's size and returned. O(m).
    """
    import robust_laplacian

    V, F = check_mesh(V, F, name=name, allow_no_faces=True)
    if matrices is not None:
        L, M = matrices
        n = len(V)
        if L.shape != (n, n) or M.shape != (n, n):
            raise InvalidOptionError(f"{name}: Laplacian matrices of shape {L.shape} / {M.shape} given for "
                                     f"{n} vertices")
        return L, M
    if len(F):
        return robust_laplacian.mesh_laplacian(V, F)
    return robust_laplacian.point_cloud_laplacian(V)
