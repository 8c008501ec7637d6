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
  only (large-mesh mode).
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
from geoshape.correspondence.orientation import orientation_score
from geoshape.correspondence.reorder import REORDER_METHODS, Alignment, align_embeddings
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

    def cached(self, key, compute):
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

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
        from geoshape.spectral.laplacian import laplacian_basis

        best = [key for key in self._cache if key[0] == "laplacian" and key[1] >= k]
        if best:
            return self._cache[min(best)]
        return self.cached(("laplacian", k), lambda: laplacian_basis(self.V, self.F, k, name=self.name))

    def descriptor_operators(self, k: int, lb_k: int):
        """Wave kernel signature operators in the first ``k`` of ``lb_k`` eigenvectors, cached."""
        from geoshape.correspondence.fmaps.descriptor_fmap import descriptor_operators

        return self.cached(("descriptor_operators", k, lb_k), lambda: descriptor_operators(
            self.V, self.F, self.laplacian(lb_k), k=k))

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


def _spectral_candidates(m1, m2, *, k, scaling, reorder, n_keep, n_samples, seed, timings, sigma="max"):
    t = time.perf_counter()
    e1 = m1.embedding(k, scaling=scaling, sigma=sigma, n_samples=n_samples, seed=seed)
    e2 = m2.embedding(k, scaling=scaling, sigma=sigma, n_samples=n_samples, seed=seed)
    timings["embedding"] = time.perf_counter() - t
    t = time.perf_counter()
    alignments = align_embeddings(e1.coords, e2.coords, reorder, n_keep=n_keep, seed=seed)
    timings["reorder"] = time.perf_counter() - t
    return e1.coords, e2.coords, alignments


def _jz(m1, m2, *, k=5, reorder="exhaustive", icp_iterations=8, n_controls=300, anchors=3,
        proximity=True, bijective=False, n_samples=None, seed=0, n_candidates=20, scaling="sqrt",
        sigma="max"):
    timings = {}
    A, B, alignments = _spectral_candidates(m1, m2, k=k, scaling=scaling, reorder=reorder, n_keep=2,
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


def _sign_flip_variants(alignments: list, A: np.ndarray, B: np.ndarray) -> list:
    """Every other sign vector of the best alignment's column order (2^k − 1 − already kept).

    A bilateral symmetry shows up as one or more eigenvectors whose signs swap left and
    right; the cheapest candidates by the L2 cost often all share those signs, so the
    mirror map would never be tried. O(2^k s^2 k) on s = 200 samples.
    """
    import itertools

    from geoshape.correspondence.reorder import best_match_cost
    from geoshape.geometry.sampling import euclidean_farthest_point_sampling

    best = alignments[0]
    seen = {(a.perm, a.signs) for a in alignments}
    A_s, B_s = A[euclidean_farthest_point_sampling(A, 200)], B[euclidean_farthest_point_sampling(B, 200)]
    out = []
    for signs in itertools.product((1, -1), repeat=len(best.signs)):
        if (best.perm, signs) not in seen:
            trial = Alignment(best.perm, signs, 0.0)
            out.append(Alignment(best.perm, signs, best_match_cost(A_s, trial.apply(B_s))))
    return out


#: above this many vertices (either mesh) screening and refinement work on samples only
LARGE_MESH = 8000


def geodesic_distortion(m1: PreparedMesh, m2: PreparedMesh, rows1: np.ndarray, *images) -> list[float]:
    """For each map, the mean |d1(i, j) − d2(T i, T j)| over pairs of ``rows1`` (each mesh's
    distances divided by their median, so uniform scale does not count). Each of ``images``
    gives, at position ``a``, the vertex of mesh 2 matched to ``rows1[a]``. Mesh 1's rows
    are computed once. O((1 + maps) s n log n) for s rows (graph Dijkstra).
    """
    rows1 = np.asarray(rows1, dtype=np.int64)

    def normalised(mesh, rows):
        D = mesh.solver("graph").distances(rows)[:, rows]
        return D / max(float(np.median(D)), 1e-300)

    D1 = normalised(m1, rows1)
    return [float(np.mean(np.abs(D1 - normalised(m2, np.asarray(t, dtype=np.int64))))) for t in images]


def _geoshape(m1, m2, *, k=5, reorder="exhaustive", n_keep=8, n_refine=5, icp_iterations=6,
              n_controls=200, lb_k=60, screen_k=16,
              screen_samples=500, zoomout_start=6, zoomout_step=2, zoomout_samples=1500,
              n_samples=None, seed=0, symmetry_completion=True, symmetry_ratio=1.25,
              prefer="preserving", descriptor_map=True, descriptor_k=30, descriptor_ratio=1.15,
              distortion_samples=32):
    # every option, for the symmetry-completion call below (first statement: only the
    # parameters are local yet)
    settings = {name: value for name, value in locals().items() if name not in ("m1", "m2")}
    from geoshape.correspondence.fmaps.zoomout import full_resolution_map, functional_map_from_p2p, zoomout
    from geoshape.correspondence.orientation import outward_vertex_normals, patch_orientation_score
    from geoshape.geometry.sampling import euclidean_farthest_point_sampling

    timings = {}
    A, B, alignments = _spectral_candidates(m1, m2, k=k, scaling="sqrt", reorder=reorder, n_keep=n_keep,
                                            n_samples=n_samples, seed=seed, timings=timings)
    alignments = alignments + _sign_flip_variants(alignments, A, B)
    t = time.perf_counter()
    lb_k = min(lb_k, m1.n - 1, m2.n - 1)
    screen_k = min(screen_k, lb_k)
    b1, b2 = m1.laplacian(lb_k), m2.laplacian(lb_k)
    s1, s2 = m1.samples(zoomout_samples, seed), m2.samples(zoomout_samples, seed)
    # a farthest-point prefix is the shorter run itself (not so when every vertex was taken)
    c1 = s1[:screen_samples] if screen_samples <= zoomout_samples < m1.n else m1.samples(screen_samples, seed)
    c2 = s2[:screen_samples] if screen_samples <= zoomout_samples < m2.n else m2.samples(screen_samples, seed)
    timings["laplacian"] = time.perf_counter() - t
    # Large meshes: no step below touches every vertex until the final map — maps live on
    # the samples and orientation is judged on sample triples.
    large = max(m1.n, m2.n) > LARGE_MESH

    normals = (outward_vertex_normals(m1.V, m1.F), outward_vertex_normals(m2.V, m2.F)) if large else None

    def orientation(p2p, rows):
        if large:
            return patch_orientation_score(m1.V, m1.F, m2.V, m2.F, p2p, rows1=rows, seed=seed,
                                           normals=normals)
        return orientation_score(m1.V, m1.F, m2.V, m2.F, p2p)

    # 1. screen every candidate alignment by a coarse ZoomOut on few samples: the thesis'
    #    L2 reordering cost alone often ranks the right signed order only 5th-15th
    t = time.perf_counter()
    candidates = []
    # the controls of B do not depend on the signed order (FPS distances are invariant);
    # on large meshes they are matched against the refinement samples of A only
    controls = euclidean_farthest_point_sampling(B, n_controls, seed)
    A_targets = A[s1] if large else A
    for a in alignments:
        warp, _ = nonrigid_icp(A_targets, a.apply(B), n_iter=icp_iterations, controls=controls, seed=seed,
                               return_transform=True)
        init = c2[nearest(warp(a.apply(B[c2])), A[c1])[1]]  # samples of mesh 1 → samples of mesh 2
        # large meshes keep the map on the samples; otherwise every vertex of mesh 1 is
        # mapped onto the samples of mesh 2
        coarse, energy = zoomout(b1, b2, init, k_start=min(zoomout_start, screen_k), k_end=screen_k,
                                 step=zoomout_step, samples1=c1, samples2=c2, return_energy=True,
                                 samples_only=large, final_on_samples=not large)
        candidates.append({"perm": a.perm, "signs": a.signs, "cost": a.cost, "zoomout_energy": energy,
                           "orientation": orientation(coarse, c1), "p2p": coarse, "alignment": a})
    timings["screening"] = time.perf_counter() - t
    # 2. refine the most isometric candidate, and the most isometric candidates of clearly
    #    positive and of clearly negative coarse orientation (coarse scores cluster near
    #    ±0.3 for the direct and the mirrored map, near 0 for mixed ones): on coarse maps
    #    the orientation signal is weak, on refined maps it is decisive. While every
    #    refined map reverses orientation, refine the candidate of highest coarse
    #    orientation next (at most ``n_refine`` in all).
    t = time.perf_counter()
    ranked = sorted(candidates, key=lambda c: c["zoomout_energy"])
    queue = [ranked[0]]
    for side in (1.0, -1.0):  # the most isometric clearly direct and clearly mirrored candidates
        group = [c for c in ranked if np.sign(c["orientation"]) == side]
        if group:
            strongest = max(abs(c["orientation"]) for c in group)
            first = next(c for c in group if abs(c["orientation"]) >= 0.5 * strongest)
            if all(first is not q for q in queue):
                queue.append(first)
    screen_to_refine = nearest(m1.V[c1], m1.V[s1])[1] if large else None

    def refine(init, on_refinement_rows=False, k_start=screen_k):
        """ZoomOut k_start → lb_k on the refinement samples; (map, energy, orientation).

        Large meshes: the samples' map, each refinement sample starting from its nearest
        screening sample. Otherwise every vertex of mesh 1 onto the samples of mesh 2,
        enough to judge orientation.
        """
        start = init[screen_to_refine] if large and not on_refinement_rows else init
        p2p, energy = zoomout(b1, b2, start, k_start=k_start, k_end=lb_k, step=zoomout_step,
                              samples1=s1, samples2=s2, return_energy=True, samples_only=large,
                              final_on_samples=not large)
        return p2p, energy, orientation(p2p, s1)

    # r = (has the unwanted orientation, energy, map, candidate)
    unwanted = (lambda o: o <= 0) if prefer == "preserving" else (lambda o: o > 0)
    refined = []
    while queue and len(refined) < max(n_refine, 1):
        c = queue.pop(0)
        p2p, energy, orient = refine(c["p2p"])
        c.update(refined_energy=energy, refined_orientation=orient)
        refined.append((unwanted(orient), energy, p2p, c))
        if not queue and all(r[0] for r in refined):
            rest = [x for x in ranked if "refined_energy" not in x]
            if rest:
                sign = 1.0 if prefer == "preserving" else -1.0
                queue.append(max(rest, key=lambda x: (sign * x["orientation"], -x["zoomout_energy"])))
    timings["refinement"] = time.perf_counter() - t
    # 2b. an independent candidate from wave kernel signatures with an orientation term
    #     (descriptor_fmap): low eigenvectors of a body do not tell front from back, and
    #     the front-back mirror composed with the left-right one keeps orientation
    if descriptor_map and min(descriptor_k, lb_k) >= 3:
        from geoshape.correspondence.fmaps.descriptor_fmap import descriptor_functional_map
        from geoshape.correspondence.fmaps.zoomout import p2p_from_functional_map

        t = time.perf_counter()
        kd = min(descriptor_k, lb_k)
        C = descriptor_functional_map(m1.descriptor_operators(kd, lb_k), m2.descriptor_operators(kd, lb_k),
                                      orientation="preserving" if prefer == "preserving" else "reversing")
        init = p2p_from_functional_map(b1, b2, C, rows1=s1 if large else None, rows2=s2)
        p2p, energy, orient = refine(init, on_refinement_rows=True, k_start=kd)
        c = {"source": "descriptors", "perm": None, "signs": None, "alignment": None,
             "refined_energy": energy, "refined_orientation": orient}
        refined.append((unwanted(orient), energy, p2p, c))
        timings["descriptor_map"] = time.perf_counter() - t
    # 3. symmetry completion: when a map of the unwanted orientation is clearly more
    #    isometric than every map of the wanted one (energy ratio above symmetry_ratio),
    #    the wanted map is that map followed by the intrinsic left-right symmetry of mesh 2
    #    (mesh 2 matched to itself, orientation reversed). Mirror maps of a symmetric shape
    #    are as isometric as direct ones, so a ratio near 1 fires on noise: on tosca_r5k it
    #    added about 4 s to a third of the pairs and helped none.
    details = {"large_mesh_mode": large, "symmetry_completed": False}
    wrong = [r for r in refined if r[0]]
    right = [r for r in refined if not r[0]]
    if symmetry_completion and prefer == "preserving" and wrong and (
            not right or min(r[1] for r in right) > symmetry_ratio * min(r[1] for r in wrong)):
        t = time.perf_counter()
        mirror = _geoshape(m2, m2, **dict(settings, prefer="reversing", symmetry_completion=False))
        best_wrong = min(wrong, key=lambda r: r[1])
        if mirror.details["orientation"] < 0:  # mesh 2 does have an orientation-reversing self-map
            p2p, energy, orient = refine(mirror.p2p_12[best_wrong[2]], on_refinement_rows=True)
            completed = dict(best_wrong[3], refined_energy=energy, refined_orientation=orient,
                             symmetry_completed=True)
            refined.append((unwanted(orient), energy, p2p, completed))
        timings["symmetry"] = time.perf_counter() - t
    # 4. the choice: wanted orientation first, then the functional-map energy. When the
    #    descriptor candidate and the best spectral one are within descriptor_ratio in
    #    energy, the energy cannot tell them apart (stretched TOSCA meshes: the descriptor
    #    map won by 3–12 % with wrong maps; a generated biped: it lost by 1 % with the right
    #    one), so the geodesic distortion of sample pairs decides
    chosen_row = min(refined, key=lambda r: (r[0], r[1]))
    wanted = [r for r in refined if not r[0]]
    by_descriptors = [r for r in wanted if r[3].get("source") == "descriptors"]
    spectral = [r for r in wanted if r[3].get("source") != "descriptors"]
    if by_descriptors and spectral:
        d, sp = by_descriptors[0], min(spectral, key=lambda r: r[1])
        if max(d[1], sp[1]) <= descriptor_ratio * min(d[1], sp[1]):
            t = time.perf_counter()
            rows = s1[:distortion_samples] if large else c1[:distortion_samples]
            at = slice(0, len(rows)) if large else rows  # large: maps are aligned with s1
            dist_d, dist_sp = geodesic_distortion(m1, m2, rows, d[2][at], sp[2][at])
            chosen_row = d if dist_d <= dist_sp else sp
            details["distortion"] = {"descriptors": dist_d, "spectral": dist_sp}
            timings["distortion"] = time.perf_counter() - t
    _, energy, coarse, chosen = chosen_row
    details["symmetry_completed"] = bool(chosen.get("symmetry_completed", False))
    details["source"] = chosen.get("source", "spectral")
    t = time.perf_counter()
    if large:
        C = functional_map_from_p2p(b1, b2, coarse, lb_k, lb_k, rows1=s1)
        coarse = coarse[nearest(m1.V[s1], m1.V)[1]]  # each vertex: its nearest sample's image
    else:
        C = functional_map_from_p2p(b1, b2, coarse, lb_k, lb_k)
    p2p = full_resolution_map(b1, b2, C, coarse, m2.V)
    timings["full_resolution"] = time.perf_counter() - t
    keys = ("perm", "signs", "cost", "zoomout_energy", "orientation", "refined_energy", "refined_orientation")
    alts = [{key: c[key] for key in keys if key in c} for c in ranked]
    alts += [dict(source="descriptors", refined_energy=r[3]["refined_energy"],
                  refined_orientation=r[3]["refined_orientation"])
             for r in refined if r[3].get("source") == "descriptors"]
    details["orientation"] = orientation_score(m1.V, m1.F, m2.V, m2.F, p2p)
    return Correspondence(p2p, energy, "geoshape", chosen.get("alignment"), alts, timings, details)


def _shapiro_brady(m1, m2, *, scaling, name, k=5, n_samples=None, seed=0):
    timings = {}
    A, B, alignments = _spectral_candidates(m1, m2, k=k, scaling=scaling, reorder="signs", n_keep=2,
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
        ``icp_iterations``, ``anchors``, ``bijective``, ``scaling``, ``sigma`` (jz), ``lb_k``,
        ``n_keep``, ``n_refine``, ``screen_samples``, ``zoomout_samples``,
        ``symmetry_completion``, ``symmetry_ratio``, ``descriptor_map``, ``descriptor_k``,
        ``descriptor_ratio``, ``distortion_samples`` (geoshape),
        ``n_samples`` (Nyström samples), ``seed``.
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
    (O(n1 c k) with c = 64 spatial candidates above 8000 vertices); symmetry completion
    adds one screening and refinement of mesh 2 against itself. Measured times are in
    docs/RESULTS.md (``geoshape bench correspondence``).
    """
    check_choice("correspondence method", method, CORRESPONDENCE_METHODS)
    if "scaling" in options:
        from geoshape.spectral.embedding import SCALINGS

        check_choice("eigenvector scaling", options["scaling"], SCALINGS)
    if "reorder" in options:
        check_choice("reordering method", options["reorder"], REORDER_METHODS)
    from geoshape.io.interop import is_mesh_object

    if V2 is None and F2 is None and F1 is not None and (isinstance(F1, PreparedMesh) or is_mesh_object(F1)):
        V2, F1 = F1, None  # correspond(mesh_1, mesh_2) with two mesh objects
    m1 = _prepared(V1, F1, names[0])
    m2 = _prepared(V2, F2, names[1])
    from geoshape import parallel

    with parallel.blas_threads(blas_threads, openmp=True):
        return _dispatch(m1, m2, method, options)


def _dispatch(m1: PreparedMesh, m2: PreparedMesh, method: str, options: dict) -> Correspondence:
    t0 = time.perf_counter()
    try:
        if method == "geoshape":
            result = _geoshape(m1, m2, **options)
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
