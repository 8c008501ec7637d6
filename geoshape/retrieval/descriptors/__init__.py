"""Global 3D shape descriptors, their registry and their distances (thesis §4.4, §4.6.2).

Every descriptor is a function on one mesh ``(V, F) -> array`` registered in
:data:`MESH_DESCRIPTORS` with the metric it is compared with; each also takes one trimesh /
Open3D / pymeshlab mesh in place of ``V, F`` (:func:`geoshape.io.interop.mesh_input`).
The registry is what the CLI, the index and the benchmark list.

On the original mesh
    ``d2`` (Osada et al. 2002 shape distribution), ``shapedna`` (Reuter et al. 2006,
    Laplace–Beltrami eigenvalues), ``gsv`` (singular values of the sampled geodesic
    distance matrix), ``shd`` (spherical harmonics, Kazhdan et al. 2003), ``lfd`` (light
    field, Chen et al. 2003), ``pcavox`` (PCA-aligned surface occupancy grid, each principal
    axis scaled to the unit cube, compared over the plausible axis flips and swaps;
    :mod:`geoshape.retrieval.descriptors.pcavox`).
On the 3D spectral embedding (thesis Fig. 4.10)
    ``d2_emb``, ``shd_emb``, ``lfd_emb``: the same descriptors computed on the mesh whose
    vertices are the 2nd–4th √λ-scaled eigenvectors of the affinity (first three columns of
    ``spectral_embedding(V, F, k=3)``), same faces. The descriptors normalise translation
    and scale themselves.
Spectral
    ``evd``: √ of the first 20 eigenvalues of the Nyström sample affinity, χ²
    (:mod:`geoshape.retrieval.descriptors.evd`) — by default the area-weighted "quadrature"
    configuration; ``evd_thesis`` is the thesis' own (60 unweighted samples, sigma = max);
    ``evd_heat`` its narrow-kernel limit computed from exact Laplace–Beltrami eigenvalues
    (no sampling, no affinity choice, so it is listed with the original-mesh descriptors).
    ``wks``: area-weighted quantiles of log wave kernel signatures in fixed bands of
    unit-area eigenvalues, L1 (a per-band 1-Wasserstein distance;
    :mod:`geoshape.retrieval.descriptors.wks`).
    ``ccd``: the correspondence cost descriptor — the 5-D embedding itself, subsampled to
    ``CCD_POINTS`` farthest points in embedding space;
    two are compared by :func:`ccd_distance` (best match after aligning the eigenvectors).

The re-ranking scheme EVD → CCD is :data:`RERANKERS` (``"evd_ccd"`` in
:data:`RETRIEVAL_METHODS`): rank by EVD, then re-rank each query's top ``K`` by CCD.
The late fusion ``"fused"`` (:data:`FUSIONS`) — the default retrieval method
(:data:`DEFAULT_RETRIEVAL_METHOD`) of ``geoshape retrieval3d`` and of the index — computes
the components of :data:`geoshape.retrieval.fusion.FUSED_WEIGHTS` (intrinsic ``evd_heat``,
``shapedna``, ``wks`` from one shared Laplace–Beltrami eigen-solve,
:func:`compute_descriptor_set`; extrinsic ``shd`` and ``pcavox``), their all-pairs matrices,
and fuses them with per-query weights calibrated against each component's typical gap
(:func:`geoshape.retrieval.fusion.fuse_distances`): per query, the components that see a
sharper-than-usual group around it decide.

``affinity`` (geodesic / Euclidean / combined) applies to the descriptors flagged
``uses_affinity``; the others take none and reject one.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from geoshape._options import check_choice
from geoshape.distances import chi2_distances
from geoshape.errors import InvalidOptionError
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh
from geoshape.parallel import single_thread_blas
from geoshape.retrieval.descriptors.evd import EVD_N_EIGENVALUES
from geoshape.retrieval.descriptors.wks import WKS_EIGENPAIRS
from geoshape.retrieval.fusion import FUSED_WEIGHTS

__all__ = [
    "DescriptorSpec",
    "MESH_DESCRIPTORS",
    "METRICS",
    "RETRIEVAL_METHODS",
    "RERANKERS",
    "FUSIONS",
    "DEFAULT_RETRIEVAL_METHOD",
    "method_descriptors",
    "lower_bound_rows",
    "DEFAULT_AFFINITY",
    "CCD_POINTS",
    "get_descriptor",
    "descriptor_params",
    "params_key",
    "compute_descriptor",
    "compute_descriptor_set",
    "embedding_mesh",
    "d2_descriptor",
    "shapedna_descriptor",
    "gsv_descriptor",
    "ccd_descriptor",
    "ccd_distance",
    "descriptor_distances",
    "descriptor_distance_matrix",
    "rerank",
]

DEFAULT_AFFINITY = "geodesic"
#: points of the 5-D embedding kept by the CCD descriptor
CCD_POINTS = 100
CCD_DIMS = 5
#: eigenvector reordering used by CCD (see geoshape.correspondence.reorder)
CCD_REORDER = "greedy"
#: version of the stored descriptors; bump when a descriptor's numbers change
DESCRIPTOR_VERSION = 3  # 3: EVD with 500 samples (was 300)


# ---------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------


@mesh_input
def embedding_mesh(V, F, *, affinity: str = DEFAULT_AFFINITY, seed: int = 0,
                   method: str = "auto") -> np.ndarray:
    """Vertices of the 3D spectral embedding: 2nd–4th √λ-scaled eigenvectors (same faces).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    affinity : {"geodesic", "euclidean", "combined"}
    seed : int
    method : {"auto", "exact", "nystrom"}
        As :func:`geoshape.spectral.embedding.spectral_embedding` (Nyström above 2000
        vertices).

    Returns
    -------
    X : (n, 3) float64
        Centred at the vertex mean and scaled to unit RMS radius.

    Notes
    -----
    Exact: O(n^2 log n) time, O(n^2) memory; Nyström: O(l n log n + n l^2), O(n l).
    """
    from geoshape.spectral.embedding import spectral_embedding

    X = spectral_embedding(V, F, k=3, affinity=affinity, seed=seed, method=method).coords
    X = X - X.mean(axis=0)
    rms = float(np.sqrt((X * X).sum(axis=1).mean()))
    return X / rms if rms > 0 else X


def _pairwise_surface_distances(V, F, n_pairs: int, seed: int) -> np.ndarray:
    from geoshape.retrieval.descriptors.shd import surface_samples

    P = surface_samples(V, F, 2 * n_pairs, seed)
    return np.linalg.norm(P[:n_pairs] - P[n_pairs:], axis=1)


# ---------------------------------------------------------------------------------------
# Descriptors on one mesh
# ---------------------------------------------------------------------------------------


@mesh_input
def d2_descriptor(V, F, *, n_pairs: int = 20000, bins: int = 64, max_ratio: float = 4.0,
                  seed: int = 0) -> np.ndarray:
    """D2 shape distribution: histogram of distances between random surface points.

    Distances are divided by their mean (scale invariance, as Osada et al. propose), binned
    on ``[0, max_ratio]`` (larger ratios go to the last bin) and normalised to sum 1.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    n_pairs : int
        Random point pairs (area-weighted, seeded).
    bins : int
    max_ratio : float
    seed : int

    Returns
    -------
    hist : (bins,) float64, sums to 1. Compare with χ².

    Notes
    -----
    Time O(m + n_pairs log m).
    """
    V, F = check_mesh(V, F, allow_no_faces=True)
    d = _pairwise_surface_distances(V, F, n_pairs, seed)
    mean = float(d.mean())
    if not mean > 0:
        raise InvalidOptionError("the shape has zero extent; no D2 descriptor can be computed")
    h, _ = np.histogram(np.minimum(d / mean, max_ratio * (1 - 1e-12)), bins=bins,
                        range=(0.0, max_ratio))
    return h / h.sum()


@mesh_input
def shapedna_descriptor(V, F, *, k: int = 20, basis=None) -> np.ndarray:
    """ShapeDNA: the first ``k`` non-zero Laplace–Beltrami eigenvalues of the unit-area mesh.

    Each eigenvalue ``λ_i`` is divided by ``i`` (Weyl's law makes ``λ_i`` grow linearly
    in ``i`` on a surface), so every entry weighs about the same in the L2 distance.
    ``basis``: eigenpairs of this mesh already computed (at least ``k + 1``), shared with
    other spectral descriptors; ``None`` computes them.

    Returns
    -------
    dna : (k,) float64. Compare with L2.

    Notes
    -----
    One sparse factorisation, about O(n^1.5) (see :mod:`geoshape.spectral.laplacian`).
    """
    from geoshape.spectral.laplacian import laplacian_basis

    V, F = check_mesh(V, F, allow_no_faces=True)
    if basis is None:
        basis = laplacian_basis(V, F, k=k + 1)
    evals = basis.leading(k + 1, n_vertices=len(V), what="shapedna").evals[1:]
    return evals / np.arange(1, k + 1)


@mesh_input
def gsv_descriptor(V, F, *, n_samples: int = 60, k: int = 20, seed: int = 0) -> np.ndarray:
    """Singular values of the Nyström geodesic distance matrix (sample block).

    The ``l x l`` block of geodesic distances between ``l`` max-min samples is divided by
    its largest entry (scale invariance) and its ``k`` largest singular values are kept;
    with a fixed ``l`` they do not depend on the vertex count.

    Returns
    -------
    sv : (k,) float64, non-increasing. Compare with L1.

    Notes
    -----
    ``l`` geodesic rows, O(l n log n) with the graph backend, plus O(l^3).
    """
    from geoshape.geometry.sampling import farthest_point_sampling

    V, F = check_mesh(V, F, allow_no_faces=True)
    if not 1 <= k <= n_samples <= len(V):
        raise InvalidOptionError(
            f"gsv needs 1 <= k <= n_samples <= n vertices; got k={k}, n_samples={n_samples}, n={len(V)}"
        )
    samples, D = farthest_point_sampling(V, F, n_samples, seed=seed)
    B = D[:, samples]
    B = 0.5 * (B + B.T)
    top = float(B[np.isfinite(B)].max())
    if not top > 0:
        raise InvalidOptionError("the shape has zero extent; no descriptor can be computed")
    B = np.where(np.isfinite(B), B, top) / top
    return np.linalg.svd(B, compute_uv=False)[:k]


@mesh_input
def ccd_descriptor(V, F, *, affinity: str = DEFAULT_AFFINITY, n_points: int = CCD_POINTS,
                   k: int = CCD_DIMS, seed: int = 0) -> np.ndarray:
    """The CCD "descriptor": ``n_points`` farthest points of the √λ-scaled k-D embedding.

    Returns
    -------
    E : (min(n_points, n), k) float64
        Rows of the embedding (Nyström above 2000 vertices), chosen by farthest-point
        sampling in embedding space. Compare two with :func:`ccd_distance`.

    Notes
    -----
    Embedding cost (see :func:`embedding_mesh`) plus O(n · n_points) for the sampling.
    """
    from geoshape.geometry.sampling import euclidean_farthest_point_sampling
    from geoshape.spectral.embedding import spectral_embedding

    X = spectral_embedding(V, F, k=k, affinity=affinity, seed=seed).coords
    return np.ascontiguousarray(X[euclidean_farthest_point_sampling(X, n_points, seed)])


def ccd_distance(A, B, *, reorder: str = CCD_REORDER) -> float:
    """Correspondence cost between two embeddings: symmetric mean best-match distance.

    ``B``'s columns are first reordered and sign-corrected against ``A``
    (:func:`geoshape.correspondence.reorder.align_embeddings`); then
    ``0.5 * (mean_i min_j ‖A_i − B'_j‖ + mean_j min_i ‖A_i − B'_j‖)``. The thesis sums over
    the vertices of one shape; the mean and the symmetrisation make shapes of different
    sizes comparable and the distance symmetric up to the alignment search.

    Parameters
    ----------
    A : (nA, k) float
    B : (nB, k) float
    reorder : {"exhaustive", "greedy", "pairwise", "signs", "none"}

    Returns
    -------
    float

    Notes
    -----
    Greedy: O(k^2 nA nB k); exhaustive: O(k! 2^k nA nB) (about 30x slower for k = 5).
    """
    from geoshape.correspondence.reorder import align_embeddings

    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    best = align_embeddings(A, B, reorder, n_keep=1, max_points=max(len(A), len(B)))[0]
    Bp = best.apply(B)
    d2 = (A * A).sum(1)[:, None] + (Bp * Bp).sum(1)[None, :] - 2.0 * A @ Bp.T
    d = np.sqrt(np.maximum(d2, 0.0))
    return float(0.5 * (d.min(axis=1).mean() + d.min(axis=0).mean()))


# ---------------------------------------------------------------------------------------
# Registry
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DescriptorSpec:
    """A registered descriptor.

    Attributes
    ----------
    name : str
        Stable id (CLI, index, results).
    summary : str
        One line for listings.
    compute : callable
        ``compute(V, F, **params) -> ndarray`` on the mesh (or its embedding, see ``domain``).
    metric : str
        One of :data:`METRICS`.
    domain : {"original", "embedding", "spectral"}
        ``embedding``: ``compute`` runs on :func:`embedding_mesh`. ``spectral``: the
        descriptor is itself spectral and takes the affinity.
    invariances : tuple of str
        Among ``translation``, ``rotation``, ``scale``, ``bending`` (approximate).
    params : dict
        Default keyword parameters of ``compute`` (stored with every indexed row).
    eigenpairs : int
        Laplace–Beltrami eigenpairs ``compute`` reads (0: none). Such a ``compute`` takes a
        ``basis=`` keyword (:class:`geoshape.spectral.laplacian.LaplacianBasis`), so
        :func:`compute_descriptor_set` solves once, for the largest count, and shares it.
    """

    name: str
    summary: str
    compute: Callable
    metric: str
    domain: str
    invariances: tuple[str, ...]
    params: dict = field(default_factory=dict)
    eigenpairs: int = 0

    @property
    def uses_affinity(self) -> bool:
        return self.domain in ("embedding", "spectral")


@mesh_input
def _evd(V, F, *, affinity=DEFAULT_AFFINITY, seed=0, config="quadrature"):
    from geoshape.retrieval.descriptors.evd import evd_descriptor

    return evd_descriptor(V, F, config=config, affinity=affinity, seed=seed)


_evd_thesis = functools.partial(_evd, config="thesis")


@mesh_input
def _evd_heat(V, F, *, seed=0, basis=None):
    from geoshape.retrieval.descriptors.evd import evd_descriptor

    return evd_descriptor(V, F, config="heat", basis=basis)


@mesh_input
def _wks(V, F, *, seed=0, basis=None):
    from geoshape.retrieval.descriptors.wks import wks_descriptor

    return wks_descriptor(V, F, basis=basis)


@mesh_input
def _shd(V, F, *, seed=0):
    from geoshape.retrieval.descriptors.shd import shd_descriptor

    return shd_descriptor(V, F, seed=seed)


@mesh_input
def _lfd(V, F, *, seed=0):
    from geoshape.retrieval.descriptors.lfd import lfd_descriptor

    return lfd_descriptor(V, F, seed=seed)


@mesh_input
def _pcavox(V, F, *, seed=0):
    from geoshape.retrieval.descriptors.pcavox import pcavox_descriptor

    return pcavox_descriptor(V, F, seed=seed)


_RIGID = ("translation", "rotation", "scale")
_INTRINSIC = _RIGID + ("bending",)

MESH_DESCRIPTORS: dict[str, DescriptorSpec] = {
    s.name: s
    for s in [
        DescriptorSpec("evd", "√ of the top 20 eigenvalues of the area-weighted affinity of 500 "
                       "samples, sigma = 0.1 √area", _evd, "chi2", "spectral", _INTRINSIC),
        DescriptorSpec("evd_thesis", "√ of the top 20 eigenvalues of the Nyström sample affinity "
                       "(thesis: 60 samples, sigma = max)", _evd_thesis, "chi2", "spectral", _INTRINSIC),
        DescriptorSpec("evd_heat", "the EVD's narrow-kernel (heat-kernel) limit from 20 exact "
                       "Laplace-Beltrami eigenvalues, sigma = 0.1 √area", _evd_heat, "chi2",
                       "original", _INTRINSIC, eigenpairs=EVD_N_EIGENVALUES),
        DescriptorSpec("ccd", "correspondence cost between 5-D spectral embeddings (thesis)",
                       ccd_descriptor, "ccd", "spectral", _INTRINSIC),
        DescriptorSpec("d2", "D2 shape distribution, 64 bins (Osada et al. 2002)",
                       d2_descriptor, "chi2", "original", _RIGID),
        DescriptorSpec("shapedna", "first 20 Laplace-Beltrami eigenvalues, unit area (Reuter et al.)",
                       shapedna_descriptor, "l2", "original", _INTRINSIC, eigenpairs=21),
        DescriptorSpec("wks", "area-weighted quantiles of log wave kernel signatures, 16 bands x 16 "
                       "levels, from 100 Laplace-Beltrami eigenpairs", _wks, "l1", "original", _INTRINSIC,
                       eigenpairs=WKS_EIGENPAIRS),
        DescriptorSpec("gsv", "singular values of the sampled geodesic distance matrix",
                       gsv_descriptor, "l1", "original", _INTRINSIC),
        DescriptorSpec("shd", "spherical harmonics energies, 16 shells x l<=16 (Kazhdan et al.)",
                       _shd, "l2", "original", _RIGID),
        DescriptorSpec("lfd", "light field: Zernike + Fourier of 10 dodecahedron silhouettes (Chen et al.)",
                       _lfd, "lfd", "original", _RIGID),
        DescriptorSpec("pcavox", "PCA-aligned surface occupancy grid 16^3, each axis scaled to the cube; "
                       "min L2 over plausible axis flips / swaps", _pcavox, "pcavox", "original", _RIGID),
        DescriptorSpec("d2_emb", "D2 on the 3D spectral embedding", d2_descriptor, "chi2",
                       "embedding", _INTRINSIC),
        DescriptorSpec("shd_emb", "spherical harmonics descriptor on the 3D spectral embedding",
                       _shd, "l2", "embedding", _INTRINSIC),
        DescriptorSpec("lfd_emb", "light field descriptor on the 3D spectral embedding",
                       _lfd, "lfd", "embedding", _INTRINSIC),
    ]
}

#: Distances between descriptors, by name.
METRICS = ("chi2", "l1", "l2", "lfd", "pcavox", "ccd")
#: Everything ``geoshape retrieval3d --descriptor`` accepts: descriptors + re-ranking schemes.
RERANKERS = {"evd_ccd": ("evd", "ccd")}
#: Late fusions: method -> {component descriptor: weight} (:mod:`geoshape.retrieval.fusion`).
FUSIONS = {"fused": dict(FUSED_WEIGHTS)}
RETRIEVAL_METHODS = tuple(MESH_DESCRIPTORS) + tuple(RERANKERS) + tuple(FUSIONS)
#: What ``geoshape retrieval3d`` and ``geoshape index add/query`` use without ``--descriptor``.
DEFAULT_RETRIEVAL_METHOD = "fused"


def method_descriptors(method: str) -> tuple[str, ...]:
    """The descriptors a retrieval method computes: itself, a re-ranker's two, a fusion's components."""
    check_choice("descriptor", method, RETRIEVAL_METHODS)
    if method in RERANKERS:
        return RERANKERS[method]
    if method in FUSIONS:
        return tuple(n for n, w in FUSIONS[method].items() if w > 0)
    return (method,)


def get_descriptor(name: str) -> DescriptorSpec:
    """The registered descriptor ``name``; raises listing the registered names."""
    check_choice("descriptor", name, MESH_DESCRIPTORS)
    return MESH_DESCRIPTORS[name]


def descriptor_params(name: str, affinity: str | None = None, seed: int = 0) -> dict:
    """The full parameter record of a descriptor computation (stored with indexed rows).

    ``affinity=None`` means the default for descriptors that take one; giving one to a
    descriptor that takes none raises :class:`InvalidOptionError`.
    """
    from geoshape.spectral.affinity import AFFINITY_KINDS

    spec = get_descriptor(name)
    params = {"descriptor": name, "version": DESCRIPTOR_VERSION, "seed": int(seed)}
    if spec.uses_affinity:
        params["affinity"] = check_choice("affinity", affinity or DEFAULT_AFFINITY, AFFINITY_KINDS)
    elif affinity is not None:
        alt = f"; use '{name}_emb' for the spectral embedding" if f"{name}_emb" in MESH_DESCRIPTORS else ""
        raise InvalidOptionError(
            f"descriptor {name!r} works on the original mesh and takes no affinity "
            f"(got {affinity!r}){alt}"
        )
    return params


def params_key(params: dict) -> str:
    """Canonical JSON of a parameter record (sorted keys), for equality and storage."""
    return json.dumps(params, sort_keys=True, separators=(",", ":"))


@mesh_input
def compute_descriptor(V, F, name: str, *, affinity: str | None = None, seed: int = 0,
                       check: bool = True) -> np.ndarray:
    """Compute registered descriptor ``name`` of one mesh.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    name : str
        One of :data:`MESH_DESCRIPTORS`.
    affinity : {"geodesic", "euclidean", "combined"} or None
        For spectral and embedding descriptors (default geodesic); must be None for the
        others.
    seed : int

    Returns
    -------
    ndarray
        Shape depends on the descriptor (see its function).

    Examples
    --------
    >>> import trimesh
    >>> m = trimesh.creation.icosphere(2)
    >>> compute_descriptor(m.vertices, m.faces, "d2").shape
    (64,)
    """
    params = descriptor_params(name, affinity, seed)
    if check:
        V, F = check_mesh(V, F, allow_no_faces=True)
    # one BLAS thread: the same bits whichever runner (processes, Dask, serial) computes it
    with single_thread_blas():
        return _compute(V, F, name, params, seed)


@mesh_input
def compute_descriptor_set(V, F, names, *, affinity: str | None = None, seed: int = 0,
                           check: bool = True) -> tuple[dict, dict]:
    """Several registered descriptors of one mesh, sharing one Laplace–Beltrami eigen-solve.

    The descriptors that read eigenpairs (:attr:`DescriptorSpec.eigenpairs`: ``evd_heat``,
    ``shapedna``, ``wks``) get the first pairs of one :func:`geoshape.spectral.laplacian.laplacian_basis`
    solved for the largest count (capped at ``n - 1``); the others are computed as
    :func:`compute_descriptor` does. A descriptor read from the shared basis equals its own
    computation up to the eigen-solver's tolerance (``EIGSH_TOL``, relative 1e-8).

    Parameters
    ----------
    V, F : mesh
    names : sequence of str
        Registered descriptors (duplicates computed once).
    affinity : str or None
        For the descriptors that take one (default geodesic); the others ignore it.
    seed : int
    check : bool
        Validate the mesh first.

    Returns
    -------
    descriptors : dict name -> ndarray
    seconds : dict name -> float
        Compute time per descriptor; the shared eigen-solve is split evenly among the
        descriptors that read it, so the values sum to the total.
    """
    import time

    from geoshape.spectral.laplacian import laplacian_basis

    names = list(dict.fromkeys(names))
    params = {nm: descriptor_params(nm, affinity if get_descriptor(nm).uses_affinity else None, seed)
              for nm in names}
    if check:
        V, F = check_mesh(V, F, allow_no_faces=True)
    users = [nm for nm in names if MESH_DESCRIPTORS[nm].eigenpairs > 0]
    out, sec = {}, {}
    with single_thread_blas():
        basis, share = None, 0.0
        if users:
            k = min(max(MESH_DESCRIPTORS[nm].eigenpairs for nm in users), len(V) - 1)
            t0 = time.perf_counter()
            basis = laplacian_basis(V, F, k=k)
            share = (time.perf_counter() - t0) / len(users)
        for nm in names:
            t0 = time.perf_counter()
            out[nm] = _compute(V, F, nm, params[nm], seed, basis=basis if nm in users else None)
            sec[nm] = time.perf_counter() - t0 + (share if nm in users else 0.0)
    return out, sec


def _compute(V, F, name: str, params: dict, seed: int, basis=None) -> np.ndarray:
    spec = MESH_DESCRIPTORS[name]
    if basis is not None:
        return np.asarray(spec.compute(V, F, seed=seed, basis=basis) if name != "shapedna"
                          else spec.compute(V, F, basis=basis), dtype=np.float64)
    if spec.domain == "embedding":
        X = embedding_mesh(V, F, affinity=params["affinity"], seed=seed)
        return np.asarray(spec.compute(X, F, seed=seed), dtype=np.float64)
    if spec.domain == "spectral":
        return np.asarray(spec.compute(V, F, affinity=params["affinity"], seed=seed), dtype=np.float64)
    if name == "shapedna":
        return np.asarray(spec.compute(V, F), dtype=np.float64)
    return np.asarray(spec.compute(V, F, seed=seed), dtype=np.float64)


# ---------------------------------------------------------------------------------------
# Distances
# ---------------------------------------------------------------------------------------


def lower_bound_rows(name: str):
    """For a descriptor whose metric is not a vector distance but has a cheap lower bound
    (``pcavox``), ``(rows, metric, tag)``: the function ``(N, ...) array -> (N, m) float64``
    giving short rows, the name of their distance (a :mod:`geoshape.retrieval.ann` metric)
    that never exceeds the descriptor's, and a tag naming the rows' settings (a stored set
    of other settings is rebuilt). pcavox:
    :func:`~geoshape.retrieval.descriptors.pcavox.pcavox_projection`, metric ``"pcavox_lb"``.
    Otherwise None. A large index searches those rows for candidates and re-scores the
    candidates with the descriptor's own distance."""
    if get_descriptor(name).metric == "pcavox":
        from geoshape.retrieval.descriptors.pcavox import (
            PCAVOX_EMBEDDING_FREQUENCIES,
            PCAVOX_PROJECTION_FREQUENCIES,
            pcavox_projection,
        )

        tag = f"pcavox_projection {PCAVOX_PROJECTION_FREQUENCIES}/{PCAVOX_EMBEDDING_FREQUENCIES}"
        return pcavox_projection, "pcavox_lb", tag
    return None


def descriptor_distances(name: str, queries, database) -> np.ndarray:
    """Distances from each query descriptor to each database descriptor.

    Parameters
    ----------
    name : str
        Registered descriptor (its metric is used).
    queries : sequence of ndarray or (Q, ...) array
    database : sequence of ndarray or (M, ...) array

    Returns
    -------
    D : (Q, M) float64

    Notes
    -----
    χ², L1, L2: O(Q M d), vectorised. LFD: O(Q M f^2 (100 d + 600)). PCAVOX: O(48 Q M d).
    CCD: one eigenvector alignment per pair, O(Q M k^3 p^2) for ``p`` embedding points (greedy reordering).
    """
    metric = get_descriptor(name).metric
    if metric == "ccd":
        D = np.zeros((len(queries), len(database)))
        for i, a in enumerate(queries):
            for j, b in enumerate(database):
                D[i, j] = ccd_distance(a, b)
        return D
    X = np.asarray(queries, dtype=np.float64)
    Y = np.asarray(database, dtype=np.float64)
    if metric == "lfd":
        from geoshape.retrieval.descriptors.lfd import lfd_distance_matrix

        return lfd_distance_matrix(X, Y)
    if metric == "pcavox":
        from geoshape.retrieval.descriptors.pcavox import pcavox_distance_matrix

        return pcavox_distance_matrix(X, Y)
    X = X.reshape(len(X), -1)
    Y = Y.reshape(len(Y), -1)
    if X.shape[1] != Y.shape[1]:
        raise InvalidOptionError(f"descriptor lengths differ: {X.shape[1]} vs {Y.shape[1]}")
    if metric == "chi2":
        return chi2_distances(X, Y)
    if metric == "l1":
        return np.abs(X[:, None, :] - Y[None, :, :]).sum(axis=2) if len(X) * len(Y) * X.shape[1] < 5e7 \
            else np.array([np.abs(x - Y).sum(axis=1) for x in X])
    # L2 from the differences, not from |x|² + |y|² − 2 x·y: that expansion cancels to ~1e-14
    # |x|² for equal vectors, i.e. a distance of ~1e-7 |x| between a shape and itself
    if len(X) * len(Y) * X.shape[1] < 5e7:
        return np.sqrt(((X[:, None, :] - Y[None, :, :]) ** 2).sum(axis=2))
    return np.array([np.sqrt(((x - Y) ** 2).sum(axis=1)) for x in X])


def descriptor_distance_matrix(name: str, descriptors, *, backend: str | None = "serial",
                               n_jobs: int | None = None, scheduler=None,
                               progress: bool = False) -> np.ndarray:
    """All-pairs dissimilarity matrix of per-shape descriptors.

    Cheap metrics (χ², L1, L2, LFD, PCAVOX) run in this process; CCD (one eigenvector alignment per
    pair) is spread over the parallel runner by :func:`geoshape.parallel.pairwise_matrix`.

    Returns
    -------
    D : (N, N) float64, symmetric, zero diagonal.
    """
    metric = get_descriptor(name).metric
    descriptors = list(descriptors)
    if metric == "ccd" and backend != "serial":
        from geoshape.parallel import pairwise_matrix

        return pairwise_matrix(_ccd_block, descriptors, vectorized=True, diagonal=0.0,
                               backend=backend, n_jobs=n_jobs, scheduler=scheduler,
                               progress=progress, desc="ccd pairs")
    D = descriptor_distances(name, descriptors, descriptors)
    D = 0.5 * (D + D.T)
    np.fill_diagonal(D, 0.0)
    return D


def _ccd_block(list_a, list_b):
    with single_thread_blas():
        return descriptor_distances("ccd", list_a, list_b)


def _ccd_pairs_task(args):
    pairs, descs = args
    with single_thread_blas():
        return [ccd_distance(descs[i], descs[j]) for i, j in pairs]


def rerank(D_first, second_descriptors, *, k: int = 20, backend: str | None = "serial",
           n_jobs: int | None = None, scheduler=None) -> np.ndarray:
    """Re-rank each query's top ``k`` (by ``D_first``) by CCD; the rest keeps its order.

    Parameters
    ----------
    D_first : (N, N) float
        First-stage dissimilarities (EVD).
    second_descriptors : sequence of (p, 5) arrays
        CCD descriptors of the same N shapes.
    k : int
        Shortlist size per query (the query itself excluded).

    Returns
    -------
    D : (N, N) float64
        Row ``i``: the shortlist holds its CCD distances, every other item
        ``max CCD + 1 + D_first`` (so it ranks after the shortlist, in first-stage order).
        Not symmetric. The diagonal is 0.

    Notes
    -----
    At most ``N k`` CCD evaluations (a pair shortlisted both ways is computed once).
    """
    from geoshape.parallel import run_map

    D_first = np.asarray(D_first, dtype=np.float64)
    n = len(D_first)
    if not isinstance(k, (int, np.integer)) or k < 1:
        raise InvalidOptionError(f"re-ranking shortlist size must be a positive integer, got {k!r}")
    k = min(int(k), n - 1)
    Dq = D_first.copy()
    np.fill_diagonal(Dq, np.inf)
    short = np.argsort(Dq, axis=1, kind="stable")[:, :k]
    pairs = sorted({(min(i, j), max(i, j)) for i in range(n) for j in short[i].tolist()})
    descs = list(second_descriptors)
    n_tasks = max(1, min(len(pairs), 4 * (n_jobs or 2)))
    chunks = [pairs[s::n_tasks] for s in range(n_tasks)]
    out = run_map(_ccd_pairs_task, [(c, descs) for c in chunks], backend=backend,
                  n_jobs=n_jobs, scheduler=scheduler, progress=False, chunksize=1)
    cost = {}
    for c, vals in zip(chunks, out, strict=True):
        cost.update(zip(c, vals, strict=True))
    top = max(cost.values()) if cost else 0.0
    D = top + 1.0 + np.where(np.isfinite(Dq), Dq, 0.0)
    for i in range(n):
        for j in short[i].tolist():
            D[i, j] = cost[(min(i, j), max(i, j))]
    np.fill_diagonal(D, 0.0)
    return D
