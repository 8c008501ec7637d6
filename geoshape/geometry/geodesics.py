"""Geodesic distances on triangle meshes: one API, three backends.

Backends (``GEODESIC_METHODS``):

``"graph"``
    Shortest paths on the structural graph (:func:`geoshape.geometry.graph.structural_graph`)
    with SciPy's Dijkstra. Works on anything (several parts, triangle soups, point clouds).
    Overestimates surface distance (paths follow edges): about 5–15 % on irregular
    meshes, see ``docs/RESULTS.md``. Fastest; the default.
``"heat"``
    The heat method (Crane et al. 2013): potpourri3d's ``MeshHeatMethodDistanceSolver``
    (robust intrinsic Laplacian).
    One factorisation per mesh, then one linear solve per source.
``"exact"``
    libigl's exact polyhedral geodesics (MMP). No precomputation, O(n^2) per source
    in the worst case: for tests and benchmarks on small meshes.

Several components. ``heat`` and ``exact`` measure distances along the surface inside one
connected component. Across components they are combined with the bridging edges of the
structural graph: the endpoints of bridging edges ("portals") get one surface-distance
row each, inside their own component (computed once and cached); the distance from a
source to a vertex in another component is then the shortest route source → portal →
bridge → portal → … → vertex, found by Dijkstra on the small graph of portals. When there
are more than ``max_portals`` portals (a triangle soup, a point cloud) the solver falls
back to the ``graph`` backend and emits a ``UserWarning``; ``solver.method`` tells which
backend is actually used.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import scipy.sparse as sp

from geoshape._options import check_choice
from geoshape.errors import InvalidMeshError, InvalidOptionError, ResourceLimitError
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = [
    "GEODESIC_METHODS",
    "DEFAULT_GEODESIC_METHOD",
    "GeodesicSolver",
    "geodesic_distances",
    "all_pairs_geodesics",
    "available_memory_bytes",
    "check_all_pairs_memory",
]

GEODESIC_METHODS = ("graph", "heat", "exact")
DEFAULT_GEODESIC_METHOD = "graph"
#: fraction of the available memory that one n x n float64 block may take
ALL_PAIRS_MEMORY_FRACTION = 0.25


def available_memory_bytes() -> int:
    """Memory the process may still use: ``MemAvailable`` of /proc/meminfo, else physical RAM."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 8 * 1024**3


def check_all_pairs_memory(n: int, *, what: str = "all-pairs geodesic distances",
                           max_bytes: int | None = None) -> None:
    """Raise :class:`ResourceLimitError` if an ``(n, n)`` float64 matrix would not fit.

    The limit is ``max_bytes`` if given, else ``ALL_PAIRS_MEMORY_FRACTION`` of the
    available memory (the embedding holds two such blocks at its peak, plus the
    eigensolver's work space).
    """
    need = 8 * n * n
    limit = max_bytes if max_bytes is not None else int(
        ALL_PAIRS_MEMORY_FRACTION * available_memory_bytes()
    )
    if need > limit:
        raise ResourceLimitError(
            f"{what} for n = {n} vertices need {need / 1e9:.1f} GB (an n x n float64 "
            f"matrix) but the limit is {limit / 1e9:.1f} GB; use the Nystrom embedding "
            "(spectral_embedding(..., method='nystrom'), or `geoshape embed --samples L`), "
            "which computes only an l x n block"
        )


def exact_geodesic_problems(V: np.ndarray, F: np.ndarray) -> list[str]:
    """What stops libigl's exact (MMP) geodesics on a mesh: degenerate faces (a repeated
    vertex or zero area), duplicate faces and non-manifold edges — inputs on which its C++
    code corrupts memory instead of failing. Empty when the mesh is fine. O(m log m).

    >>> exact_geodesic_problems(np.eye(3), np.array([[0, 1, 2], [2, 1, 0]]))
    ['1 duplicate face']
    """
    from geoshape.geometry.mesh import degenerate_faces, duplicate_face_count, unique_edges

    F = np.asarray(F, dtype=np.int64)
    degenerate = int(np.count_nonzero(degenerate_faces(V, F)))
    duplicate = duplicate_face_count(F)
    _, counts = unique_edges(F, len(V), return_counts=True)
    nonmanifold = int(np.count_nonzero(counts > 2))
    found = [(degenerate, "degenerate face"), (duplicate, "duplicate face"),
             (nonmanifold, "non-manifold edge")]
    return [f"{k} {what}{'s' if k > 1 else ''}" for k, what in found if k]


class _SurfaceSolver:
    """Single-source surface distances on one connected triangle mesh (heat or exact)."""

    def __init__(self, V: np.ndarray, F: np.ndarray, method: str, t_coef: float, clip: bool = True):
        self.V, self.F, self.method, self.clip = V, F, method, clip
        self.n = len(V)
        if method == "exact":
            problems = exact_geodesic_problems(V, F)
            if problems:
                raise InvalidMeshError(
                    f"exact geodesics need a manifold mesh without degenerate or duplicate faces; "
                    f"this one has {', '.join(problems)} (use the 'heat' or 'graph' geodesics, or repair it)"
                )
        if method == "heat":
            import potpourri3d as pp3d

            self.backend = "potpourri3d"
            self._solver = pp3d.MeshHeatMethodDistanceSolver(V, F, t_coef=t_coef)
        else:
            self.backend = "igl"

    def row(self, s: int) -> np.ndarray:
        if self.method == "heat":
            d = np.asarray(self._solver.compute_distance(int(s)), dtype=np.float64)
            if len(d) < self.n:  # trailing vertices in no face (raw mode): unreachable
                d = np.concatenate([d, np.full(self.n - len(d), np.inf)])
            if self.clip:
                d = np.maximum(d, 0.0)
                d[s] = 0.0
            return d
        import igl

        return np.asarray(
            igl.exact_geodesic(
                self.V, self.F,
                np.array([s], dtype=np.int64), np.array([], dtype=np.int64),
                np.arange(self.n, dtype=np.int64), np.array([], dtype=np.int64),
            ),
            dtype=np.float64,
        )


class GeodesicSolver:
    """Geodesic distances from chosen sources on one mesh, with the precomputation cached.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
        May be empty (point cloud; only ``"graph"`` applies, the others fall back to it).
    method : {"graph", "heat", "exact"}
        Backend, see the module documentation.
    p : int
        Number of EMSTs of the structural graph (bridging edges between components).
    max_portals : int
        Above this many bridging-edge endpoints, ``heat``/``exact`` fall back to ``graph``.
    t_coef : float
        Heat method time step, as a multiple of the mean edge length squared.
    raw : bool
        ``True``: the backend's own distances on the mesh exactly as given, for scoring
        against ground truth — nothing bridges components (``graph`` is the mesh graph,
        zero-length edges kept at 0, infinite between components; ``heat``/``exact`` run
        one solver on the whole mesh, whatever it gives across components) and heat
        values are not clipped at 0. ``p`` and ``max_portals`` are then unused.

    Attributes
    ----------
    method : str
        The backend actually used (``"graph"`` after a fallback).
    n : int
        Number of vertices.

    Examples
    --------
    >>> import trimesh
    >>> m = trimesh.creation.icosphere(3)
    >>> solver = GeodesicSolver(m.vertices, m.faces, "heat")
    >>> solver.distances([0, 5]).shape
    (2, 642)

    Notes
    -----
    Precomputation: ``graph`` O(n log n) (the structural graph), ``heat`` one sparse
    Cholesky factorisation per component, ``exact`` none. Per source: ``graph``
    O(n log n), ``heat`` O(n) (two back-substitutions), ``exact`` O(n^2) worst case.
    Each source returns a row of n float64.
    """

    @mesh_input
    def __init__(self, V, F, method: str = DEFAULT_GEODESIC_METHOD, *, p: int = 1,
                 max_portals: int = 256, t_coef: float = 1.0, raw: bool = False):
        check_choice("geodesic method", method, GEODESIC_METHODS)
        V, F = check_mesh(V, F, allow_no_faces=True, min_vertices=1)
        from geoshape.geometry.graph import bridging_edges, structural_graph
        from geoshape.geometry.mesh import edge_graph, vertex_components

        self.V, self.F, self.n, self.p, self.raw = V, F, len(V), p, raw
        self.requested_method = method
        self.method = method
        self.graph: sp.csr_matrix | None = None
        if method == "graph":
            self.graph = edge_graph(V, F, raw_lengths=True) if raw else structural_graph(V, F, p)
            return
        if len(F) == 0:
            self._fallback("the mesh has no faces")
            return
        n_comp, labels = (1, None) if raw else vertex_components(self.n, F)
        self.labels = labels
        if n_comp == 1:
            self._parts = {0: (np.arange(self.n), _SurfaceSolver(V, F, method, t_coef, clip=not raw))}
            self._portals = np.zeros(0, dtype=np.int64)
            return
        B = bridging_edges(V, F, p)
        portals = np.unique(B)
        if len(portals) > max_portals:
            self._fallback(
                f"the mesh has {n_comp} components joined by {len(portals)} bridge endpoints "
                f"(more than max_portals = {max_portals})"
            )
            return
        self._t_coef = t_coef
        self._parts = {}
        self._bridges = B
        self._portals = portals
        self._portal_rows = np.vstack([self._component_row(int(q)) for q in portals])

    def _fallback(self, reason: str) -> None:
        from geoshape.geometry.graph import structural_graph

        warnings.warn(
            f"{self.requested_method!r} geodesics need one connected surface; {reason}: "
            "using shortest paths on the structural graph instead",
            UserWarning,
            stacklevel=3,
        )
        self.method = "graph"
        if self.raw:
            from geoshape.geometry.mesh import edge_graph

            self.graph = edge_graph(self.V, self.F, raw_lengths=True)
        else:
            self.graph = structural_graph(self.V, self.F, self.p)

    def _part(self, c: int):
        if c not in self._parts:
            verts = np.flatnonzero(self.labels == c)
            if len(verts) < 3:
                self._parts[c] = (verts, None)
            else:
                remap = np.full(self.n, -1, dtype=np.int64)
                remap[verts] = np.arange(len(verts))
                Fc = remap[self.F[remap[self.F[:, 0]] >= 0]]
                self._parts[c] = (
                    verts, _SurfaceSolver(self.V[verts], Fc, self.method, self._t_coef)
                )
        return self._parts[c]

    def _component_row(self, s: int) -> np.ndarray:
        """Surface distances from ``s`` inside its own component, inf elsewhere."""
        if len(self._portals) == 0:
            return self._parts[0][1].row(s)
        verts, solver = self._part(int(self.labels[s]))
        row = np.full(self.n, np.inf)
        if solver is None:  # isolated vertex or edge: straight-line distances
            row[verts] = np.linalg.norm(self.V[verts] - self.V[s], axis=1)
        else:
            local = int(np.searchsorted(verts, s))
            row[verts] = solver.row(local)
        return row

    def _combined_row(self, s: int) -> np.ndarray:
        from scipy.sparse.csgraph import dijkstra

        d_s = self._component_row(s)
        P = self._portals
        k = len(P)
        Dpp = self._portal_rows[:, P]  # (k, k), inf across components
        pos = {int(q): i for i, q in enumerate(P)}
        r, c = np.nonzero(np.isfinite(Dpp))
        rows = [r, np.full(k, k)]
        cols = [c, np.arange(k)]
        vals = [Dpp[r, c], d_s[P]]
        B = self._bridges
        bi = np.array([pos[int(a)] for a in B[:, 0]])
        bj = np.array([pos[int(b)] for b in B[:, 1]])
        blen = np.linalg.norm(self.V[B[:, 0]] - self.V[B[:, 1]], axis=1)
        rows += [bi, bj]
        cols += [bj, bi]
        vals += [blen, blen]
        rows, cols, vals = map(np.concatenate, (rows, cols, vals))
        ok = np.isfinite(vals)
        # tiny positive lengths so that zero-length links stay edges in the sparse graph
        vals = np.maximum(vals[ok], 1e-300)
        G = sp.coo_matrix((vals, (rows[ok], cols[ok])), shape=(k + 1, k + 1)).tocsr()
        g = dijkstra(G, directed=True, indices=k)[:k]  # (k,) source -> each portal
        via = (g[:, None] + self._portal_rows).min(axis=0)
        return np.minimum(d_s, via)

    def distances(self, sources) -> np.ndarray:
        """Geodesic distances from each source to every vertex.

        Parameters
        ----------
        sources : int or (s,) array_like of int
            Vertex indices.

        Returns
        -------
        D : (s, n) float64
            ``D[i, j]`` is the distance from ``sources[i]`` to vertex ``j``.
        """
        src = np.atleast_1d(np.asarray(sources))
        if src.dtype.kind not in "iu" or src.ndim != 1:
            raise InvalidOptionError(f"sources must be vertex indices, got {src!r}")
        if len(src) and (src.min() < 0 or src.max() >= self.n):
            raise InvalidOptionError(
                f"sources must lie in [0, {self.n - 1}], got values in [{src.min()}, {src.max()}]"
            )
        src = src.astype(np.int64)
        if self.method == "graph":
            from scipy.sparse.csgraph import dijkstra

            if len(src) == 0:
                return np.zeros((0, self.n))
            # the graph is symmetric: directed=True avoids a transpose per call
            return np.atleast_2d(dijkstra(self.graph, directed=True, indices=src))
        out = np.empty((len(src), self.n))
        for i, s in enumerate(src):
            out[i] = self._component_row(int(s)) if len(self._portals) == 0 else \
                self._combined_row(int(s))
        return out


@mesh_input
def geodesic_distances(V, F, sources, method: str = DEFAULT_GEODESIC_METHOD, *,
                       p: int = 1) -> np.ndarray:
    """Geodesic distances from ``sources`` to all vertices (one-off; see :class:`GeodesicSolver`).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    sources : (s,) array_like of int
    method : {"graph", "heat", "exact"}
    p : int
        EMSTs for bridging components (see :func:`~geoshape.geometry.graph.structural_graph`).

    Returns
    -------
    D : (s, n) float64

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    >>> geodesic_distances(V, [[0, 1, 2], [0, 2, 3]], [0]).round(3)
    array([[0.   , 1.   , 1.414, 1.   ]])
    """
    check_choice("geodesic method", method, GEODESIC_METHODS)
    return GeodesicSolver(V, F, method, p=p).distances(sources)


@mesh_input
def all_pairs_geodesics(V, F, method: str = DEFAULT_GEODESIC_METHOD, *, p: int = 1,
                        max_bytes: int | None = None) -> np.ndarray:
    """All-pairs geodesic distances, refused when the ``(n, n)`` matrix would not fit.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    method : {"graph", "heat", "exact"}
    p : int
    max_bytes : int, optional
        Largest matrix accepted; default a fraction of the available memory.

    Returns
    -------
    D : (n, n) float64
        Symmetrised (``(D + D.T) / 2``) for the approximate backends.

    Raises
    ------
    ResourceLimitError
        ``8 n^2`` bytes exceed the limit; use the Nyström embedding instead.

    Notes
    -----
    Time: ``graph`` O(n^2 log n); ``heat`` O(n^2) after one factorisation; ``exact``
    O(n^3) worst case. Memory O(n^2).
    """
    check_choice("geodesic method", method, GEODESIC_METHODS)
    V, F = check_mesh(V, F, allow_no_faces=True, min_vertices=1)
    check_all_pairs_memory(len(V), max_bytes=max_bytes)
    solver = GeodesicSolver(V, F, method, p=p)
    if solver.method == "graph":
        from scipy.sparse.csgraph import dijkstra

        return dijkstra(solver.graph, directed=True)
    D = np.empty((solver.n, solver.n))
    for s in range(solver.n):
        D[s] = solver.distances([s])[0]
    D += D.T
    D *= 0.5
    return D
