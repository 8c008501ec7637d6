"""Eigenvalue descriptor (EVD) and its chi-square distance (thesis §4.6.2).

The descriptor of a shape is ``sqrt(|lambda_i|)`` of the first twenty eigenvalues of the
Gaussian geodesic affinity of ``l`` max-min samples — the Nyström sample block. Compare
descriptors with :func:`chi2_distance`. Three configurations:

``"quadrature"`` (default)
    ``l = 500`` samples, each weighted by the area of its geodesic Voronoi cell, width
    ``sigma = 0.1 sqrt(area)``: the eigenvalues of ``W^½ A W^½`` (``W`` the cell areas
    over the total) approximate those of the affinity *operator* on the surface, so they
    do not depend on the vertex count, the sampling density or the sample positions, and
    a narrow kernel sees the proportions of the parts (in the limit it is a heat kernel,
    whose spectrum is the Laplace–Beltrami spectrum). Sample rows stop at ``6 sigma``,
    beyond which the affinity is below 1e-7.
``"thesis"``
    The faithful configuration: ``l = 60`` unweighted samples, ``sigma`` = the largest
    sampled geodesic distance (every affinity lies in [exp(-1/2), 1]).
``"heat"``
    No sampling: the narrow-kernel limit of the quadrature configuration. For a small
    width the Gaussian affinity operator is ``2π sigma²`` times the heat kernel at
    ``t = sigma² / 2``, whose eigenvalues are ``exp(-sigma² μ_k / 2)`` for the
    Laplace–Beltrami eigenvalues ``μ_k``; this configuration computes the ``μ_k`` of the
    unit-area mesh (robust Laplacian) and returns the square roots of those affinity
    eigenvalues for ``sigma = 0.1`` (:func:`heat_limit_evd`). It sees neither sample
    positions nor geodesic error, and drops the curvature term that the sampled Gaussian
    of geodesic distances adds at the same order.

On tosca_r5k (76 meshes, 8 classes) the thesis configuration reaches NN 0.75 / FT 0.57,
the quadrature one NN ≈ 0.99 / FT ≈ 0.89 and the heat limit NN 1.0 / FT ≈ 0.96: see
docs/RESULTS.md (sections retrieval3d-geodesic and evd-settings).
"""

from __future__ import annotations

import numpy as np

from geoshape.distances import chi2_distances
from geoshape.errors import InvalidOptionError
from geoshape.geometry.mesh import vertex_areas
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = ["EVD_N_EIGENVALUES", "EVD_N_SAMPLES", "EVD_CONFIGS", "EVD_CONFIG_NAMES", "evd_descriptor",
           "affinity_spectrum", "heat_limit_evd", "evd_distance_matrix"]

EVD_N_EIGENVALUES = 20
#: samples per shape of the default configuration; keep it fixed across a collection
EVD_N_SAMPLES = 500
#: the named configurations: samples, width rule, cell weighting
EVD_CONFIGS = {
    "quadrature": {"n_samples": EVD_N_SAMPLES, "sigma": "area", "weighting": "area"},
    "thesis": {"n_samples": 60, "sigma": "max", "weighting": "none"},
}
#: every configuration ``evd_descriptor`` takes: the sampled ones and the unsampled "heat"
EVD_CONFIG_NAMES = (*EVD_CONFIGS, "heat")
#: width of the quadrature kernel in units of sqrt(surface area)
AREA_SIGMA = 0.1
#: rows of the quadrature configuration stop at this many widths
CUTOFF_SIGMAS = 6.0


@mesh_input
def evd_descriptor(V, F, *, config: str = "quadrature", n_eigenvalues: int = EVD_N_EIGENVALUES,
                   n_samples: int | None = None, affinity: str = "geodesic", sigma=None,
                   weighting: str | None = None, geodesics: str = "graph", p: int = 1,
                   seed: int = 0, basis=None) -> np.ndarray:
    """The EVD of one mesh: square roots of the top eigenvalues of the sample affinity.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    config : {"quadrature", "thesis", "heat"}
        Defaults for ``n_samples``, ``sigma`` and ``weighting`` (see the module notes);
        any of those given explicitly overrides the configuration. ``"heat"`` samples
        nothing and takes none of ``n_samples``, ``sigma``, ``weighting``, ``geodesics``,
        ``p`` (``seed`` is ignored); its ``affinity`` must be ``"geodesic"`` (it is
        intrinsic). It also works on a point cloud (point-cloud Laplacian).
    n_eigenvalues : int
        Length of the descriptor (20 in the thesis); ``<= n_samples``.
    n_samples : int
        Max-min samples ``l``; keep it fixed across a collection. With ``weighting="area"``
        a mesh with fewer vertices uses all of them (the weights keep it comparable).
    sigma : "max", "mean", positive float (times the mean distance) or "area"
        ``"area"``: ``AREA_SIGMA * sqrt(surface area)``.
    weighting : {"area", "none"}
        ``"area"``: weight each sample by its geodesic Voronoi cell (needs faces);
        ``"none"``: the plain sample block.
    affinity, geodesics, p, seed
        As in :func:`geoshape.spectral.embedding.spectral_embedding`.
    basis : LaplacianBasis or None
        ``"heat"`` only: Laplace–Beltrami eigenpairs of this mesh already computed
        (:func:`geoshape.spectral.laplacian.laplacian_basis`, at least ``n_eigenvalues``
        pairs), so descriptors fused together share one eigen-solve; ``None`` computes them.

    Returns
    -------
    evd : (n_eigenvalues,) float64
        Non-increasing, non-negative.

    Notes
    -----
    ``"thesis"``: l full geodesic rows, O(l n log n + l^3), memory O(l n). ``"quadrature"``
    with graph geodesics: sampling about O(n log n) plus l rows cut at 6 sigma (a few
    percent of the surface each), then O(l^3); memory O(n + l^2). ``"heat"``: one sparse
    factorisation and a shift-invert Lanczos run for ``n_eigenvalues`` pairs, about
    O(n^1.5); memory O(n).
    """
    from geoshape._options import check_choice

    V, F = check_mesh(V, F, allow_no_faces=True)
    check_choice("EVD configuration", config, EVD_CONFIG_NAMES)
    if config == "heat":
        return _heat_evd(V, F, n_eigenvalues, n_samples=n_samples, sigma=sigma, weighting=weighting,
                         geodesics=geodesics, p=p, affinity=affinity, basis=basis)
    if basis is not None:
        raise InvalidOptionError(f"the {config!r} EVD samples its own affinity and takes no Laplacian basis")
    cfg = EVD_CONFIGS[config]
    n_samples = cfg["n_samples"] if n_samples is None else n_samples
    sigma = cfg["sigma"] if sigma is None else sigma
    weighting = check_choice("EVD weighting", cfg["weighting"] if weighting is None else weighting,
                             ("area", "none"))
    n = len(V)
    if weighting == "area" and n_samples > n:
        # weighted samples estimate the surface operator at any density: every vertex is
        # then a sample (the exact lumped quadrature), comparable with larger meshes
        n_samples = n
    if not 1 <= n_eigenvalues <= n_samples:
        raise InvalidOptionError(
            f"n_eigenvalues must lie in [1, n_samples = {n_samples}], got {n_eigenvalues}"
        )
    if n_samples > n:
        raise InvalidOptionError(f"n_samples = {n_samples} exceeds the {n} vertices of the mesh")
    needs_area = weighting == "area" or (isinstance(sigma, str) and sigma == "area")
    if needs_area and len(F) == 0:
        raise InvalidOptionError(
            "the 'quadrature' EVD weights samples by surface area and needs faces; "
            "for a point cloud use config='heat' or config='thesis'"
        )
    if needs_area:
        vertex_area = vertex_areas(V, F)
        area = float(vertex_area.sum())
        if not area > 0:
            raise InvalidOptionError("the mesh has zero surface area; no EVD can be computed")
    if isinstance(sigma, str) and sigma == "area":
        width = AREA_SIGMA * np.sqrt(area)
    else:
        width = None
    if weighting == "area" and affinity == "geodesic" and geodesics == "graph" and width is not None:
        K, w = _quadrature_block(V, F, n_samples, width, vertex_area, p, seed)
    else:
        K, w = _sample_block(V, F, n_samples, affinity, sigma, width,
                             vertex_area if weighting == "area" else None, geodesics, p, seed)
    return affinity_spectrum(K, w, n_eigenvalues)


def _heat_evd(V, F, n_eigenvalues, *, affinity, basis=None, **sampling) -> np.ndarray:
    """The "heat" configuration: check that no sampling option was given, then
    :func:`heat_limit_evd` of the unit-area Laplace–Beltrami eigenvalues (of ``basis``
    when given)."""
    from geoshape.spectral.laplacian import laplacian_basis

    defaults = {"n_samples": None, "sigma": None, "weighting": None, "geodesics": "graph", "p": 1}
    given = [name for name, value in sampling.items() if value != defaults[name]]
    if given or affinity != "geodesic":
        what = ", ".join(given) if given else f"affinity={affinity!r}"
        raise InvalidOptionError(
            f"the 'heat' EVD samples nothing and is intrinsic; it takes no {what} "
            "(use config='quadrature' to set them)"
        )
    if not isinstance(n_eigenvalues, (int, np.integer)) or not 1 <= n_eigenvalues < len(V):
        raise InvalidOptionError(
            f"the 'heat' EVD needs an integer n_eigenvalues in [1, {len(V) - 1}] (fewer than the "
            f"{len(V)} vertices), got {n_eigenvalues!r}"
        )
    k = int(n_eigenvalues)
    if basis is None:
        basis = laplacian_basis(V, F, k=k)
    return heat_limit_evd(basis.leading(k, n_vertices=len(V), what="the 'heat' EVD").evals, AREA_SIGMA)


def heat_limit_evd(mu_unit, rho: float = AREA_SIGMA) -> np.ndarray:
    """The EVD in the narrow-kernel limit, from Laplace–Beltrami eigenvalues.

    Parameters
    ----------
    mu_unit : (k,) float
        The ``k`` smallest Laplace–Beltrami eigenvalues of the shape scaled to unit area
        (``mu_unit[0] ≈ 0``; tiny negative round-off is clipped).
    rho : float
        Kernel width ``sigma`` in units of ``sqrt(area)``; a width of ``S`` mesh units on
        a shape of area ``A`` is ``rho = S / sqrt(A)``.

    Returns
    -------
    evd : (k,) float64
        ``sqrt(2π) rho exp(-rho² mu_unit / 4)``: square roots of the eigenvalues
        ``2π sigma² / A · exp(-sigma² μ / 2)`` of the Gaussian affinity operator with
        area-normalised weights, in its heat-kernel limit. Non-increasing when ``mu_unit``
        is non-decreasing. O(k).

    >>> heat_limit_evd([0.0], rho=1.0)
    array([2.50662827])
    """
    mu = np.maximum(np.asarray(mu_unit, dtype=np.float64), 0.0)
    if not isinstance(rho, (int, float, np.integer, np.floating)) or not rho > 0:
        raise InvalidOptionError(f"the kernel width rho must be a positive number, got {rho!r}")
    return np.sqrt(2.0 * np.pi) * rho * np.exp(-rho * rho * mu / 4.0)


def affinity_spectrum(K: np.ndarray, weights: np.ndarray | None, n_eigenvalues: int) -> np.ndarray:
    """``sqrt(|λ|)`` of the top eigenvalues of ``W^½ K W^½`` (``W`` = weights / their sum),
    or of ``K`` itself when ``weights`` is None. ``K (l, l)``; O(l^3)."""
    from scipy.linalg import eigh

    if weights is not None:
        sw = np.sqrt(weights / weights.sum())
        K = sw[:, None] * K * sw[None, :]
    lam = eigh(0.5 * (K + K.T), eigvals_only=True)[::-1][:n_eigenvalues]
    return np.sqrt(np.abs(lam))


def _quadrature_block(V, F, n_samples, width, vertex_area, p, seed):
    """(l, l) affinity among Voronoi-sampled vertices and the (l,) cell areas; cut rows."""
    from scipy.sparse.csgraph import dijkstra

    from geoshape.geometry.graph import structural_graph
    from geoshape.geometry.sampling import geodesic_voronoi_sampling

    graph = structural_graph(V, F, p)
    samples, owner, _ = geodesic_voronoi_sampling(graph, n_samples, seed=seed)
    D = dijkstra(graph, directed=True, indices=samples, limit=CUTOFF_SIGMAS * width)[:, samples]
    K = np.exp(-(D**2) / (2.0 * width * width))  # rows cut at the limit are inf: affinity 0
    return K, np.bincount(owner, weights=vertex_area, minlength=n_samples)


def _sample_block(V, F, n_samples, affinity, sigma, width, vertex_area, geodesics, p, seed):
    """(l, l) affinity among max-min samples from full rows, and cell areas or None.

    ``width`` (absolute) overrides the rule ``sigma``; cell areas come with ``vertex_area``.
    """
    from geoshape.geometry.geodesics import GeodesicSolver
    from geoshape.geometry.sampling import farthest_point_sampling
    from geoshape.spectral.affinity import distance_rows, gaussian_affinity

    solver = GeodesicSolver(V, F, geodesics, p=p)
    samples, Dg = farthest_point_sampling(V, F, n_samples, seed=seed, solver=solver)
    w = None if vertex_area is None else np.bincount(Dg.argmin(axis=0), weights=vertex_area,
                                                     minlength=n_samples)
    D = distance_rows(V, samples, affinity, geodesic_rows=Dg)
    if width is None:  # the width rule sees all l x n sampled distances, as the embedding's
        K, _ = gaussian_affinity(D, sigma, out=D)
        return K[:, samples], w
    D = D[:, samples]
    return np.exp(-(D**2) / (2.0 * width * width)), w


def evd_distance_matrix(descriptors) -> np.ndarray:
    """All-pairs chi-square distances of ``(N, d)`` descriptors, an ``(N, N)`` matrix.

    :func:`geoshape.distances.chi2_distances` on absolute values (one pair:
    :func:`geoshape.distances.chi2_distance`).
    """
    X = np.asarray(descriptors, dtype=np.float64)
    return chi2_distances(X, X)
