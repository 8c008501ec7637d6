"""The ``geoshape`` correspondence method as a sequence of stages, with its options.

``correspond(..., method="geoshape", **options)`` checks ``options`` against
:class:`GeoshapeOptions` before any work, then :func:`run_geoshape` runs

1. :func:`candidate_alignments` — spectral embeddings and the signed eigenvector orders;
2. :func:`pair_context` — Laplace–Beltrami bases and samples of both meshes, once per pair;
3. :func:`screen_beside_descriptors` — :func:`coarse_candidate` and
   :func:`measure_coarse_distortion` of each order (warped by TPS-ICP, run through a coarse
   ZoomOut), ranked by :func:`screening_score` (the decision objective on the coarse maps),
   beside :func:`descriptor_candidates`;
4. :func:`refine` — the best-ranked screened candidates refined by ZoomOut, plus the
   descriptor candidates (wave kernel signatures), :func:`measure_distortion`,
   :func:`orientation_repair` of the best mirrored map, :func:`polish_against_repair` when
   the repaired map would win, and, when the best map is still mirrored,
   :func:`complete_symmetry`;
5. :func:`decide` — the wanted orientation, then one objective, :func:`decision_score`;
6. :func:`full_resolution` — the chosen map at every vertex of both meshes, then a
   full-resolution ZoomOut to :func:`final_basis_size` and a soft last read-off for precision.

Every candidate map is a :class:`Candidate` with its scores by name. See
docs/correspondence3d.md ("Pipeline stages") for what each stage costs.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import numbers
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from geoshape._options import check_choice
from geoshape.correspondence.icp import nonrigid_icp
from geoshape.correspondence.orientation import orientation_score
from geoshape.correspondence.reorder import REORDER_METHODS, Alignment, align_embeddings
from geoshape.errors import InvalidOptionError
from geoshape.geometry.knn import nearest, nearest_searcher
from geoshape.geometry.procrustes import kabsch

if TYPE_CHECKING:
    from geoshape.correspondence.mesh_matching import Correspondence, PreparedMesh
    from geoshape.spectral.laplacian import LaplacianBasis

#: above this many vertices (either mesh) screening and refinement work on samples only
LARGE_MESH = 8000
#: ``final_k`` is the final basis size on a mesh of this many vertices; on a larger one it
#: shrinks as 1/√n, so the eigen-solve's n k² stays what it is here (the final ZoomOut, about
#: O(n k²) per step over (k − lb_k) / final_step steps, grows slowly with k: SCAPE's 12.5k
#: vertices at 210 eigenpairs do about 1.4× the ZoomOut work of 25k at 150)
FINAL_COST_VERTICES = 25_000
#: which orientation of mapped triangles the ``prefer`` option asks for
PREFERENCES = ("preserving", "reversing")
#: scaling of the spectral embedding's columns by the eigenvalues (√λ, see spectral_embedding)
EMBEDDING_SCALING = "sqrt"
#: Dijkstra sources per call when distances are measured: full rows of O(block n) memory
DIJKSTRA_BLOCK = 64


def _int(low: int, *, none: bool = False) -> dict:
    return {"kind": "int", "low": low, "none": none}


def _float(low: float) -> dict:
    return {"kind": "float", "low": low}


_BOOL = {"kind": "bool"}


@dataclass(frozen=True)
class GeoshapeOptions:
    """Every option of the ``geoshape`` method, with its default; checked when built.

    Build it from keyword options with :meth:`from_options` (unknown names fail, listing the
    valid ones) or directly; change one with :func:`dataclasses.replace` (checked again).
    Counts of samples and eigenvectors are clipped to what a mesh has when used.
    """

    k: int = field(default=5, metadata=_int(1))
    """Eigenvectors of the spectral embedding that are reordered and sign-corrected."""
    reorder: str = "exhaustive"
    """How the signed eigenvector orders are searched: one of ``REORDER_METHODS``."""
    n_keep: int = field(default=8, metadata=_int(1))
    """Cheapest signed orders kept as candidates (every sign vector of the best is added)."""
    n_refine: int = field(default=5, metadata=_int(0))
    """At most this many screened candidates are refined (0 acts as 1): distinct ones, see below."""
    distinct_spacing: float = field(default=1.0, metadata=_float(0.0))
    """Coarse maps closer than this many sample spacings are one hypothesis, refined once (0: off)."""
    icp_iterations: int = field(default=6, metadata=_int(0))
    """TPS non-rigid ICP iterations per candidate in the spectral domain."""
    n_controls: int = field(default=200, metadata=_int(1))
    """Farthest-point control points of the thin-plate spline."""
    lb_k: int = field(default=60, metadata=_int(1))
    """Laplace–Beltrami eigenpairs of the refined functional maps (at most n − 1)."""
    # Why a cost bound: the final stage's eigen-solve costs O(n k²) and its ZoomOut more; 150 eigenpairs
    # on 25k vertices take about 10 s a pair (28k-vertex TOSCA cats: 10.8 s at 150, 15.7 s at
    # 200), and more eigenpairs keep lowering the error (docs/correspondence3d.md).
    final_k: int = field(default=150, metadata=_int(0))
    """Final ZoomOut basis size on 25k vertices, ×√(25000 / n) on n (0: no final ZoomOut)."""
    # Why 50: at 5k vertices it gives the 100 eigenpairs that keep a pair at 0.6× pyFM's time;
    # 25 (200 eigenpairs) lowered the 5k dev sets' errors by 4–12 % at twice the final stage's
    # cost. It also keeps each basis function resolved by the mesh (on a 162-vertex sphere,
    # 100 of its 161 eigenpairs turned the exact map into a rotation).
    final_vertices_per_eigenpair: float = field(default=50.0, metadata=_float(1.0))
    """The final ZoomOut uses about one eigenpair per this many vertices of the smaller mesh, at most."""
    final_step: int = field(default=5, metadata=_int(1))
    """Basis size added per iteration of the final full-resolution ZoomOut."""
    # Why a soft read-off: at 100 eigenpairs the rows of a few neighbouring vertices are about
    # as near as the best one, and the nearest neighbour picks among them by the noise of the
    # highest basis functions; the weighted mean over them is the expected position under a
    # Gibbs model of that noise, which lowers the expected error. The temperature scales with
    # each vertex's own best residual, so it has no unit. Why 0.5: of 0.5, 1 and 2 (rings 2–4)
    # on every pair of the five 5k/12k dev sets it had the lowest worst-case ratio of mean error
    # with/without (docs/correspondence3d.md); colder tends to the nearest neighbour.
    soft_temperature: float = field(default=0.5, metadata=_float(0.0))
    """Temperature of the final ZoomOut's soft last step, relative to a vertex's best residual (0: off)."""
    # Why rings, not spatial neighbours: a mean over two limbs that touch lands between them
    # (64 spatial neighbours raised some TOSCA pairs' error by 20 %). Why 3: about 37 vertices,
    # one basis function's scale at 100 eigenpairs on 5k–12k vertices; 2 gains less on SCAPE,
    # 4 raised the 5k sets slightly (same comparison as the temperature).
    soft_rings: int = field(default=3, metadata=_int(1))
    """Edge rings around a vertex's current image that the soft read-off averages over."""
    screen_k: int = field(default=16, metadata=_int(1))
    """Basis size at the end of the coarse screening ZoomOut (at most ``lb_k``)."""
    screen_samples: int = field(default=500, metadata=_int(1))
    """Farthest-point samples per mesh on which candidates are screened."""
    zoomout_start: int = field(default=6, metadata=_int(1))
    """Basis size at the start of the screening ZoomOut."""
    zoomout_step: int = field(default=2, metadata=_int(1))
    """Basis size added per ZoomOut iteration."""
    zoomout_samples: int = field(default=1500, metadata=_int(1))
    """Farthest-point samples per mesh on which candidates are refined."""
    n_samples: int | None = field(default=None, metadata=_int(1, none=True))
    """Nyström samples of the spectral embedding (None: the embedding's default)."""
    seed: int = field(default=0, metadata=_int(0))
    """Seed of every sampling (results are deterministic for a given seed)."""
    symmetry_completion: bool = field(default=True, metadata=_BOOL)
    """If the best-scoring map is mirrored, also try it composed with mesh 2's own mirror."""
    prefer: str = "preserving"
    """Orientation of mapped triangles to choose: ``"preserving"`` or ``"reversing"`` (mirror)."""
    descriptor_map: bool = field(default=True, metadata=_BOOL)
    """Add the candidate from wave kernel signatures with an orientation term."""
    descriptor_k: int = field(default=30, metadata=_int(1))
    """Basis size of the descriptor functional map (skipped below 3 after clipping to ``lb_k``)."""
    distortion_samples: int = field(default=128, metadata=_int(1))
    """Farthest samples of mesh 1 whose pairwise geodesics measure a refined map's distortion."""
    # Why 2: squaring weighs a few large distance changes — a limb or half the body sent to
    # the other side, as in a half-turn — over the spread of small ones every refined map has
    # from remeshing and sampling, and (stress = RMS²) doubles the distortion's weight against
    # the energy in decision_score; power 1 let the half-turns of remeshed SCAPE and TOSCA
    # through, and so does the RMS at equal weight. Screening keeps power 1: coarse maps land
    # on 500 samples, where the small spread is most of the signal.
    distortion_power: float = field(default=2.0, metadata=_float(0.5))
    """Power p of the decision's distortion, the mean of |distance change|^p (2: the stress of metric MDS)."""
    orientation_repair: bool = field(default=True, metadata=_BOOL)
    """Add the best mirrored map re-solved with the orientation term, pinned by its ends."""
    repair_landmarks: int = field(default=8, metadata=_int(1))
    """Landmarks pinning the orientation repair: the first farthest samples of mesh 1 (a body's ends)."""
    polish_wanted: bool = field(default=True, metadata=_BOOL)
    """When the repaired map would win, also re-solve the best other wanted map the same way."""
    # Why 1 %: a patch then spans about a limb's width on a body, where a front↔back half-turn
    # shows (a foot mapped onto a heel); on the candidate pools of the five 5k-vertex dev sets
    # 0.5 %, 1 % and 2 % ranked all 22 right/wrong twins alike (docs/correspondence3d.md). The
    # ape-like family, added later, has 3 such twins, all ranked wrong (Known limitations).
    rigidity_patch: float = field(default=0.01, metadata=_float(0.0))
    """Share of refinement samples per patch of the rigidity deciding repaired vs polished (0: off)."""
    # Why ranks: two bodies of different build (a heavy ape and a slim human) curve alike in
    # kind where they correspond, but not by the same amount, and a squared difference of values
    # charges the right map for that; the quantile of each point within its own mesh's field is
    # unchanged by any increasing transformation of the curvature, so it compares kind with kind.
    # Off: with the curvature also screening the coarse maps, ranks lowered the ape-like
    # family's symmetry-aware error on its remeshed copy from 0.150 to 0.131, but raised the
    # arm-length family's (0.075 → 0.086; its remeshed copy 0.071 → 0.125 on the first 24
    # pairs), past that family's 0.10 bound (docs/correspondence3d.md).
    curvature_ranks: bool = field(default=False, metadata=_BOOL)
    """Compare the two curvature fields by each point's quantile within its own mesh (False: by value)."""

    def __post_init__(self):
        check_choice("geoshape option reorder", self.reorder, REORDER_METHODS)
        check_choice("geoshape option prefer", self.prefer, PREFERENCES)
        for f in dataclasses.fields(self):
            rule, value = f.metadata, getattr(self, f.name)
            if not rule:
                continue
            if rule["kind"] == "bool":
                if not isinstance(value, (bool, np.bool_)):
                    raise InvalidOptionError(f"geoshape option {f.name} must be True or False, got {value!r}")
            elif rule["kind"] == "float":
                if (not isinstance(value, numbers.Real) or isinstance(value, (bool, np.bool_))
                        or not np.isfinite(value) or value < rule["low"]):
                    raise InvalidOptionError(
                        f"geoshape option {f.name} must be a number >= {rule['low']:g}, got {value!r}")
            elif rule["kind"] == "int":
                if value is None and rule["none"]:
                    continue
                if (not isinstance(value, numbers.Integral) or isinstance(value, (bool, np.bool_))
                        or value < rule["low"]):
                    what = "None or an integer" if rule["none"] else "an integer"
                    raise InvalidOptionError(
                        f"geoshape option {f.name} must be {what} >= {rule['low']}, got {value!r}")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The option names, in the order of the fields."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def from_options(cls, options: Mapping) -> GeoshapeOptions:
        """The options object of keyword ``options``; an unknown name (a misspelling, or an
        option of another method) raises :class:`InvalidOptionError` listing the valid ones.

        >>> GeoshapeOptions.from_options({"lb_k": 40}).lb_k
        40
        """
        valid = cls.names()
        unknown = [name for name in options if name not in valid]
        if unknown:
            hints = [f"{name!r} (did you mean {close[0]!r}?)" if (close := difflib.get_close_matches(
                name, valid, n=1)) else repr(name) for name in unknown]
            raise InvalidOptionError(
                f"method 'geoshape': unexpected keyword option {', '.join(hints)}; "
                f"valid options: {', '.join(valid)}")
        return cls(**options)


@dataclass(eq=False)
class Candidate:
    """One candidate map of mesh 1 onto mesh 2, with its scores by name.

    Screening fills ``coarse_map``, ``zoomout_energy`` and ``coarse_distortion``
    (``orientation`` only when :func:`refine` needs it); refinement fills
    ``refined_map``, ``refined_energy``, ``refined_orientation`` and ``unwanted``;
    :func:`measure_distortion` fills ``distortion``. Energies are ‖CᵀC − I‖_F / k of the functional map C
    (0 for an isometry, lower is better); orientation scores are in [−1, 1] (+1: every
    mapped triangle keeps its orientation, −1: a mirror image).
    """

    source: str = "spectral"
    """``"spectral"`` (a signed eigenvector order), ``"descriptors"`` (wave kernel signatures) or
    ``"repaired"`` (:func:`orientation_repair`)."""
    alignment: Alignment | None = None
    """The signed column order of mesh 2's embedding (spectral candidates), else None."""
    coarse_map: np.ndarray | None = None
    """Screening map: every vertex of mesh 1 → samples of mesh 2 (large meshes: screening samples only)."""
    zoomout_energy: float | None = None
    """Functional-map energy after the coarse screening ZoomOut."""
    orientation: float | None = None
    """Orientation score of the coarse map (:func:`coarse_orientation`; None until asked for)."""
    coarse_distortion: float | None = None
    """:func:`geodesic_distortion` of the coarse map (screening ranks by :func:`screening_score`)."""
    coarse_curvature: float | None = None
    """:func:`curvature_disagreement` of the coarse map on the screening samples (None: 1)."""
    refined_map: np.ndarray | None = None
    """Refined map: every vertex of mesh 1 → refinement samples of mesh 2 (large: samples only)."""
    refined_energy: float | None = None
    """Functional-map energy after the refining ZoomOut to ``lb_k``."""
    refined_orientation: float | None = None
    """Orientation score of the refined map."""
    unwanted: bool | None = None
    """The refined map has the orientation that ``prefer`` does not ask for."""
    orientation_share: float | None = None
    """``(1 ± refined_orientation) / 2``: share of the surface mapped with the orientation asked for."""
    symmetry_completed: bool = False
    """The map is a mirrored map composed with mesh 2's own left–right symmetry."""
    distortion: float | None = None
    """Geodesic distortion of the refined map: its mean normalised geodesic distortion to the
    power ``distortion_power`` (:func:`geodesic_distortion`; default 2, the stress)."""
    curvature_disagreement: float | None = None
    """:func:`curvature_disagreement` of the refined map (0: it carries mesh 1's mean curvature
    field onto mesh 2's exactly; 1: no better than pairing samples at random)."""
    rigidity: float | None = None
    """:func:`local_rigidity` of the refined map (0: a rotation and uniform scaling on every
    patch), measured for the repaired and polished maps only (:func:`measure_rigidity`)."""

    @property
    def cost(self) -> float | None:
        """The thesis' L2 best-match cost of the signed order (spectral candidates)."""
        return None if self.alignment is None else self.alignment.cost

    @property
    def refined(self) -> bool:
        """Whether the refinement stage has run on this candidate."""
        return self.refined_map is not None

    def summary(self) -> dict:
        """The candidate as one entry of ``Correspondence.alternatives`` (JSON output)."""
        if self.alignment is None:
            out = {"source": self.source}
        else:
            a = self.alignment
            out = {"perm": a.perm, "signs": a.signs, "cost": a.cost, "zoomout_energy": self.zoomout_energy}
            if self.orientation is not None:
                out["orientation"] = self.orientation
            if self.coarse_distortion is not None:
                out["coarse_distortion"] = self.coarse_distortion
            if self.coarse_curvature is not None:
                out["coarse_curvature"] = self.coarse_curvature
        if self.refined:
            out.update(refined_energy=self.refined_energy, refined_orientation=self.refined_orientation)
        if self.distortion is not None:
            out["distortion"] = self.distortion
        if self.curvature_disagreement is not None:
            out["curvature_disagreement"] = self.curvature_disagreement
        if self.rigidity is not None:
            out["rigidity"] = self.rigidity
        return out


@dataclass(frozen=True, eq=False)
class PairContext:
    """Per-pair precomputations shared by the stages (built by :func:`pair_context`)."""

    m1: PreparedMesh
    m2: PreparedMesh
    A: np.ndarray
    """(n1, k) spectral embedding of mesh 1."""
    B: np.ndarray
    """(n2, k) spectral embedding of mesh 2 (columns in its own order)."""
    b1: LaplacianBasis
    b2: LaplacianBasis
    lb_k: int
    """Eigenpairs used: ``lb_k`` clipped to n − 1 of both meshes."""
    final_k: int
    """Final ZoomOut basis size (:func:`final_basis_size`), at least ``lb_k``."""
    screen_k: int
    """``screen_k`` clipped to ``lb_k``."""
    s1: np.ndarray
    """Refinement samples of mesh 1 (``zoomout_samples`` farthest points)."""
    s2: np.ndarray
    c1: np.ndarray
    """Screening samples of mesh 1 (``screen_samples`` farthest points)."""
    c2: np.ndarray
    large: bool
    """Large-mesh mode: maps live on samples until :func:`full_resolution`."""
    normals: tuple | None
    """Outward vertex normals of both meshes (large-mesh mode only)."""
    screen_to_refine: np.ndarray | None
    """Large-mesh mode: for each refinement sample, its nearest screening sample (index in ``c1``)."""
    seed: int


def spectral_alignments(m1: PreparedMesh, m2: PreparedMesh, *, k, scaling, reorder, n_keep, n_samples,
                        seed, timings: dict, sigma="max"):
    """Both meshes' spectral embeddings and the cheapest signed column orders of mesh 2's.

    Returns ``(A (n1, k), B (n2, k), alignments)``, cheapest first (``n_keep`` of them).
    Nyström embeddings O(l n log n), then :func:`embedding_alignments`.
    Shared by every spectral method (``jz``, ``shapiro-brady``, ``improved-sb``).
    """
    t = time.perf_counter()
    e1 = m1.embedding(k, scaling=scaling, sigma=sigma, n_samples=n_samples, seed=seed)
    e2 = m2.embedding(k, scaling=scaling, sigma=sigma, n_samples=n_samples, seed=seed)
    timings["embedding"] = timings.get("embedding", 0.0) + time.perf_counter() - t
    return embedding_alignments(e1, e2, reorder=reorder, n_keep=n_keep, seed=seed, timings=timings)


def embedding_alignments(e1, e2, *, reorder, n_keep, seed, timings: dict):
    """``(A (n1, k), B (n2, k), alignments)`` of two spectral embeddings: the ``n_keep``
    cheapest signed column orders of ``e2``'s, cheapest first. Exhaustive reordering
    O(k! 2^k s^2) on s = 200 samples (shared with a second core)."""
    t = time.perf_counter()
    alignments = align_embeddings(e1.coords, e2.coords, reorder, n_keep=n_keep, seed=seed, beside=True)
    timings["reorder"] = time.perf_counter() - t
    return e1.coords, e2.coords, alignments


def sign_flip_variants(alignments: list, A: np.ndarray, B: np.ndarray) -> list:
    """Every other sign vector of the best alignment's column order (2^k − 1 − already kept).

    A bilateral symmetry shows up as one or more eigenvectors whose signs swap left and
    right; the cheapest candidates by the L2 cost often all share those signs, so the
    mirror map would never be tried. O(2^k s^2 k) on s = 200 samples.
    """
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


def candidate_alignments(m1: PreparedMesh, m2: PreparedMesh, options: GeoshapeOptions, timings: dict):
    """Stage 1: ``(A (n1, k), B (n2, k), alignments)`` — the ``n_keep`` cheapest signed
    orders of √λ-scaled embeddings, then every other sign vector of the best order
    (up to n_keep + 2^k − 1 alignments). The embeddings are :func:`_alignment_embedding`'s,
    so the one a child computed beside the eigen-solve is the one used. Cost: the Nyström
    embeddings (cached), :func:`embedding_alignments` and :func:`sign_flip_variants`.
    """
    t = time.perf_counter()
    e1, e2 = _alignment_embedding(m1, options), _alignment_embedding(m2, options)
    timings["embedding"] = timings.get("embedding", 0.0) + time.perf_counter() - t
    A, B, alignments = embedding_alignments(e1, e2, reorder=options.reorder, n_keep=options.n_keep,
                                            seed=options.seed, timings=timings)
    return A, B, alignments + sign_flip_variants(alignments, A, B)


def refined_basis_size(m1: PreparedMesh, m2: PreparedMesh, options: GeoshapeOptions) -> int:
    """Eigenpairs of the refined functional maps: ``lb_k`` clipped to n − 1 of both meshes."""
    return min(options.lb_k, m1.n - 1, m2.n - 1)


def final_basis_size(m1: PreparedMesh, m2: PreparedMesh, options: GeoshapeOptions) -> int:
    """Eigenpairs of each mesh's one eigen-solve: the smaller of a resolution bound, one per
    ``final_vertices_per_eigenpair`` vertices of the smaller mesh, and a cost bound,
    ``final_k`` × √(:data:`FINAL_COST_VERTICES` / n) for the larger mesh's n (the eigen-solve's
    n k² held constant); rounded to the nearest multiple of ``final_step`` (so it may exceed
    a bound by up to half a step), at least ``lb_k`` (clipped to n − 1); ``lb_k`` means no
    final ZoomOut (``final_k`` = 0 turns it off). 5k vertices: 100; 12.5k: 210; 28k: 140; 50k:
    105 (with the defaults); below about 3k vertices (the resolution bound) and above about
    140k (the cost bound) it falls to ``lb_k`` and the final ZoomOut is skipped.
    """
    lb_k = refined_basis_size(m1, m2, options)
    by_resolution = min(m1.n, m2.n) / options.final_vertices_per_eigenpair
    by_cost = options.final_k * np.sqrt(FINAL_COST_VERTICES / max(m1.n, m2.n))
    step = options.final_step
    k = step * int(min(by_resolution, by_cost) / step + 0.5)  # the nearest multiple (both ≥ 0)
    return int(max(lb_k, min(k, m1.n - 1, m2.n - 1)))


#: the per-mesh cache entries a stage run :func:`~geoshape.parallel.beside` the others hands back
_SHARED_CACHES = ("laplacian", "embedding", "descriptor_operators", "curvature_field")


def _with_new_caches(fn, meshes: tuple, *args):
    """``(fn(*args), entries)``: also the :data:`_SHARED_CACHES` entries ``fn`` added to each
    mesh's cache, so that a forked stage's eigen-solves and operators reach the parent."""
    before = [m.cache_keys() for m in meshes]
    value = fn(*args)
    return value, [m.cache_entries(_SHARED_CACHES, since) for m, since in zip(meshes, before, strict=True)]


def _adopted(outcome: tuple, meshes: tuple):
    """The value of a :func:`_with_new_caches` outcome, its cache entries stored in ``meshes``."""
    value, entries = outcome
    for m, new in zip(meshes, entries, strict=True):
        m.add_cache_entries(new)
    return value


def _alignment_embedding(m: PreparedMesh, options: GeoshapeOptions):
    """``m``'s spectral embedding as :func:`candidate_alignments` asks for it (cached)."""
    return m.embedding(options.k, scaling=EMBEDDING_SCALING, n_samples=options.n_samples, seed=options.seed)


def _eigenpairs_and_embedding(m: PreparedMesh, k: int, options: GeoshapeOptions, lb_k: int) -> float:
    """``m``'s ``k`` Laplace–Beltrami eigenpairs, :func:`_alignment_embedding` and its curvature
    field at ``lb_k`` eigenpairs (:func:`measure_distortion` reads it; all cached); returns the
    seconds taken."""
    t = time.perf_counter()
    m.laplacian(k)
    _alignment_embedding(m, options)
    m.curvature_field(lb_k)
    return time.perf_counter() - t


def _timed(stage, *args) -> tuple:
    """``(stage(*args, timings), timings)`` with a fresh ``timings`` dict: a stage run in a child
    hands its timings back with its value."""
    timings: dict = {}
    return stage(*args, timings), timings


def screen_beside_descriptors(ctx: PairContext, alignments: list, options: GeoshapeOptions,
                              timings: dict) -> tuple[list[Candidate], list[Candidate]]:
    """Stages 3 and 4b together: ``(screened, descriptor candidates)``. A child
    (:func:`~geoshape.parallel.map_beside_after`) computes the descriptor candidates, then
    joins this process in taking the next alignment left for :func:`coarse_candidate`;
    this process also measures the coarse distortion of its own as it goes (Dijkstra rows
    stay cached here), then of the child's. The same candidates whoever computes them."""
    from geoshape.parallel import map_beside_after

    t = time.perf_counter()
    controls, icp_search = screening_controls(ctx, options), icp_target_searcher(ctx)

    def coarse(a):
        return coarse_candidate(ctx, a, controls, options, icp_search)

    def coarse_and_distortion(a):
        c = coarse(a)
        measure_coarse_distortion(ctx, [c], options)
        return c

    meshes = (ctx.m1, ctx.m2)
    first, screened = map_beside_after(
        lambda: _with_new_caches(_timed, meshes, descriptor_candidates, ctx, options),
        coarse, alignments, here=coarse_and_distortion)
    described, side_timings = _adopted(first, meshes)
    measure_coarse_distortion(ctx, [c for c in screened if c.coarse_distortion is None], options)
    timings["screening"] = time.perf_counter() - t
    timings.update({f"{key} (beside)": value for key, value in side_timings.items()})
    return screened, described


def pair_context(m1: PreparedMesh, m2: PreparedMesh, A: np.ndarray, B: np.ndarray, options: GeoshapeOptions,
                 timings: dict) -> PairContext:
    """Stage 2: Laplace–Beltrami bases (``lb_k`` eigenpairs), refinement and screening samples
    of both meshes, and in large-mesh mode the vertex normals. Two sparse eigenproblems
    (cached per mesh), farthest-point sampling O(n s); O(n lb_k) memory per mesh.
    """
    t = time.perf_counter()
    seed = options.seed
    lb_k = refined_basis_size(m1, m2, options)
    screen_k = min(options.screen_k, lb_k)
    final_k = final_basis_size(m1, m2, options)
    m1.laplacian(final_k), m2.laplacian(final_k)  # one eigen-solve per mesh for every stage
    b1, b2 = m1.laplacian(lb_k), m2.laplacian(lb_k)
    zs, ss = options.zoomout_samples, options.screen_samples
    s1, s2 = m1.samples(zs, seed), m2.samples(zs, seed)
    # a farthest-point prefix is the shorter run itself (not so when every vertex was taken)
    c1 = s1[:ss] if ss <= zs < m1.n else m1.samples(ss, seed)
    c2 = s2[:ss] if ss <= zs < m2.n else m2.samples(ss, seed)
    timings["laplacian"] = time.perf_counter() - t
    # Large meshes: no step below touches every vertex until the final map — maps live on
    # the samples and orientation is judged on sample triples.
    large = max(m1.n, m2.n) > LARGE_MESH
    normals = screen_to_refine = None
    if large:
        from geoshape.geometry.mesh import outward_vertex_normals

        normals = (outward_vertex_normals(m1.V, m1.F), outward_vertex_normals(m2.V, m2.F))
        screen_to_refine = nearest(m1.V[c1], m1.V[s1])[1]
    return PairContext(m1, m2, A, B, b1, b2, lb_k, final_k, screen_k, s1, s2, c1, c2, large, normals,
                       screen_to_refine, seed)


def orientation_of(ctx: PairContext, p2p: np.ndarray, rows: np.ndarray) -> float:
    """Orientation score of a map in [−1, 1]: of every triangle (O(n1)), or in large-mesh
    mode of sample triples around ``rows`` (``p2p`` aligned with ``rows``)."""
    m1, m2 = ctx.m1, ctx.m2
    if ctx.large:
        from geoshape.correspondence.orientation import patch_orientation_score

        return patch_orientation_score(m1.V, m1.F, m2.V, m2.F, p2p, rows1=rows, seed=ctx.seed,
                                       normals=ctx.normals)
    return orientation_score(m1.V, m1.F, m2.V, m2.F, p2p)


def coarse_orientation(ctx: PairContext, c: Candidate) -> float:
    """The orientation score of a screened candidate's coarse map, computed on first use and
    stored in ``c.orientation`` (O(n1), or O(s) sample triples on large meshes). Screening does
    not compute it for every candidate: only :func:`refine`'s fallback reads it."""
    if c.orientation is None:
        c.orientation = orientation_of(ctx, c.coarse_map, ctx.c1)
    return c.orientation


def screening_controls(ctx: PairContext, options: GeoshapeOptions) -> np.ndarray:
    """The ``n_controls`` thin-plate-spline controls of mesh 2's embedding: the same for every
    signed order (farthest-point distances are invariant to it). O(n2 · n_controls · k)."""
    from geoshape.geometry.sampling import euclidean_farthest_point_sampling

    return euclidean_farthest_point_sampling(ctx.B, options.n_controls, options.seed)


def icp_targets(ctx: PairContext) -> np.ndarray:
    """The rows of mesh 1's embedding the TPS-ICP of every signed order matches against: the
    refinement samples on large meshes, else every vertex."""
    return ctx.A[ctx.s1] if ctx.large else ctx.A


def icp_target_searcher(ctx: PairContext):
    """:func:`~geoshape.geometry.knn.nearest_searcher` over :func:`icp_targets`: its KD-tree
    is built once per pair, O(n log n)."""
    return nearest_searcher(icp_targets(ctx))


def coarse_candidate(ctx: PairContext, a: Alignment, controls: np.ndarray,
                     options: GeoshapeOptions, icp_search=None) -> Candidate:
    """Stage 3 (screening, with :func:`measure_coarse_distortion`): the :class:`Candidate` of
    one alignment with its coarse map and ``zoomout_energy``: TPS-ICP O(iter c^3) on the
    ``controls``, then ZoomOut ``zoomout_start`` → ``screen_k`` on ``screen_samples`` samples
    O(iter s^2 k) (the thesis' L2 reordering cost alone often ranks the right signed order
    only 5th–15th). ``icp_search``: :func:`icp_target_searcher` (built here when not given).
    """
    from geoshape.correspondence.fmaps.zoomout import zoomout

    A, B, c1, c2, large = ctx.A, ctx.B, ctx.c1, ctx.c2, ctx.large
    warp, _ = nonrigid_icp(icp_targets(ctx), a.apply(B), n_iter=options.icp_iterations, controls=controls,
                           seed=options.seed, return_transform=True,
                           nearest_in_A=icp_target_searcher(ctx) if icp_search is None else icp_search)
    init = c2[nearest(warp(a.apply(B[c2])), A[c1])[1]]  # samples of mesh 1 → samples of mesh 2
    # large meshes keep the map on the samples; otherwise every vertex of mesh 1 is mapped
    # onto the samples of mesh 2
    coarse, energy = zoomout(ctx.b1, ctx.b2, init, k_start=min(options.zoomout_start, ctx.screen_k),
                             k_end=ctx.screen_k, step=options.zoomout_step, samples1=c1, samples2=c2,
                             return_energy=True, samples_only=large, final_on_samples=not large)
    return Candidate(source="spectral", alignment=a, coarse_map=coarse, zoomout_energy=energy)


def measure_coarse_distortion(ctx: PairContext, candidates: list[Candidate],
                              options: GeoshapeOptions) -> None:
    """Fill ``coarse_distortion`` and ``coarse_curvature`` of ``candidates``:
    :func:`geodesic_distortion` of every coarse map on the ``distortion_samples`` rows the
    decision uses (Dijkstra from the distinct images, at most ``screen_samples`` sources on
    mesh 2, cached), and :func:`curvature_disagreement` (by rank with ``curvature_ranks``) on
    every screening sample, O(s) per map after the two meshes' fields."""
    if not candidates:
        return
    rows, at = distortion_rows(ctx, ctx.c1, options.distortion_samples)
    distortions = geodesic_distortion(ctx.m1, ctx.m2, rows, *[c.coarse_map[at] for c in candidates],
                                      within=ctx.s2)
    curvatures = map_curvature_disagreements(ctx, [c.coarse_map for c in candidates], ctx.c1, ctx.c2,
                                             options)
    for c, d, h in zip(candidates, distortions, curvatures, strict=True):
        c.coarse_distortion, c.coarse_curvature = d, h


def screening_score(c: Candidate) -> float:
    """The rank of a screened candidate: :func:`decision_score` without the orientation share,
    on the coarse map (coarse distortion × coarse ZoomOut energy × coarse curvature
    disagreement; coarse orientation is too weak to count), so refinement goes to the
    candidates the decision would favour. The energy alone ranks the best-refined map
    anywhere from 1st to 37th of 38 on the non-isometric dev pairs (a thick and a slim body
    give every coarse map a similar energy); the distortion sees which parts go where, and
    the curvature which side faces front: without it a front↔back half-turn of about the
    same stress could take the right map's place among the refined ones (the ape-like
    family, docs/correspondence3d.md). An unmeasured curvature counts 1."""
    return c.coarse_distortion * c.zoomout_energy * _score_factor(c.coarse_curvature, 1e-12)


def _score_factor(value: float | None, floor: float) -> float:
    """A measured quantity as a factor of a score: 1 when unmeasured (``None``), kept at or
    above ``floor`` so a perfect value does not zero the other factors (or, as a divisor,
    blow up the score)."""
    return 1.0 if value is None else max(value, floor)


def refine_map(ctx: PairContext, init: np.ndarray, options: GeoshapeOptions, *,
               on_refinement_rows: bool = False, k_start: int | None = None):
    """ZoomOut ``k_start`` (default ``screen_k``) → ``lb_k`` on the refinement samples:
    ``(map, energy, orientation)``. O(iter s^2 lb_k) for s = ``zoomout_samples``.

    Large meshes: the samples' map, each refinement sample starting from its nearest
    screening sample (unless ``init`` is already on the refinement samples). Otherwise every
    vertex of mesh 1 onto the samples of mesh 2, enough to judge orientation.
    """
    from geoshape.correspondence.fmaps.zoomout import zoomout

    start = init[ctx.screen_to_refine] if ctx.large and not on_refinement_rows else init
    p2p, energy = zoomout(ctx.b1, ctx.b2, start, k_start=ctx.screen_k if k_start is None else k_start,
                          k_end=ctx.lb_k, step=options.zoomout_step, samples1=ctx.s1, samples2=ctx.s2,
                          return_energy=True, samples_only=ctx.large, final_on_samples=not ctx.large)
    return p2p, energy, orientation_of(ctx, p2p, ctx.s1)


def is_unwanted(orientation: float, prefer: str) -> bool:
    """Whether an orientation score is of the orientation ``prefer`` does not ask for."""
    return orientation <= 0 if prefer == "preserving" else orientation > 0


def _refine_into(ctx: PairContext, c: Candidate, init: np.ndarray, options: GeoshapeOptions,
                 **kwargs) -> Candidate:
    """Refine ``init`` and store map and scores in ``c``; returns ``c``."""
    return _store_refined(c, refine_map(ctx, init, options, **kwargs), options)


def _refine_coarse_maps(ctx: PairContext, candidates: list[Candidate],
                        options: GeoshapeOptions) -> list[Candidate]:
    """:func:`_refine_into` of each candidate's coarse map, shared with a child process
    (:func:`~geoshape.parallel.map_beside_after`: each takes the next candidate left); this
    process also measures the ``distortion`` of its own maps as it goes
    (:func:`measure_distortion`: its Dijkstra rows stay cached here, and it fills time that
    would be spent waiting for the child's last map). The same values whoever computes
    them. Returns ``candidates``."""
    from geoshape.parallel import map_beside_after

    def refine_and_measure(c):
        refined = refine_map(ctx, c.coarse_map, options)
        measure_distortion(ctx, [_store_refined(c, refined, options)], options, {})
        return refined

    _, refined = map_beside_after(None, lambda c: refine_map(ctx, c.coarse_map, options), candidates,
                                  here=refine_and_measure)
    for c, result in zip(candidates, refined, strict=True):  # the child's maps (this one's: again, same)
        _store_refined(c, result, options)
    return candidates


def _store_refined(c: Candidate, refined: tuple, options: GeoshapeOptions) -> Candidate:
    """Store :func:`refine_map`'s ``(map, energy, orientation)`` and the scores derived from it in ``c``."""
    c.refined_map, c.refined_energy, c.refined_orientation = refined
    c.unwanted = is_unwanted(c.refined_orientation, options.prefer)
    sign = 1.0 if options.prefer == "preserving" else -1.0
    c.orientation_share = (1.0 + sign * c.refined_orientation) / 2.0
    return c


def distinct_hypotheses(ctx: PairContext, ranked: list[Candidate], n: int,
                        spacings: float) -> tuple[list[Candidate], list[Candidate]]:
    """``(picked, rest)``: the first ``n`` of ``ranked`` whose coarse maps each differ from every
    earlier pick, in ranked order, and the others (in ranked order).

    Two coarse maps are one hypothesis when the images of mesh 1's screening samples lie on
    average closer than ``spacings`` × the screening-sample spacing of mesh 2
    (√(area / ``screen_samples``)): coarse maps land on those samples, so maps closer than one
    spacing differ by at most a neighbouring sample, and refining both spends a refinement
    on the same map. Sign variants of one eigenvector order often give the same map (the
    flipped eigenvectors are ones the coarse ZoomOut overrides); without this rule five
    copies of one mirrored map could take every refinement. Unit-free. O(len(ranked) · n · s)
    for s screening samples (Euclidean distances between images).
    """
    if spacings <= 0:
        return list(ranked[:n]), list(ranked[n:])
    limit = hypothesis_spacing(ctx, spacings)
    picked, rest, images = [], [], []
    for c in ranked:
        image = coarse_image(ctx, c) if len(picked) < n else None
        if image is not None and is_new_hypothesis(image, images, limit):
            picked.append(c)
            images.append(image)
        else:
            rest.append(c)
    return picked, rest


def coarse_image(ctx: PairContext, c: Candidate) -> np.ndarray:
    """``(s, 3)``: where the coarse map of ``c`` sends mesh 1's screening samples, in space."""
    _, at = distortion_rows(ctx, ctx.c1, len(ctx.c1))
    return ctx.m2.V[c.coarse_map[at]]


def hypothesis_spacing(ctx: PairContext, spacings: float) -> float:
    """``spacings`` screening-sample spacings of mesh 2, √(area / screening samples) each."""
    return spacings * float(np.sqrt(ctx.m2.area / len(ctx.c2)))


def is_new_hypothesis(image: np.ndarray, images: list[np.ndarray], limit: float) -> bool:
    """Whether a :func:`coarse_image` lies, on average over the samples, at least ``limit`` from
    each of ``images`` (the rule of :func:`distinct_hypotheses`). O(len(images) · s)."""
    return all(np.linalg.norm(image - other, axis=1).mean() >= limit for other in images)


def refine(ctx: PairContext, ranked: list[Candidate], options: GeoshapeOptions,
           timings: dict) -> list[Candidate]:
    """Stage 4: refine the ``max(n_refine, 1)`` first distinct hypotheses of ``ranked`` (sorted
    by :func:`screening_score`, whatever their coarse orientation: coarse orientation is weak;
    :func:`distinct_hypotheses`); while every refined map has the unwanted orientation, refine
    the candidate of most wanted coarse orientation next, at most ``max(n_refine, 1)`` more,
    skipping copies of maps already refined (:func:`is_new_hypothesis`; with
    ``distinct_spacing`` 0 nothing is a copy).
    Fills the refined scores and returns the refined candidates in the order refined;
    O(n_refine · iter s^2 lb_k).
    """
    t = time.perf_counter()
    n = max(options.n_refine, 1)
    picked, rest = distinct_hypotheses(ctx, ranked, n, options.distinct_spacing)
    refined = _refine_coarse_maps(ctx, picked, options)
    sign = 1.0 if options.prefer == "preserving" else -1.0
    limit = hypothesis_spacing(ctx, options.distinct_spacing)
    images = None  # coarse images of the refined maps and of the rest, once the fallback runs
    for _ in range(n):
        if not all(r.unwanted for r in refined):
            break
        if images is None:
            images = {id(c): coarse_image(ctx, c) for c in refined + rest}
        rest = [c for c in rest
                if is_new_hypothesis(images[id(c)], [images[id(r)] for r in refined], limit)]
        if not rest:
            break
        c = max(rest, key=lambda x: (sign * coarse_orientation(ctx, x), -x.zoomout_energy))
        rest.remove(c)
        refined.append(_refine_into(ctx, c, c.coarse_map, options))
    timings["refinement"] = time.perf_counter() - t
    return refined


def descriptor_candidates(ctx: PairContext, options: GeoshapeOptions, timings: dict) -> list[Candidate]:
    """Stage 4b: refined candidates independent of the eigenvector alignment, from the
    functional map of wave kernel signatures with an orientation term (low eigenvectors of
    a body do not tell front from back, and the front–back mirror composed with the
    left–right one keeps orientation). Empty when ``descriptor_map`` is off or fewer than 3
    eigenpairs are usable. A least-squares problem in kd^2 unknowns (kd = ``descriptor_k``),
    then one refinement from kd; when ``screen_k`` < kd, a second candidate restarts from
    that refined map at ``screen_k`` eigenpairs, as every spectral candidate is refined
    (the descriptor map's high frequencies are its least reliable part; the decision keeps
    whichever of the two scores better). Two refinements.
    """
    kd = min(options.descriptor_k, ctx.lb_k)
    if not (options.descriptor_map and kd >= 3):
        return []
    from geoshape.correspondence.fmaps.descriptor_fmap import descriptor_functional_map
    from geoshape.correspondence.fmaps.zoomout import functional_map_from_p2p, p2p_from_functional_map

    t = time.perf_counter()
    m1, m2, lb_k = ctx.m1, ctx.m2, ctx.lb_k
    rows1 = ctx.s1 if ctx.large else None
    C = descriptor_functional_map(m1.descriptor_operators(kd, lb_k), m2.descriptor_operators(kd, lb_k),
                                  orientation=options.prefer)
    init = p2p_from_functional_map(ctx.b1, ctx.b2, C, rows1=rows1, rows2=ctx.s2)
    out = [_refine_into(ctx, Candidate("descriptors"), init, options, on_refinement_rows=True, k_start=kd)]
    ks = ctx.screen_k
    if ks < kd:
        C = functional_map_from_p2p(ctx.b1, ctx.b2, out[0].refined_map, ks, ks, rows1=rows1)
        init = p2p_from_functional_map(ctx.b1, ctx.b2, C, rows1=rows1, rows2=ctx.s2)
        out.append(_refine_into(ctx, Candidate("descriptors"), init, options, on_refinement_rows=True,
                                k_start=ks))
    timings["descriptor_map"] = time.perf_counter() - t
    return out


def orientation_repair(ctx: PairContext, refined: list[Candidate], options: GeoshapeOptions,
                       timings: dict) -> list[Candidate]:
    """Stage 4c: the maps of :func:`repair_sources` (of the unwanted orientation: the best by
    :func:`decision_score` and the most isometric, one or two maps), each re-solved as a
    functional map with the orientation term and descriptors pinned by its own ends
    (:func:`landmark_resolve`); empty when no refined map has the unwanted orientation (or
    ``orientation_repair`` is off, or fewer than 3 eigenpairs are usable).
    :func:`polish_against_repair` may follow.

    Why: on a human body the spectral candidates can come out mirrored front↔back on the
    torso only, with the hands, feet and head in the right place (orientation score about
    −0.6, not −0.9); neither the decision nor composing with mesh 2's own symmetries turns
    that into the right map. Its landmarks — the first ``repair_landmarks`` farthest samples
    of mesh 1, the ends of a body, and their images — still tell left from right. Their
    geodesic distance functions (÷ √area of each mesh) as descriptors, with the
    multiplication and orientation commutativity terms of :func:`descriptor_functional_map`,
    leave one consistent map: the orientation-preserving one through the same ends. On a
    plain left–right mirror the same problem gives the half-turn, which competes in the
    decision like any candidate. Cost per repaired map: Dijkstra from the landmarks on both
    meshes (mesh 1's once), the operators O(m kd (kd + L)), one kd² solve and one refinement
    from kd (kd = ``descriptor_k``).
    A trial that also repaired the best descriptor map gained nothing (remeshed SCAPE,
    tosca_r5k, non-isometric dev sets) and cost one more solve.
    """
    sources = repair_sources(ctx, refined, options)
    if not sources:
        return []
    t = time.perf_counter()
    out = [landmark_resolve(ctx, source, options, "repaired") for source in sources]
    timings["orientation_repair"] = time.perf_counter() - t
    return out


def polish_against_repair(ctx: PairContext, refined: list[Candidate], options: GeoshapeOptions,
                          timings: dict) -> list[Candidate]:
    """Stage 4c′: when the repaired map (:func:`orientation_repair`, its distortion measured)
    would win :func:`decide`, the other map of the wanted orientation with the lowest
    :func:`decision_score` re-solved the same way (:func:`landmark_resolve`), so that the
    decision compares like with like (a list of one; empty when ``polish_wanted`` is off or
    the repair would not win).

    Why: a map re-solved from landmark distance functions keeps geodesic distances better
    than one that was not, whatever its error: on a stretched pair the repaired half-turn had
    a lower stress than the right map (docs/correspondence3d.md). The polished map is often
    also the more precise one. Only when the repair would decide, so the cost (one solve and
    one refinement, mesh 1's operators reused from the repair) is paid where it matters.
    Polishing every wanted map instead was no better on the non-isometric dev sets and costs
    one solve per map (docs/correspondence3d.md).
    """
    if not (options.polish_wanted and refined and decide(refined).source == "repaired"):
        return []
    others = [c for c in refined if not c.unwanted and c.source != "repaired"]
    if not others:
        return []
    t = time.perf_counter()
    out = [landmark_resolve(ctx, min(others, key=decision_score), options, "polished")]
    timings["polish"] = time.perf_counter() - t
    return out


def _landmark_operators(m: PreparedMesh, basis, landmarks: np.ndarray, kd: int):
    """Descriptor operators (``kd`` eigenpairs) of the geodesic distance functions of ``landmarks``."""
    from geoshape.correspondence.fmaps.descriptor_fmap import operators_of_descriptors

    return operators_of_descriptors(m.V, m.F, basis, _distance_functions(m, landmarks), k=kd)


def landmark_resolve(ctx: PairContext, source: Candidate, options: GeoshapeOptions, name: str) -> Candidate:
    """``source``'s refined map re-solved as a functional map with the orientation term and,
    as descriptors, the geodesic distance functions of :func:`repair_landmarks` on mesh 1 and
    of their images under ``source`` on mesh 2, then refined from ``descriptor_k``: a new
    :class:`Candidate` named ``name``. Cost: Dijkstra from the landmarks (mesh 1's operators
    cached per pair), the operators O(m kd (kd + L)), one kd² solve, one refinement."""
    from geoshape.correspondence.fmaps.descriptor_fmap import descriptor_functional_map
    from geoshape.correspondence.fmaps.zoomout import p2p_from_functional_map

    kd = min(options.descriptor_k, ctx.lb_k)
    ends1, at = repair_landmarks(ctx, options)
    # mesh 1's side is the same for the repair and the polish: cached per landmark set and size
    ops1 = ctx.m1.cached(("landmark_operators", ends1.tobytes(), kd, ctx.lb_k),
                         lambda: _landmark_operators(ctx.m1, ctx.b1, ends1, kd))
    ops2 = _landmark_operators(ctx.m2, ctx.b2, source.refined_map[at], kd)
    C = descriptor_functional_map(ops1, ops2, orientation=options.prefer)
    init = p2p_from_functional_map(ctx.b1, ctx.b2, C, rows1=ctx.s1 if ctx.large else None, rows2=ctx.s2)
    return _refine_into(ctx, Candidate(name), init, options, on_refinement_rows=True, k_start=kd)


def repair_sources(ctx: PairContext, refined: list[Candidate], options: GeoshapeOptions) -> list[Candidate]:
    """The refined maps :func:`orientation_repair` re-solves, all of the unwanted orientation:
    the one of lowest :func:`decision_score` and, when it is another map, the most isometric
    one (lowest score without the orientation factor), both scored without the curvature
    factor (:func:`_source_exponents`). Empty when the repair does not run: off, fewer than 3
    usable eigenpairs, or no map of the unwanted orientation. O(len(refined)).

    Why two: the repair keeps its source's images of the landmarks and replaces its
    orientation, and the orientation share of the score reads both ways here. It prefers a
    torso-only front↔back mirror (orientation about −0.7), whose repair is the direct map,
    to a clean left↔right mirror (about −0.9), whose repair is the half-turn; but it also
    prefers a map mirrored on part of the body (about −0.2) to a more isometric torso-only
    mirror, and that repair is a half-turn too (remeshed SCAPE mesh000 → mesh047 at sampling
    seed 1). The most isometric map alone lost the first case on the generated families.
    Neither reading wins on every dev set (docs/correspondence3d.md), so both are re-solved
    and the decision ranks the results like every other candidate.
    """
    sources = [c for c in refined if c.unwanted]
    if not (options.orientation_repair and min(options.descriptor_k, ctx.lb_k) >= 3 and sources):
        return []
    with_share, without_share = _source_exponents(), _source_exponents(share=False)
    best = min(sources, key=lambda c: decision_score(c, with_share))
    isometric = min(sources, key=lambda c: decision_score(c, without_share))
    return [best] if isometric is best else [best, isometric]


def _source_exponents(share: bool = True) -> tuple[float, ...]:
    """The decision exponents with the curvature factor (and without ``share``, the orientation
    share) at 0: how :func:`repair_sources` scores a mirrored map. The repair replaces what
    the curvature disagreement of a mirrored map measures — which side of the body faces
    where — so that factor says nothing of the repaired map; it would only favour the clean
    left↔right mirror (curvature does not see that mirror), whose repair is the half-turn
    (remeshed tosca david0 → david6 lost its right map that way)."""
    off = {"curvature disagreement"} | (set() if share else {"orientation share"})
    return tuple(0.0 if name in off else e
                 for name, e in zip(DECISION_FACTORS, DECISION_EXPONENTS, strict=True))


def may_complete_symmetry(refined: list[Candidate], options: GeoshapeOptions) -> bool:
    """Whether :func:`complete_symmetry` can fire on ``refined`` and whatever the repair adds
    to it: it is on, the wanted orientation is the preserving one, and some map has the
    unwanted orientation (the repair runs only then, so without one the best map stays a
    wanted one). A necessary condition; whether it fires is known after the repair."""
    return (options.symmetry_completion and options.prefer == "preserving"
            and any(c.unwanted for c in refined))


def repair_landmarks(ctx: PairContext, options: GeoshapeOptions) -> tuple[np.ndarray, np.ndarray]:
    """``(landmarks1, at)``: the first ``repair_landmarks`` screening samples of mesh 1 (the
    ends of a body) and where to read their images in a refined map (large meshes: among the
    refinement samples, with which the maps are aligned)."""
    landmarks1 = ctx.c1[:min(options.repair_landmarks, len(ctx.c1))]
    at = nearest(ctx.m1.V[ctx.s1], ctx.m1.V[landmarks1])[1] if ctx.large else landmarks1
    return landmarks1, at


def _distance_functions(m: PreparedMesh, landmarks: np.ndarray) -> np.ndarray:
    """(n, L) graph geodesic distance from each landmark, ÷ √area (unit-free)."""
    return m.solver("graph").distances(landmarks).T / np.sqrt(m.area)


def complete_symmetry(ctx: PairContext, refined: list[Candidate], options: GeoshapeOptions,
                      timings: dict) -> Candidate | None:
    """Stage 4d: when the refined map of lowest :func:`decision_score` has the unwanted
    orientation, that map followed by the intrinsic left–right symmetry of mesh 2 (mesh 2
    matched to itself with ``prefer="reversing"``) is a wanted-orientation candidate as
    isometric as it. Returns the completed candidate (its distortion not yet measured), or
    None. Cost when it fires: one more pipeline run on (mesh 2, mesh 2) and one refinement.
    The score counts the share of the surface with the wanted orientation, so this fires
    only when no wanted map scores better than the mirrored one despite that share (a
    clean mirror's share is about 0.05): mostly when every candidate is mirrored.
    """
    if not may_complete_symmetry(refined, options):
        return None
    best = min(refined, key=decision_score)
    if not best.unwanted:
        return None
    t = time.perf_counter()
    # the self-run looks for mesh 2's mirror: repairing its best orientation-keeping map (the
    # identity) would only add a candidate
    mirror = run_geoshape(ctx.m2, ctx.m2, dataclasses.replace(options, prefer="reversing",
                                                              symmetry_completion=False,
                                                              orientation_repair=False))
    completed = None
    if mirror.details["orientation"] < 0:  # mesh 2 does have an orientation-reversing self-map
        completed = dataclasses.replace(best, symmetry_completed=True, distortion=None,
                                        curvature_disagreement=None, rigidity=None)
        _refine_into(ctx, completed, mirror.p2p_12[best.refined_map], options, on_refinement_rows=True)
    timings["symmetry"] = time.perf_counter() - t
    return completed


def geodesic_distortion(m1: PreparedMesh, m2: PreparedMesh, rows1: np.ndarray, *images,
                        within: np.ndarray | None = None, power: float = 1) -> list[float]:
    """For each map, the mean |d1(i, j) − d2(T i, T j)|^``power`` over pairs of ``rows1`` (each
    mesh's distances divided by their median, so uniform scale does not count): power 1 is
    the mean absolute distortion, power 2 the stress (mean squared). Each of ``images``
    gives, at position ``a``, the vertex of mesh 2 matched to ``rows1[a]``. Graph Dijkstra
    runs once from ``rows1`` (cached on mesh 1) and once from each distinct image:
    O((s + u) n log n) for s rows and u distinct images.

    ``within``: vertices of mesh 2 that contain every image (the pipeline's refinement
    samples). Distances among them are then cached on mesh 2, so later calls (screening,
    refinement, repair, the symmetry self-run) run Dijkstra only from images not seen before.
    """
    rows1 = np.asarray(rows1, dtype=np.int64)

    def normalised_rows1():
        D = m1.solver("graph").distances(rows1)[:, rows1]
        return D / max(float(np.median(D)), 1e-300)

    # cached per mesh and rows: a symmetry completion measures again on the same rows
    D1 = m1.cached(("distortion_rows", rows1.tobytes()), normalised_rows1)
    targets = [np.asarray(t, dtype=np.int64) for t in images]
    if not targets:
        return []
    sources, where = np.unique(np.concatenate(targets), return_inverse=True)
    if within is None:
        D2_all = _graph_distances_among(m2, sources)
    else:
        D2_all = m2.cached(("distances_within", np.asarray(within).tobytes()),
                           lambda: _DistancesWithin(m2, within)).among(sources)
    out = []
    for i in range(len(targets)):
        pos = where[i * len(rows1):(i + 1) * len(rows1)]
        D2 = D2_all[np.ix_(pos, pos)]
        out.append(float(np.mean(np.abs(D1 - D2 / max(float(np.median(D2)), 1e-300)) ** power)))
    return out


def _graph_distances_among(m: PreparedMesh, sources: np.ndarray,
                           columns: np.ndarray | None = None) -> np.ndarray:
    """Graph geodesic distances from ``sources`` to ``columns`` (default: the sources), by
    Dijkstra in blocks of :data:`DIJKSTRA_BLOCK` sources (memory O(block n), not O(s n)),
    shared with a second core when there are several (:func:`~geoshape.parallel.map_beside`)."""
    from geoshape.parallel import map_beside

    columns = sources if columns is None else columns
    solver = m.solver("graph")
    if len(sources) == 0:
        return np.zeros((0, len(columns)))
    blocks = [sources[b:b + DIJKSTRA_BLOCK] for b in range(0, len(sources), DIJKSTRA_BLOCK)]
    return np.vstack(map_beside(lambda block: solver.distances(block)[:, columns], blocks))


class _DistancesWithin:
    """Graph distances among a fixed vertex set of one mesh, filled as asked for by Dijkstra
    from the sources not seen before, in blocks of :data:`DIJKSTRA_BLOCK` (memory O(w²) for w
    vertices)."""

    def __init__(self, m: PreparedMesh, within: np.ndarray):
        self.m = m
        self.within = np.asarray(within, dtype=np.int64)
        self.position = np.full(m.n, -1, dtype=np.int64)
        self.position[self.within] = np.arange(len(self.within))
        self.D = np.empty((len(self.within), len(self.within)))
        self.known = np.zeros(len(self.within), dtype=bool)

    def among(self, vertices: np.ndarray) -> np.ndarray:
        """(u, u) distances among distinct ``vertices`` (computed afresh if any lies outside the set)."""
        pos = self.position[vertices]
        if np.any(pos < 0):
            return _graph_distances_among(self.m, vertices)
        todo = pos[~self.known[pos]]
        if len(todo):
            self.D[todo] = _graph_distances_among(self.m, self.within[todo], self.within)
            self.known[todo] = True
        return self.D[np.ix_(pos, pos)]


def distortion_rows(ctx: PairContext, samples: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray | slice]:
    """``(rows, at)``: the first ``n`` of ``samples`` (vertices of mesh 1), on which distortion
    is measured, and where a map holds their images: positions ``0 … n−1`` of a map aligned
    with ``samples`` (large meshes, where maps live on samples), else the vertices themselves
    of a per-vertex map."""
    rows = samples[:n]
    return rows, sample_positions(ctx, rows)


def sample_positions(ctx: PairContext, samples: np.ndarray) -> np.ndarray | slice:
    """Where a map holds the images of ``samples``, the first ones of mesh 1's screening or
    refinement samples: its first ``len(samples)`` positions in large-mesh mode (maps aligned
    with the samples), else the sample vertices themselves (per-vertex maps)."""
    return slice(0, len(samples)) if ctx.large else samples


def measure_distortion(ctx: PairContext, candidates: list[Candidate], options: GeoshapeOptions,
                       timings: dict) -> None:
    """Fill the two distortions of every refined candidate that lacks them: ``distortion``,
    :func:`geodesic_distortion` with power ``distortion_power`` (2: the stress) on the first
    ``distortion_samples`` screening samples of mesh 1 (large meshes: refinement samples,
    with which the maps are aligned), and ``curvature_disagreement``
    (:func:`curvature_disagreement` on every refinement sample, by rank with ``curvature_ranks``)."""
    todo = [c for c in candidates if c.distortion is None]
    if todo:
        t = time.perf_counter()
        rows, at = distortion_rows(ctx, ctx.s1 if ctx.large else ctx.c1, options.distortion_samples)
        images = [c.refined_map[at] for c in todo]
        distortions = geodesic_distortion(ctx.m1, ctx.m2, rows, *images, within=ctx.s2,
                                          power=options.distortion_power)
        for c, d in zip(todo, distortions, strict=True):
            c.distortion = d
        timings["distortion"] = timings.get("distortion", 0.0) + time.perf_counter() - t
    todo = [c for c in candidates if c.curvature_disagreement is None]
    if todo:
        t = time.perf_counter()
        curvatures = map_curvature_disagreements(ctx, [c.refined_map for c in todo], ctx.s1, ctx.s2,
                                                 options)
        for c, h in zip(todo, curvatures, strict=True):
            c.curvature_disagreement = h
        timings["curvature"] = timings.get("curvature", 0.0) + time.perf_counter() - t


def map_curvature_disagreements(ctx: PairContext, maps: list[np.ndarray], samples1: np.ndarray,
                                samples2: np.ndarray, options: GeoshapeOptions) -> list[float]:
    """:func:`curvature_disagreement` (by rank with ``curvature_ranks``) of each of ``maps``
    on mesh 1's ``samples1`` (screening or refinement samples, where the maps hold their
    images: :func:`sample_positions`) against mesh 2's field on ``samples2``. O(s) per map
    after the two meshes' cached ``lb_k`` fields."""
    h1 = ctx.m1.curvature_field(ctx.lb_k)[samples1]
    h2 = ctx.m2.curvature_field(ctx.lb_k)
    at = sample_positions(ctx, samples1)
    return [curvature_disagreement(h1, h2[p2p[at]], h2[samples2], ranks=options.curvature_ranks)
            for p2p in maps]


def within_quantiles(values: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``(n,)`` share of ``reference (t,)`` below each of ``values (n,)``, ties counted half
    (mid-ranks): in [0, 1], uniform on ``reference`` itself, and unchanged by any increasing
    transformation of both. O((n + t) log t).

    >>> within_quantiles(np.array([10.0, 0.0, 5.0, 5.0]), np.array([0.0, 5.0, 5.0, 10.0]))
    array([0.875, 0.125, 0.5  , 0.5  ])
    """
    from scipy.stats import percentileofscore

    return percentileofscore(reference, values, kind="mean") / 100.0


def curvature_disagreement(h1: np.ndarray, h2_images: np.ndarray, h2: np.ndarray, *,
                           ranks: bool = False) -> float:
    """How far a map is from carrying one curvature field onto another: the mean squared
    difference between ``h1 (s,)`` (mesh 1's field at sample points) and ``h2_images (s,)``
    (mesh 2's field at their images), divided by its value for random pairs of those samples
    and ``h2 (t,)`` (mesh 2's field at its own samples). 0 for a map that carries the field
    exactly, about 1 for one no better than chance; no unit (fields of different scale give
    the same ranking of maps). O(s + t).

    Why: a human body's front↔back reflection is nearly an isometry (torso, limbs and head are
    close to tubes), and composed with the left↔right one it keeps the orientation, so
    neither the geodesic stress nor the orientation share tells that half-turn from the right
    map. Mean curvature does: toes against heels, the face against the back of the head, the
    front of a bent knee against its hollow. It is extrinsic but changes only at the joints
    when a body bends; compared at the resolution of the maps (``lb_k`` eigenfunctions,
    :meth:`~geoshape.correspondence.mesh_matching.PreparedMesh.curvature_field`) it is free of
    the per-vertex noise of remeshing.

    With ``ranks``, each field is replaced by its :func:`within_quantiles` on its own mesh's
    samples (``h1`` on ``h1``, ``h2_images`` on ``h2``) before comparing, O(s log s + t log t):
    the disagreement then does not change under any increasing transformation of either field,
    so two bodies that curve alike in kind but not in amount (a heavy build and a slim one)
    are compared kind with kind. A field that is flat by value stays flat (1 for every map).

    >>> h = np.array([0.0, 1.0, 2.0, 3.0])
    >>> curvature_disagreement(h, h, h)
    0.0
    >>> curvature_disagreement(h, h[::-1], h)  # a map that reverses the field: worse than chance
    2.0
    >>> curvature_disagreement(np.ones(4), np.ones(4), np.ones(4))  # a flat field
    1.0
    >>> curvature_disagreement(h, h**3, h**3, ranks=True)  # same kind, other amount
    0.0
    """
    h1, h2_images, h2 = (np.asarray(x, dtype=np.float64) for x in (h1, h2_images, h2))
    if ranks:
        if not (_varies(h1) and _varies(h2) and np.all(np.isfinite(h2_images))):
            return 1.0  # ranks would turn rounding noise into a field
        h1, h2_images, h2 = (within_quantiles(h1, h1), within_quantiles(h2_images, h2),
                             within_quantiles(h2, h2))
    # E (h1(x) − h2(y))² over independent x, y, written without cancellation
    chance = np.var(h1) + np.var(h2) + (np.mean(h1) - np.mean(h2)) ** 2
    scale = np.mean(h1**2) + np.mean(h2**2)
    disagreement = np.mean((h1 - h2_images) ** 2)
    if not (np.isfinite(chance) and np.isfinite(disagreement) and chance > 1e-12 * scale):
        return 1.0  # a flat field (a sphere, lb_k = 1) or a broken one tells no map from another
    return float(disagreement / chance)


def _varies(h: np.ndarray) -> bool:
    """Whether a field holds more than rounding noise about its mean (and is finite)."""
    return bool(np.all(np.isfinite(h)) and np.var(h) > 1e-12 * np.mean(h**2))


def local_rigidity(X1: np.ndarray, X2: np.ndarray, patches: np.ndarray) -> float:
    """How far a map is from a rotation and a uniform scaling, locally: the mean over
    ``patches`` (rows of indices into ``X1 (s, 3)``, e.g. a point and its nearest neighbours)
    of the residual after each patch and its image (the same rows of ``X2 (s, 3)``) are
    centred, scaled to unit RMS radius and the image aligned by the best proper rotation
    (Kabsch): the mean squared distance left, in [0, 2]. 0 for a map that is a rotation and
    a uniform scaling on every patch; a fold, or the reflection of a curved patch, costs (a
    flat patch's mirror image is a rotation of it). A patch whose images all coincide scores 1.
    Scaling each patch on its own makes it blind to a smooth change of local scale (a limb
    stretched or thickened), which the geodesic stress counts. O(P k) and P 3 × 3 SVDs for P
    patches of k points.

    >>> X = np.random.default_rng(0).normal(size=(50, 3))
    >>> patches = np.arange(50).reshape(10, 5)
    >>> R = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> round(local_rigidity(X, 2 * X @ R.T + 1, patches), 9)
    0.0
    >>> local_rigidity(X, X * [1, 1, -1], patches) > 0.1  # a mirror image is not a rotation
    True
    """
    def centred_unit(Y):
        Y = Y - Y.mean(axis=1, keepdims=True)
        rms = np.sqrt((Y**2).sum(axis=(1, 2), keepdims=True) / Y.shape[1])
        return Y / np.maximum(rms, 1e-300)

    X1, X2 = np.asarray(X1, dtype=np.float64), np.asarray(X2, dtype=np.float64)
    P, Q = centred_unit(X1[patches]), centred_unit(X2[patches])
    _, trace = kabsch(P, Q)  # the best rotation, not a reflection
    k = patches.shape[1]
    residual = ((P**2).sum(axis=(1, 2)) + (Q**2).sum(axis=(1, 2)) - 2 * trace) / k
    return float(max(np.mean(residual), 0.0))  # ≥ 0 up to rounding


#: the sources of maps re-solved from landmark distance functions (:func:`landmark_resolve`)
LANDMARK_SOURCES = ("repaired", "polished")


def rigidity_patches(ctx: PairContext, options: GeoshapeOptions) -> np.ndarray:
    """``(s, k)`` patches of :func:`local_rigidity`: each refinement sample of mesh 1 and its
    ``k − 1`` nearest (k = ``rigidity_patch`` × s, at least 4), as positions in ``ctx.s1``;
    one KD-tree query, O(s k log s), cached per mesh."""
    from geoshape.geometry.knn import KNNIndex

    def patches():
        X = np.ascontiguousarray(ctx.m1.V[ctx.s1], dtype=np.float64)
        return np.asarray(KNNIndex(X).query(X, k=k)[1], dtype=np.int64)

    k = min(len(ctx.s1), max(4, int(round(options.rigidity_patch * len(ctx.s1)))))
    return ctx.m1.cached(("rigidity_patches", ctx.s1.tobytes(), k), patches)


def measure_rigidity(ctx: PairContext, candidates: list[Candidate], options: GeoshapeOptions,
                     timings: dict) -> None:
    """Fill ``rigidity`` (:func:`local_rigidity` on :func:`rigidity_patches`) of every
    candidate that lacks it; nothing when ``rigidity_patch`` is 0."""
    todo = [c for c in candidates if c.rigidity is None]
    if not todo or options.rigidity_patch <= 0:
        return
    t = time.perf_counter()
    patches = rigidity_patches(ctx, options)
    at = sample_positions(ctx, ctx.s1)
    X1 = ctx.m1.V[ctx.s1]
    for c in todo:
        c.rigidity = local_rigidity(X1, ctx.m2.V[c.refined_map[at]], patches)
    timings["rigidity"] = timings.get("rigidity", 0.0) + time.perf_counter() - t


#: Exponents of (distortion, energy, curvature disagreement, orientation share) in
#: :func:`decision_score`: equal weights in log space. ``geoshape bench correspondence --suite
#: generalization --decision-weights`` measures each one halved, doubled and left out on the dev sets.
DECISION_EXPONENTS = (1.0, 1.0, 1.0, 1.0)
#: the factors of :func:`decision_score`, in the order of ``DECISION_EXPONENTS``
DECISION_FACTORS = ("distortion", "energy", "curvature disagreement", "orientation share")


def decision_score(c: Candidate, exponents: tuple[float, ...] = DECISION_EXPONENTS) -> float:
    """The one objective every refined candidate is ranked by (lower is better): geodesic
    stress × functional map energy × curvature disagreement ÷ the share of the surface whose
    orientation the map keeps as asked (``orientation_share``), each factor raised to its
    ``exponents`` entry (``DECISION_FACTORS`` order).

    Every factor is unit-free and at its best for an orientation-keeping isometry that keeps
    the shape of each part (0, 0, 0 and 1): the stress (``Candidate.distortion``) compares
    normalised geodesic distances on sample pairs (sees which parts go where), the energy is
    the distance of the refined functional map from orthonormality (sees the whole spectrum),
    the curvature disagreement (:func:`curvature_disagreement`) sees front from back, which
    on a body neither of the first two nor the orientation can (a front↔back mirror composed
    with the left↔right one is an orientation-keeping near-isometry), and the share sees a
    map mirrored on part of the surface (orientation near 0) that the sign test of
    :func:`decide` lets through. A product weighs a relative change of any factor the same
    (equal weights in log space), so there is no weight to set, and the scale of a factor
    (the chance level dividing the curvature disagreement, say) does not change the ranking.
    A candidate whose curvature disagreement was not measured counts 1 for it.
    """
    a, b, h, s = exponents
    share = _score_factor(c.orientation_share, 1e-6)
    curvature = _score_factor(c.curvature_disagreement, 1e-12)
    return c.distortion ** a * c.refined_energy ** b * curvature ** h / share ** s


def decide(refined: list[Candidate], *,
           exponents: tuple[float, ...] = DECISION_EXPONENTS) -> Candidate:
    """Stage 5: the candidate of lowest :func:`decision_score` (with ``exponents``) among those
    of the wanted orientation (the sign of the orientation score, no threshold), or among all
    when none is. A map must not win by being smooth and mirrored. O(len(refined)).

    When that candidate is the repaired or the polished map and the other one is also of the
    wanted orientation, the more rigid of the two (lower :func:`local_rigidity`, when both were
    measured) is chosen. Both come out of the same landmark solve, which fits geodesic
    distances to the landmarks, so the stress is what the solve optimised rather than an
    independent judge between them: on stretched pairs it preferred the half-turn of the two
    as often as the right map. Local rigidity is not fitted by the solve and sees a foot
    mapped onto a heel whatever the stretching (docs/correspondence3d.md).
    """
    wanted = [c for c in refined if not c.unwanted] or refined
    best = min(wanted, key=lambda c: decision_score(c, exponents))
    if best.source not in LANDMARK_SOURCES or best.rigidity is None:
        return best
    twins = [c for c in wanted if c.source in LANDMARK_SOURCES and c.source != best.source
             and c.rigidity is not None and c.rigidity < best.rigidity]
    return min(twins, key=lambda c: c.rigidity) if twins else best


def full_resolution(ctx: PairContext, chosen: Candidate, options: GeoshapeOptions,
                    timings: dict) -> np.ndarray:
    """Stage 6: ``p2p_12 (n1,)`` — the chosen refined map's functional map (``lb_k`` × ``lb_k``)
    read off at every vertex of both meshes, then ZoomOut at full resolution from ``lb_k`` to
    :func:`final_basis_size` in steps of ``final_step`` (precision: more basis functions resolve finer
    detail than the samples can). Each read-off is O(n1 n2 k), or O(n1 c k) with c = 64
    spatial candidates around the current image above ``BRUTE_FORCE_MAX`` target vertices.
    In large-mesh mode each vertex starts from its nearest sample's image. The final ZoomOut
    ends, with a ``soft_temperature`` > 0, with one more step at that size read off softly
    (:func:`~geoshape.correspondence.fmaps.zoomout.soft_read_off`, O((n1 + n2) k² + n1 c k)); pairs
    whose :func:`final_basis_size` is ``lb_k`` (meshes too small for the resolution bound or
    too large for the cost bound, or ``final_k`` = 0) skip both: on small meshes a
    ring spans more than the basis resolves, and on a 500-vertex pair the soft step raised
    the error of a near-exact map.
    """
    from geoshape.correspondence.fmaps.zoomout import (
        BRUTE_FORCE_MAX,
        full_resolution_map,
        functional_map_from_p2p,
        soft_read_off,
        spatial_neighbours,
    )
    from geoshape.geometry.mesh import vertex_rings

    t = time.perf_counter()
    b1, b2, lb_k, coarse = ctx.b1, ctx.b2, ctx.lb_k, chosen.refined_map
    if ctx.large:
        C = functional_map_from_p2p(b1, b2, coarse, lb_k, lb_k, rows1=ctx.s1)
        coarse = coarse[nearest(ctx.m1.V[ctx.s1], ctx.m1.V)[1]]  # each vertex: its nearest sample's image
    else:
        C = functional_map_from_p2p(b1, b2, coarse, lb_k, lb_k)
    p2p = full_resolution_map(b1, b2, C, coarse, ctx.m2.V)
    timings["full_resolution"] = time.perf_counter() - t
    if ctx.final_k > lb_k:
        t = time.perf_counter()
        B1, B2 = ctx.m1.laplacian(ctx.final_k), ctx.m2.laplacian(ctx.final_k)
        ks = list(range(lb_k + options.final_step, ctx.final_k + 1, options.final_step))
        if not ks or ks[-1] != ctx.final_k:
            ks.append(ctx.final_k)
        near = None
        if ctx.m2.n > BRUTE_FORCE_MAX:  # each step searches around the last image: one table
            near = ctx.m2.cached(("spatial_neighbours", 64), lambda: spatial_neighbours(ctx.m2.V, 64))
        for k in ks:
            p2p = full_resolution_map(B1, B2, functional_map_from_p2p(B1, B2, p2p, k, k), p2p, ctx.m2.V,
                                      neighbours=near)
        timings["final_zoomout"] = time.perf_counter() - t
        if options.soft_temperature > 0:  # the final ZoomOut's last step, read off softly
            t = time.perf_counter()
            rings = ctx.m2.cached(("vertex_rings", options.soft_rings),
                                  lambda: vertex_rings(ctx.m2.F, ctx.m2.n, options.soft_rings))
            p2p = soft_read_off(B1, B2, p2p, ctx.m2.V, rings, options.soft_temperature)
            timings["soft_read_off"] = time.perf_counter() - t
    return p2p


def alternatives(ranked: list[Candidate], refined: list[Candidate]) -> list[dict]:
    """``Correspondence.alternatives``: every screened candidate by :func:`screening_score`, then
    every refined candidate that is not a signed order (descriptor maps, the orientation
    repair, the polish; see :meth:`Candidate.summary`)."""
    return [c.summary() for c in ranked] + [c.summary() for c in refined if c.alignment is None]


def run_geoshape(m1: PreparedMesh, m2: PreparedMesh, options: GeoshapeOptions) -> Correspondence:
    """The ``geoshape`` method: every stage in turn (module docstring); a
    :class:`~geoshape.correspondence.mesh_matching.Correspondence` whose ``cost`` is the chosen
    map's refined energy and whose ``details`` hold ``large_mesh_mode``, ``symmetry_completed``,
    ``source``, the chosen map's ``distortion`` and ``decision_score``, the final map's
    ``orientation``, and for diagnosis ``candidates`` (every refined :class:`Candidate`; the
    chosen one at ``chosen_index``) with ``candidate_rows`` (the mesh-1 vertices their maps are aligned
    with on large meshes, else None: maps hold every vertex).
    """
    from geoshape.correspondence.mesh_matching import Correspondence
    from geoshape.parallel import beside, can_run_beside

    timings: dict = {}
    # independent stages run beside each other on a second core (parallel.beside): mesh 1's
    # eigen-solve and embedding beside mesh 2's; the descriptor map beside the screening,
    # then both processes take the alignments left to screen and the refinements left to do
    # (parallel.map_beside_after); the same maps whether or not they do
    k = final_basis_size(m1, m2, options)
    # a child only for an eigen-solve still to do, on a mesh other than mesh 2 (self-matches)
    solve_beside = m1 is not m2 and not m1.has_laplacian(k)
    lb_k = refined_basis_size(m1, m2, options)
    with beside(_with_new_caches, _eigenpairs_and_embedding, (m1,), m1, k, options, lb_k,
                fork=solve_beside) as basis1:
        t = time.perf_counter()
        m2.laplacian(k)
        timings["eigenpairs"] = time.perf_counter() - t
        t = time.perf_counter()
        _alignment_embedding(m2, options)
        timings["embedding"] = time.perf_counter() - t
        t = time.perf_counter()
        m2.curvature_field(lb_k)
        timings["curvature field"] = time.perf_counter() - t
        timings["eigenpairs and embedding (beside)"] = _adopted(basis1.result(), (m1,))
    A, B, alignments = candidate_alignments(m1, m2, options, timings)
    ctx = pair_context(m1, m2, A, B, options, timings)
    screened, descriptor_maps = screen_beside_descriptors(ctx, alignments, options, timings)
    ranked = sorted(screened, key=screening_score)
    refined = refine(ctx, ranked, options, timings)
    refined += descriptor_maps
    measure_distortion(ctx, refined, options, timings)
    # the repair and the symmetry completion only add candidates, and mostly the decision
    # stays with the best map so far: its full-resolution map is computed in a child beside
    # them when they can run (each stage's own firing condition) and a child can be forked;
    # otherwise only the chosen map is computed, after the decision
    likely = decide(refined)
    may_add = bool(repair_sources(ctx, refined, options)) or may_complete_symmetry(refined, options)
    final_likely = p2p = None
    if may_add and can_run_beside():
        final_likely = beside(_timed, full_resolution, ctx, likely, options)
    try:
        repaired = orientation_repair(ctx, refined, options, timings)
        measure_distortion(ctx, repaired, options, timings)
        refined += repaired
        polished = polish_against_repair(ctx, refined, options, timings)
        measure_distortion(ctx, polished, options, timings)
        refined += polished
        if polished:  # the twins decide() compares by local rigidity
            measure_rigidity(ctx, [c for c in refined if c.source in LANDMARK_SOURCES], options, timings)
        completed = complete_symmetry(ctx, refined, options, timings)
        if completed is not None:
            measure_distortion(ctx, [completed], options, timings)
            refined.append(completed)
        chosen = decide(refined)
        if final_likely is not None and chosen is likely:
            p2p, final_timings = final_likely.result()
            timings.update(final_timings)
    finally:
        if final_likely is not None:
            final_likely.cancel()
    details = {"large_mesh_mode": ctx.large, "symmetry_completed": bool(chosen.symmetry_completed),
               "source": chosen.source, "distortion": chosen.distortion,
               "decision_score": decision_score(chosen), "candidates": refined,
               "chosen_index": next(i for i, c in enumerate(refined) if c is chosen),
               "candidate_rows": ctx.s1 if ctx.large else None}
    if p2p is None:  # no speculative map, or the decision moved to a candidate added since
        p2p = full_resolution(ctx, chosen, options, timings)
    details["orientation"] = orientation_score(m1.V, m1.F, m2.V, m2.F, p2p)
    return Correspondence(p2p, chosen.refined_energy, "geoshape", chosen.alignment,
                          alternatives(ranked, refined), timings, details)
