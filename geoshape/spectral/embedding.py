"""Spectral embeddings of meshes: top eigenvectors of a Gaussian affinity (thesis §4.2–4.3).

Pipeline: distances (geodesic / Euclidean / combined) → Gaussian affinity ``A`` → top
eigenpairs → drop the first (near-constant) eigenvector, or centre the kernel instead →
fix the signs → scale the eigenvectors. Two ways to get the eigenpairs:

``"exact"``
    All-pairs distances (``n x n``, refused by a memory guard for large ``n``), then
    ``scipy.linalg.eigh(subset_by_index=…)`` for ``n <= DENSE_EIGH_MAX`` or
    ``scipy.sparse.linalg.eigsh(which="LA")`` (the largest eigenvalues converge fast;
    smallest-algebraic does not on these matrices).
``"nystrom"``
    ``l`` max-min samples and their ``l x n`` distance rows only
    (:mod:`geoshape.spectral.nystrom`).
``"auto"``
    Exact up to ``AUTO_EXACT_MAX`` vertices, Nyström above.

Dimensions. ``k`` is the number of embedding coordinates returned. With
``first="drop"`` (the thesis), ``k + 1`` eigenpairs are computed and the first is dropped:
the thesis's "k = 6 with the first eigenvector disregarded" is ``k=5`` here.

Signs. Every eigenvector is flipped so that its entry of largest magnitude is positive
(ties: the lowest vertex index), so results are reproducible run to run.

Scalings (``SCALINGS``): ``"sqrt"`` ``U √λ`` (thesis, default), ``"eigenvalue"`` ``U λ``
(Shapiro–Brady), ``"none"`` ``U``, ``"squared_sphere"`` ``U λ²`` with each row projected
onto the unit sphere (Caelli–Kosinov).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = [
    "SCALINGS",
    "FIRST_MODES",
    "EMBEDDING_METHODS",
    "AUTO_EXACT_MAX",
    "DENSE_EIGH_MAX",
    "SpectralEmbedding",
    "top_eigenpairs",
    "fix_signs",
    "scale_eigenvectors",
    "embedding_from_affinity",
    "spectral_embedding",
]

SCALINGS = ("sqrt", "eigenvalue", "none", "squared_sphere")
FIRST_MODES = ("drop", "center")
EMBEDDING_METHODS = ("auto", "exact", "nystrom")
AUTO_EXACT_MAX = 2000
DENSE_EIGH_MAX = 1500


@dataclass(frozen=True)
class SpectralEmbedding:
    """A spectral embedding of ``n`` points.

    Attributes
    ----------
    coords : (n, k) float64
        Embedding coordinates, one row per vertex, columns in non-increasing eigenvalue order.
    eigenvalues : (k,) float64
        The eigenvalue of each column (estimates of the full affinity's for Nyström).
    params : dict
        What was used: method, sigma (the value), affinity, geodesics, scaling, first,
        the dropped eigenvalue, samples (Nyström), …
    """

    coords: np.ndarray
    eigenvalues: np.ndarray
    params: dict = field(default_factory=dict)


def _check_k(k, n: int, first: str) -> int:
    if not isinstance(k, (int, np.integer)) or k < 1:
        raise InvalidOptionError(f"k (embedding dimensions) must be a positive integer, got {k!r}")
    m = int(k) + (first == "drop")
    if n < k + 1:
        raise InvalidOptionError(
            f"a {k}-dimensional embedding needs at least k + 1 = {k + 1} vertices, got n = {n}"
        )
    return m


def top_eigenpairs(A: np.ndarray, m: int, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The ``m`` largest eigenpairs of a symmetric matrix.

    Parameters
    ----------
    A : (n, n) float, symmetric
    m : int, ``1 <= m <= n``

    Returns
    -------
    lam : (m,) non-increasing
    U : (n, m) orthonormal columns

    Notes
    -----
    Dense ``eigh`` with ``subset_by_index`` (O(n^3)) when ``n <= DENSE_EIGH_MAX`` or
    ``m`` is close to ``n``; otherwise ARPACK ``eigsh(which="LA")`` with a seeded start
    vector (O(n^2) per iteration).
    """
    from scipy.linalg import eigh

    n = A.shape[0]
    if not 1 <= m <= n:
        raise InvalidOptionError(f"cannot compute {m} eigenpairs of a {n} x {n} matrix")
    if n <= DENSE_EIGH_MAX or m >= n - 1:
        lam, U = eigh(A, subset_by_index=[n - m, n - 1])
    else:
        from scipy.sparse.linalg import eigsh

        v0 = np.random.default_rng(seed).standard_normal(n)
        lam, U = eigsh(A, k=m, which="LA", v0=v0, tol=1e-10)
        order = np.argsort(lam)
        lam, U = lam[order], U[:, order]
    return lam[::-1].copy(), U[:, ::-1].copy()


def fix_signs(U: np.ndarray) -> np.ndarray:
    """Flip columns so the entry of largest magnitude of each is positive (in place).

    >>> fix_signs(np.array([[0.1, 0.6], [-0.9, -0.8]]))
    array([[-0.1, -0.6],
           [ 0.9,  0.8]])
    """
    if U.size == 0:
        return U
    idx = np.argmax(np.abs(U), axis=0)
    signs = np.sign(U[idx, np.arange(U.shape[1])])
    signs[signs == 0] = 1.0
    U *= signs
    return U


def scale_eigenvectors(U: np.ndarray, lam: np.ndarray, scaling: str = "sqrt") -> np.ndarray:
    """Scale eigenvectors into embedding coordinates.

    Parameters
    ----------
    U : (n, k) float
    lam : (k,) float
        Negative eigenvalues are clipped to 0 for ``"sqrt"``.
    scaling : {"sqrt", "eigenvalue", "none", "squared_sphere"}

    Returns
    -------
    X : (n, k) float64
    """
    check_choice("scaling", scaling, SCALINGS)
    if scaling == "sqrt":
        return U * np.sqrt(np.maximum(lam, 0.0))
    if scaling == "eigenvalue":
        return U * lam
    if scaling == "none":
        return U.copy()
    X = U * lam**2
    norms = np.linalg.norm(X, axis=1, keepdims=True)
    return np.divide(X, norms, out=np.zeros_like(X), where=norms > 0)


def _center_kernel(A: np.ndarray) -> np.ndarray:
    """``H A H`` in place for a symmetric ``A``."""
    r = A.mean(axis=0)
    A -= r[None, :]
    A -= r[:, None]
    A += r.mean()
    return A


def embedding_from_affinity(A: np.ndarray, k: int = 5, *, scaling: str = "sqrt",
                            first: str = "drop", overwrite: bool = False,
                            seed: int = 0) -> SpectralEmbedding:
    """Spectral embedding of a given symmetric affinity matrix.

    Parameters
    ----------
    A : (n, n) float, symmetric
    k : int
        Output dimensions.
    scaling : {"sqrt", "eigenvalue", "none", "squared_sphere"}
    first : {"drop", "center"}
        Drop the first eigenvector, or centre the kernel (``H A H``) and keep all ``k``.
    overwrite : bool
        Allow centring ``A`` in place (saves an n x n copy).

    Returns
    -------
    SpectralEmbedding
        ``coords (n, k)``, ``eigenvalues (k,)``.
    """
    check_choice("scaling", scaling, SCALINGS)
    check_choice("first", first, FIRST_MODES)
    A = np.asarray(A, dtype=np.float64)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise InvalidOptionError(f"affinity must be a square matrix, got shape {A.shape}")
    n = A.shape[0]
    m = _check_k(k, n, first)
    params: dict = {"scaling": scaling, "first": first}
    if first == "center":
        A = _center_kernel(A if overwrite else A.copy())
    lam, U = top_eigenpairs(A, m, seed=seed)
    if first == "drop":
        params["first_eigenvalue"] = float(lam[0])
        lam, U = lam[1:], U[:, 1:]
    fix_signs(U)
    return SpectralEmbedding(scale_eigenvectors(U, lam, scaling), lam, params)


@mesh_input
def spectral_embedding(V, F=None, k: int = 5, *, method: str = "auto",
                       n_samples: int | None = None, affinity: str = "geodesic",
                       sigma="max", geodesics: str = "graph", scaling: str = "sqrt",
                       first: str = "drop", orthogonalize: bool = True, p: int = 1,
                       seed: int = 0, solver=None) -> SpectralEmbedding:
    """Spectral embedding of a mesh (exact or Nyström).

    Parameters
    ----------
    V : (n, 3) float, or one mesh object
        With ``F`` omitted: a ``trimesh.Trimesh``, Open3D ``TriangleMesh``, pymeshlab
        ``Mesh`` or ``(V, F)`` pair (:func:`geoshape.io.interop.as_arrays`, vertex order kept).
    F : (m, 3) int
        May be a soup or have several parts (the structural graph bridges them); may be
        empty (point cloud) with ``geodesics="graph"``.
    k : int
        Output dimensions (``k + 1`` eigenpairs with ``first="drop"``).
    method : {"auto", "exact", "nystrom"}
        ``auto``: exact for ``n <= AUTO_EXACT_MAX``, else Nyström. Giving ``n_samples``
        with ``auto`` selects Nyström.
    n_samples : int, optional
        Nyström samples ``l`` (default :data:`~geoshape.spectral.nystrom.DEFAULT_N_SAMPLES`,
        capped at n).
    affinity : {"geodesic", "euclidean", "combined"}
    sigma : "max", "mean" or float
        Gaussian width rule (a float ``rho`` means ``rho × mean distance``).
    geodesics : {"graph", "heat", "exact"}
        Geodesic backend (see :mod:`geoshape.geometry.geodesics`).
    scaling : {"sqrt", "eigenvalue", "none", "squared_sphere"}
    first : {"drop", "center"}
    orthogonalize : bool
        Nyström only: orthonormal eigenvectors of the Nyström approximation.
    p : int
        EMSTs bridging disconnected parts.
    seed : int
        Seed of the first max-min sample and of the eigensolver's start vector.
    solver : GeodesicSolver, optional
        Reuse a solver already built for this mesh (its method overrides ``geodesics``).

    Returns
    -------
    SpectralEmbedding
        ``coords (n, k)``, ``eigenvalues (k,)`` (estimates of the full ``n x n``
        affinity's eigenvalues), ``params``.

    Raises
    ------
    InvalidMeshError, InvalidOptionError, ResourceLimitError
        Bad mesh or option; ``n < k + 1``; exact method on a mesh too large for n x n.

    Examples
    --------
    >>> import trimesh
    >>> m = trimesh.creation.icosphere(2)
    >>> emb = spectral_embedding(m.vertices, m.faces, k=3)
    >>> emb.coords.shape, emb.eigenvalues.shape
    ((162, 3), (3,))

    Notes
    -----
    Exact: time O(n^2 log n) (graph geodesics) + O(k n^2) per eigensolver iteration,
    memory O(n^2). Nyström: time O(l n log n + n l^2), memory O(n l).
    """
    from geoshape.geometry.geodesics import GeodesicSolver
    from geoshape.spectral.affinity import AFFINITY_KINDS, parse_sigma

    check_choice("method", method, EMBEDDING_METHODS)
    check_choice("affinity", affinity, AFFINITY_KINDS)
    check_choice("scaling", scaling, SCALINGS)
    check_choice("first", first, FIRST_MODES)
    from geoshape.geometry.geodesics import GEODESIC_METHODS

    check_choice("geodesics", geodesics, GEODESIC_METHODS)
    sigma = parse_sigma(sigma)
    if F is None:  # one mesh object (trimesh, Open3D, pymeshlab) or a (V, F) pair
        from geoshape.io.interop import as_arrays

        V, F = as_arrays(V)
    V, F = check_mesh(V, F, allow_no_faces=True)
    n = len(V)
    m = _check_k(k, n, first)
    if method == "auto":
        method = "nystrom" if (n_samples is not None or n > AUTO_EXACT_MAX) else "exact"
    if solver is None and (affinity != "euclidean" or method == "nystrom"):
        solver = GeodesicSolver(V, F, geodesics, p=p)
    params = {
        "method": method, "k": int(k), "affinity": affinity, "sigma_rule": sigma,
        "geodesics": solver.method if solver is not None else None, "scaling": scaling,
        "first": first, "p": p, "seed": seed, "n_vertices": n,
    }
    if method == "exact":
        emb = _exact(V, solver, m, affinity, sigma, scaling, first, seed, k, params)
    else:
        emb = _nystrom(V, F, solver, m, n_samples, affinity, sigma, scaling, first,
                       orthogonalize, seed, k, params)
    return emb


def _exact(V, solver, m, affinity, sigma, scaling, first, seed, k, params):
    from geoshape.geometry.geodesics import check_all_pairs_memory
    from geoshape.spectral.affinity import distance_rows, gaussian_affinity

    n = len(V)
    check_all_pairs_memory(n, what="the exact spectral embedding")
    if affinity == "euclidean":
        D = distance_rows(V, None, "euclidean")
    elif solver.method == "graph":
        from scipy.sparse.csgraph import dijkstra

        D = dijkstra(solver.graph, directed=True)
        if affinity == "combined":
            D = distance_rows(V, None, "combined", geodesic_rows=D)
    else:
        from geoshape.geometry.geodesics import all_pairs_geodesics

        D = all_pairs_geodesics(V, solver.F, solver.method, p=solver.p)
        if affinity == "combined":
            D = distance_rows(V, None, "combined", geodesic_rows=D)
    A, s = gaussian_affinity(D, sigma, out=D)
    del D
    emb = embedding_from_affinity(A, k, scaling=scaling, first=first, overwrite=True, seed=seed)
    params.update(emb.params)
    params["sigma"] = s
    return SpectralEmbedding(emb.coords, emb.eigenvalues, params)


def _nystrom(V, F, solver, m, n_samples, affinity, sigma, scaling, first, orthogonalize,
             seed, k, params):
    from geoshape.geometry.sampling import farthest_point_sampling
    from geoshape.spectral.affinity import distance_rows, gaussian_affinity
    from geoshape.spectral.nystrom import DEFAULT_N_SAMPLES, nystrom_eigenpairs

    n = len(V)
    l = min(DEFAULT_N_SAMPLES, n) if n_samples is None else n_samples  # noqa: E741
    if not isinstance(l, (int, np.integer)) or not m <= l <= n:
        raise InvalidOptionError(
            f"n_samples must be an integer in [{m}, {n}] ({m} eigenpairs, {n} vertices), got {l!r}"
        )
    samples, Dg = farthest_point_sampling(V, F, int(l), seed=seed, solver=solver)
    D = distance_rows(V, samples, affinity, geodesic_rows=Dg)
    C, s = gaussian_affinity(D, sigma, out=D)
    lam, U = nystrom_eigenpairs(C, samples, m, orthogonalize=orthogonalize,
                                center=(first == "center"))
    if first == "drop":
        params["first_eigenvalue"] = float(lam[0])
        lam, U = lam[1:], U[:, 1:]
    fix_signs(U)
    params.update({"sigma": s, "n_samples": int(l), "orthogonalize": bool(orthogonalize),
                   "samples": samples})
    return SpectralEmbedding(scale_eigenvectors(U, lam, scaling), lam, params)
