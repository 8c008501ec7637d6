"""Dense correspondence between two triangle meshes: the registry of methods.

``correspond(V1, F1, V2, F2, method=...)`` returns a :class:`Correspondence` whose
``p2p_12[i]`` is the vertex of mesh 2 matched to vertex ``i`` of mesh 1.

Methods (``CORRESPONDENCE_METHODS``):

- ``geoshape`` (default): the thesis' spectral alignment gives candidate initial maps
  (best signed eigenvector orders, typically the two mirror solutions), each is refined
  by non-rigid TPS-ICP in the spectral domain and then by ZoomOut on the
  Laplace–Beltrami basis; the candidate whose mapped triangles keep their orientation
  (:mod:`~geoshape.correspondence.orientation`) and whose functional map is closest to
  an isometry wins. When a mirrored map is more isometric than every direct one, the
  mirrored map followed by mesh 2's own left-right symmetry (mesh 2 matched to itself)
  is tried as well ("symmetry completion"). One more candidate comes from wave kernel
  signatures with an orientation-preserving term
  (:mod:`~geoshape.correspondence.fmaps.descriptor_fmap`), which tells front from back where
  the low eigenvectors cannot. Above 8000 vertices the intermediate maps live on samples
  only (large-mesh mode). The stages, the options (:class:`~geoshape.correspondence.pipeline.GeoshapeOptions`,
  checked before any work) and the candidate records are in :mod:`geoshape.correspondence.pipeline`.
- ``jz``: the thesis pipeline, faithfully: geodesic Gaussian affinity (σ = max
  geodesic), k = 6 eigenvectors scaled by √λ with the first dropped (5-D), exhaustive
  reordering and sign correction, TPS non-rigid ICP, proximity-aided matching with 3
  anchors; ``bijective=True`` adds a one-to-one assignment.
- ``shapiro-brady``: unscaled eigenvectors, greedy sign correction, no reordering,
  best match.  ``improved-sb``: the same with √λ scaling.
- ``rigid-icp``: similarity ICP in 3-D space from the principal axes.
- ``shape-context-3d``: 3-D log-polar shape-context histograms (trivial 3-D extension of
  Belongie et al.) after principal-axis alignment, χ²-like (Hellinger) nearest match.

Per-mesh precomputations (embedding, geodesic solver, Laplacian basis, samples) live in
:class:`PreparedMesh`, so a batch computes them once per mesh.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from geoshape._options import check_choice
from geoshape.correspondence.anchors import anchored_match, proximity_anchors
from geoshape.correspondence.icp import nonrigid_icp, rigid_icp
from geoshape.correspondence.pipeline import (  # noqa: F401  (geodesic_distortion: re-exported)
    GeoshapeOptions,
    geodesic_distortion,
    run_geoshape,
    spectral_alignments,
)
from geoshape.correspondence.reorder import REORDER_METHODS, Alignment
from geoshape.errors import InvalidMeshError, InvalidOptionError
from geoshape.geometry.knn import nearest
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

log = logging.getLogger(__name__)

CORRESPONDENCE_METHODS = (
    "geoshape",
    "jz",
    "shapiro-brady",
    "improved-sb",
    "rigid-icp",
    "shape-context-3d",
)
DEFAULT_METHOD = "geoshape"
MIN_VERTICES = 10


@dataclass
class Correspondence:
    """Result of :func:`correspond`.

    Attributes
    ----------
    p2p_12 : (n1,) int64 — for each vertex of mesh 1, a vertex of mesh 2
    cost : float — the method's own cost of the chosen solution (lower is better)
    method : str
    alignment : the chosen signed eigenvector order of mesh 2 (spectral methods)
    alternatives : list of dicts — the candidate solutions considered, with their costs
        (e.g. the best and runner-up sign configurations: mirror-symmetric maps)
    timings : dict — seconds per stage
    details : dict — method-specific extras (anchors, orientation scores, …)
    """

    p2p_12: np.ndarray
    cost: float
    method: str
    alignment: Alignment | None = None
    alternatives: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)


class PreparedMesh:
    """A mesh with its lazily computed, cached per-mesh precomputations.

    Keys of the caches include every parameter, so two methods with different settings
    never share a stale result. Memory: O(n l) for a Nyström embedding, O(n k) for a
    Laplacian basis of k eigenpairs.
    """

    @mesh_input
    def __init__(self, V, F, name: str = "mesh"):
        self.V, self.F = check_mesh(V, F, name=name)
        if len(self.V) < MIN_VERTICES:
            raise InvalidMeshError(
                f"{name}: {len(self.V)} vertices is too few for a correspondence (need >= {MIN_VERTICES})"
            )
        self.name = name
        self._cache: dict = {}

    @property
    def n(self) -> int:
        return len(self.V)

    @property
    def area(self) -> float:
        """Total surface area (sum of face areas), computed once."""
        from geoshape.geometry.mesh import face_areas

        return self.cached(("area",), lambda: float(face_areas(self.V, self.F).sum()))

    def cached(self, key, compute):
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

    def cache_keys(self) -> frozenset:
        """The keys cached so far (to pass to :meth:`cache_entries` as ``since``)."""
        return frozenset(self._cache)

    def cache_entries(self, kinds: tuple[str, ...], since: frozenset = frozenset()) -> dict:
        """The cached entries whose kind (first key item) is in ``kinds`` and whose key is not in
        ``since``: what a stage run in another process computed, to hand back with its result."""
        return {key: value for key, value in self._cache.items() if key[0] in kinds and key not in since}

    def add_cache_entries(self, entries: dict) -> None:
        """Store :meth:`cache_entries` of a copy of this mesh; entries already cached are kept."""
        for key, value in entries.items():
            self._cache.setdefault(key, value)

    def solver(self, method: str = "graph"):
        from geoshape.geometry.geodesics import GeodesicSolver

        return self.cached(("solver", method), lambda: GeodesicSolver(self.V, self.F, method))

    def embedding(self, k: int = 5, *, scaling: str = "sqrt", sigma="max", n_samples: int | None = None,
                  method: str = "auto", geodesics: str = "graph", seed: int = 0):
        from geoshape.spectral.embedding import spectral_embedding

        key = ("embedding", k, scaling, sigma, n_samples, method, geodesics, seed)
        return self.cached(key, lambda: spectral_embedding(
            self.V, self.F, k=k, method=method, n_samples=n_samples, sigma=sigma, scaling=scaling,
            geodesics=geodesics, seed=seed, solver=self.solver(geodesics)))

    def laplacian(self, k: int):
        """The ``k`` lowest Laplace–Beltrami eigenpairs: the leading columns of a larger
        cached basis when there is one (a view), else computed and cached."""
        from geoshape.spectral.laplacian import laplacian_basis

        best = [key for key in self._cache if key[0] == "laplacian" and key[1] >= k]
        if best:
            return self._cache[min(best)].leading(k)
        return self.cached(("laplacian", k), lambda: laplacian_basis(
            self.V, self.F, k, name=self.name, matrices=self.laplacian_matrices()))

    def laplacian_matrices(self):
        """``(L, M)`` of :func:`~geoshape.geometry.mesh.laplacian_matrices`, built once for
        the bases and the curvature (O(m), O(n) memory; not handed back from a forked stage)."""
        from geoshape.geometry.mesh import laplacian_matrices

        return self.cached(("laplacian_matrices",),
                           lambda: laplacian_matrices(self.V, self.F, name=self.name))

    def has_laplacian(self, k: int) -> bool:
        """Whether :meth:`laplacian` ``(k)`` is already cached (no eigen-solve)."""
        return any(key[0] == "laplacian" and key[1] >= k for key in self._cache)

    def descriptor_operators(self, k: int, lb_k: int):
        """Wave kernel signature operators in the first ``k`` of ``lb_k`` eigenvectors, cached."""
        from geoshape.correspondence.fmaps.descriptor_fmap import descriptor_operators

        return self.cached(("descriptor_operators", k, lb_k), lambda: descriptor_operators(
            self.V, self.F, self.laplacian(lb_k), k=k))

    def curvature_field(self, k: int) -> np.ndarray:
        """``(n,)`` unit-free mean curvature (:func:`~geoshape.geometry.curvature.mean_curvature`)
        projected onto the first ``k`` Laplace–Beltrami eigenfunctions: the curvature at the
        resolution of a ``k``-eigenpair functional map, free of per-vertex noise. Cached;
        O(m) + O(n k) after the basis."""
        from geoshape.geometry.curvature import mean_curvature

        def field():
            basis = self.laplacian(k)
            H = mean_curvature(self.V, self.F, matrices=self.laplacian_matrices())
            return basis.evecs @ (basis.evecs.T @ (basis.mass * H))

        return self.cached(("curvature_field", k), field)

    def samples(self, n: int, seed: int = 0):
        """``n`` farthest-point samples in Euclidean space (O(n_vertices · n)), cached."""
        from geoshape.geometry.sampling import euclidean_farthest_point_sampling

        n = min(n, self.n)
        return self.cached(("samples", n, seed), lambda: euclidean_farthest_point_sampling(self.V, n, seed))

    def geodesic_row(self, v: int) -> np.ndarray:
        return self.solver("graph").distances([v])[0]


def _prepared(mesh_or_V, F, name) -> PreparedMesh:
    """A :class:`PreparedMesh` from one, from ``(V, F)`` arrays, or from a mesh object
    (trimesh, Open3D, pymeshlab; vertex order kept) through the one boundary helper."""
    if isinstance(mesh_or_V, PreparedMesh):
        return mesh_or_V
    from geoshape.io.interop import as_arrays

    return PreparedMesh(*as_arrays(mesh_or_V, F, name=name), name=name)


def bijective_assignment(A: np.ndarray, B: np.ndarray, *, n_candidates: int = 16,
                         dense_max: int = 3000) -> np.ndarray:
    """One-to-one map between equally many embedded points minimising total distance.

    Exact Hungarian (``linear_sum_assignment``) up to ``dense_max`` points; above that a
    sparse min-weight perfect matching restricted to each point's ``n_candidates``
    nearest neighbours (``min_weight_full_bipartite_matching``), which falls back to the
    dense solver if the candidate graph has no perfect matching. Dense O(n^3) time,
    O(n^2) memory; sparse roughly O(n c log n).
    """
    import scipy.sparse as sp
    from scipy.optimize import linear_sum_assignment
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching

    from geoshape.geometry.knn import k_nearest

    if len(A) != len(B):
        raise InvalidOptionError(f"bijective matching needs equal vertex counts, got {len(A)} and {len(B)}")
    n = len(A)
    if n > dense_max:
        d, j = k_nearest(B, A, n_candidates)
        G = sp.csr_matrix((d.ravel() + 1e-12, (np.repeat(np.arange(n), j.shape[1]), j.ravel())), shape=(n, n))
        try:
            _, cols = min_weight_full_bipartite_matching(G)
            return np.asarray(cols, dtype=np.int64)
        except ValueError:
            log.warning("sparse candidate graph has no perfect matching; using the dense solver")
    from scipy.spatial.distance import cdist

    _, cols = linear_sum_assignment(cdist(A, B))
    return np.asarray(cols, dtype=np.int64)


def _jz(m1, m2, *, k=5, reorder="exhaustive", icp_iterations=8, n_controls=300, anchors=3,
        proximity=True, bijective=False, n_samples=None, seed=0, n_candidates=20, scaling="sqrt",
        sigma="max"):
    timings = {}
    A, B, alignments = spectral_alignments(m1, m2, k=k, scaling=scaling, reorder=reorder, n_keep=2,
                                           n_samples=n_samples, seed=seed, timings=timings, sigma=sigma)
    best = alignments[0]
    t = time.perf_counter()
    Bw, icp_info = nonrigid_icp(A, best.apply(B), n_iter=icp_iterations, n_controls=n_controls, seed=seed)
    timings["icp"] = time.perf_counter() - t
    t = time.perf_counter()
    details = {"icp": icp_info}
    if bijective:
        p2p = bijective_assignment(A, Bw)
    elif proximity and anchors > 0:
        pairs, G1, G2 = proximity_anchors(A, Bw, m1.geodesic_row, m2.geodesic_row,
                                          n_anchors=anchors, n_candidates=n_candidates)
        p2p = anchored_match(A, Bw, G1, G2, n_candidates=n_candidates)
        details["anchors"] = pairs
    else:
        p2p = nearest(Bw, A)[1]
    timings["matching"] = time.perf_counter() - t
    cost = float(np.linalg.norm(A - Bw[p2p], axis=1).sum())
    alts = [{"perm": a.perm, "signs": a.signs, "cost": a.cost} for a in alignments]
    return Correspondence(p2p, cost, "jz", best, alts, timings, details)


def _shapiro_brady(m1, m2, *, scaling, name, k=5, n_samples=None, seed=0):
    timings = {}
    A, B, alignments = spectral_alignments(m1, m2, k=k, scaling=scaling, reorder="signs", n_keep=2,
                                           n_samples=n_samples, seed=seed, timings=timings)
    best = alignments[0]
    t = time.perf_counter()
    d, p2p = nearest(best.apply(B), A)
    timings["matching"] = time.perf_counter() - t
    alts = [{"perm": a.perm, "signs": a.signs, "cost": a.cost} for a in alignments]
    return Correspondence(p2p, float(d.sum()), name, best, alts, timings)


def _rigid(m1, m2, *, seed=0, n_iter: int = 50):  # deterministic: seed accepted for a uniform API
    t = time.perf_counter()
    X2, p2p = rigid_icp(m1.V, m2.V, n_iter=n_iter)
    d = np.linalg.norm(m1.V - X2[p2p], axis=1)
    return Correspondence(p2p, float(d.sum()), "rigid-icp", timings={"icp": time.perf_counter() - t})


def _shape_context(m1, m2, **options):
    from geoshape.correspondence.shape_context3d import match_shape_context_3d

    t = time.perf_counter()
    p2p, cost = match_shape_context_3d(m1.V, m2.V, **options)
    return Correspondence(p2p, cost, "shape-context-3d", timings={"matching": time.perf_counter() - t})


def correspond(V1, F1=None, V2=None, F2=None, method: str = DEFAULT_METHOD, *, blas_threads: int | None = 1,
               names: tuple[str, str] = ("source mesh", "target mesh"), **options) -> Correspondence:
    """Dense vertex correspondence from mesh 1 to mesh 2.

    Parameters
    ----------
    V1, F1, V2, F2 : arrays ``(n, 3)``, ``(m, 3)``; or two mesh objects,
        ``correspond(mesh_1, mesh_2)`` — :class:`PreparedMesh` (to reuse per-mesh
        precomputations), ``trimesh.Trimesh``, Open3D ``TriangleMesh``, pymeshlab ``Mesh`` or a
        ``(V, F)`` pair; objects are converted by :func:`geoshape.io.interop.as_arrays`, vertex
        order kept, so ``p2p_12`` indexes the objects' own vertices.
    method : str
        One of :data:`CORRESPONDENCE_METHODS`.
    **options
        Method options, e.g. ``k``, ``reorder`` ({"exhaustive", "greedy", "pairwise"}),
        ``icp_iterations``, ``anchors``, ``bijective``, ``scaling``, ``sigma`` (jz),
        ``n_samples`` (Nyström samples), ``seed``. For ``geoshape`` every option is a field of
        :class:`~geoshape.correspondence.pipeline.GeoshapeOptions` (``lb_k``, ``n_keep``,
        ``n_refine``, ``screen_samples``, ``zoomout_samples``, ``symmetry_completion``,
        ``prefer``, ``descriptor_map``, …), checked before any work: an unknown name or a
        value of the wrong type or range raises :class:`InvalidOptionError`.
    names : (str, str)
        How the two meshes are named in errors (the command line passes the file paths).
    blas_threads : int or None
        BLAS threads while computing (default 1). The pipeline makes many small and
        medium matrix products, for which threaded BLAS costs more than it gains — on a
        busy 2-core machine it was measured 5× slower; parallelise over pairs instead
        (``correspond-batch``). ``None`` leaves the BLAS setting alone.

    Returns
    -------
    Correspondence

    Examples
    --------
    >>> c = correspond(V1, F1, V2, F2)  # doctest: +SKIP
    >>> c.p2p_12.shape  # doctest: +SKIP
    (5000,)

    Notes
    -----
    ``geoshape`` on two 5k-vertex meshes: two Nyström embeddings O(l n log n), the
    exhaustive reordering O(k! 2^k s^2) on s = 300 samples, n_keep × (TPS-ICP O(c^3) +
    ZoomOut O(iter · s^2 k)), two Laplacian eigenproblems, a final map O(n1 n2 k)
    (O(n1 c k) with c = 64 spatial candidates above 1000 vertices); symmetry completion
    adds one screening and refinement of mesh 2 against itself. Measured times are in
    docs/RESULTS.md (``geoshape bench correspondence``).
    """
    check_choice("correspondence method", method, CORRESPONDENCE_METHODS)
    if "scaling" in options:
        from geoshape.spectral.embedding import SCALINGS

        check_choice("eigenvector scaling", options["scaling"], SCALINGS)
    if "reorder" in options:
        check_choice("reordering method", options["reorder"], REORDER_METHODS)
    if method == "geoshape":  # every option checked before any work on the meshes
        options = GeoshapeOptions.from_options(options)
    from geoshape.io.interop import is_mesh_object

    if V2 is None and F2 is None and F1 is not None and (isinstance(F1, PreparedMesh) or is_mesh_object(F1)):
        V2, F1 = F1, None  # correspond(mesh_1, mesh_2) with two mesh objects
    m1 = _prepared(V1, F1, names[0])
    m2 = _prepared(V2, F2, names[1])
    from geoshape import parallel

    with parallel.blas_threads(blas_threads, openmp=True):
        return _dispatch(m1, m2, method, options)


def _dispatch(m1: PreparedMesh, m2: PreparedMesh, method: str, options) -> Correspondence:
    """Run ``method``; ``options`` is a :class:`GeoshapeOptions` for ``geoshape``, else a dict
    of keyword options."""
    t0 = time.perf_counter()
    try:
        if method == "geoshape":
            if not isinstance(options, GeoshapeOptions):
                options = GeoshapeOptions.from_options(options)
            result = run_geoshape(m1, m2, options)
        elif method == "jz":
            result = _jz(m1, m2, **options)
        elif method == "shapiro-brady":
            result = _shapiro_brady(m1, m2, scaling="none", name=method, **options)
        elif method == "improved-sb":
            result = _shapiro_brady(m1, m2, scaling="sqrt", name=method, **options)
        elif method == "rigid-icp":
            result = _rigid(m1, m2, **options)
        else:
            result = _shape_context(m1, m2, **options)
    except TypeError as exc:
        if "unexpected keyword" in str(exc):
            raise InvalidOptionError(f"method {method!r}: {exc}") from None
        raise
    result.timings["total"] = time.perf_counter() - t0
    result.p2p_12 = np.asarray(result.p2p_12, dtype=np.int64)
    return result
