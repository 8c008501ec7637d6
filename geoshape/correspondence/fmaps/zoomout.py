"""ZoomOut refinement of a point-to-point map on Laplace–Beltrami bases.

Melzi et al. 2019 ("ZoomOut: spectral upsampling for efficient shape correspondence"):
alternate between the functional map of size ``k`` induced by the current point map and
the point map induced by that functional map, growing ``k``. This implementation is
geoshape's own, written from the paper's description.

Conventions: ``p2p_12[i]`` is the vertex of mesh 2 matched to vertex ``i`` of mesh 1;
``C_21 (k, k)`` maps coefficients of functions on mesh 2 to functions on mesh 1
(pull-back through ``p2p_12``): ``C_21 = Φ1ᵀ M1 Φ2[p2p_12]``. The point map is recovered
by matching the rows of ``Φ1`` to the rows of ``Φ2 C_21ᵀ`` (mesh 2 carried into mesh 1's
basis), nearest neighbours by :func:`geoshape.geometry.knn.nearest`.

For speed the iterations run on farthest-point subsets of both meshes (a few thousand
points suffice to estimate a k <= 100 functional map: least squares on the subset); only
the last step maps every vertex of mesh 1. Cost per iteration O(s1 s2 k) for subsets of
sizes s1, s2 (blocked BLAS), final step O(n1 n2 k).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoshape.errors import InvalidOptionError
from geoshape.geometry.knn import k_nearest, nearest
from geoshape.spectral.laplacian import LaplacianBasis


def functional_map_from_p2p(basis1: LaplacianBasis, basis2: LaplacianBasis, p2p_12: np.ndarray,
                            k1: int, k2: int, rows1: np.ndarray | None = None, qr=None) -> np.ndarray:
    """``C_21 (k1, k2)``: functions on mesh 2 pulled back to mesh 1 through ``p2p_12``.

    With ``rows1`` (a subset of mesh-1 vertices, ``p2p_12`` given on that subset), the
    map is the least-squares fit ``Φ1[rows1] C ≈ Φ2[p2p_12]``; otherwise the mass-weighted
    projection ``Φ1ᵀ M1 Φ2[p2p_12]``. ``qr`` may pass a precomputed ``np.linalg.qr(Φ1[rows1])``.
    """
    if rows1 is None:
        return basis1.evecs[:, :k1].T @ (basis1.mass[:, None] * basis2.evecs[p2p_12, :k2])
    Q, R = np.linalg.qr(basis1.evecs[rows1]) if qr is None else qr
    # least squares with the first k1 columns: the QR of a column prefix is a prefix of the QR
    from scipy.linalg import solve_triangular

    return solve_triangular(R[:k1, :k1], Q[:, :k1].T @ basis2.evecs[p2p_12, :k2])


def aligned_bases(basis1: LaplacianBasis, basis2: LaplacianBasis, C_21: np.ndarray,
                  rows1: np.ndarray | None = None,
                  rows2: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(queries, candidates)``: rows of mesh 1 and of mesh 2 expressed in one basis.

    ``Φ1`` against ``Φ2 C_21ᵀ``: the target basis is carried into the source basis, as
    ZoomOut and the original functional-map paper recover maps. (Matching ``Φ1 C_21``
    against ``Φ2`` agrees only when ``C_21`` is orthonormal; on real pairs, where ``C`` is
    only near-orthonormal, it was less precise on tosca_r5k: see docs/correspondence3d.md.)
    """
    k1, k2 = C_21.shape
    E1 = basis1.evecs[:, :k1] if rows1 is None else basis1.evecs[rows1, :k1]
    E2 = basis2.evecs[:, :k2] if rows2 is None else basis2.evecs[rows2, :k2]
    return E1, E2 @ C_21.T


def p2p_from_functional_map(basis1: LaplacianBasis, basis2: LaplacianBasis, C_21: np.ndarray,
                            rows1: np.ndarray | None = None, rows2: np.ndarray | None = None) -> np.ndarray:
    """Point map 1 → 2 from ``C_21``: nearest neighbours in a shared spectral basis.

    ``rows1``/``rows2`` restrict queries and candidates; the result indexes mesh-2
    vertices (not positions in ``rows2``). The bases are aligned by :func:`aligned_bases`.
    Cost O(s1 s2 k) (blocked BLAS above 8 dimensions).
    """
    queries, candidates = aligned_bases(basis1, basis2, C_21, rows1, rows2)
    _, j = nearest(candidates, queries)
    return j if rows2 is None else np.asarray(rows2)[j]


def zoomout(basis1: LaplacianBasis, basis2: LaplacianBasis, p2p_12: np.ndarray, *,
            k_start: int = 8, k_end: int = 60, step: int = 2,
            samples1: np.ndarray | None = None, samples2: np.ndarray | None = None,
            return_energy: bool = False, final_on_samples: bool = False, samples_only: bool = False):
    """Refine ``p2p_12`` by spectral upsampling from ``k_start`` to ``k_end``.

    Parameters
    ----------
    basis1, basis2 : LaplacianBasis
        With at least ``k_end`` eigenpairs each.
    p2p_12 : (n1,) or (len(samples1),) int
        Initial map, for every vertex of mesh 1 or for ``samples1`` only.
    samples1, samples2 : int arrays, optional
        Vertex subsets on which the iterations run (e.g. 2000 farthest points each).
    final_on_samples : bool
        Map every vertex of mesh 1 only onto ``samples2`` (a cheap coarse map, e.g. to
        screen candidate initialisations) instead of onto every vertex of mesh 2.
    samples_only : bool
        Return the map of ``samples1`` only (aligned with it), onto ``samples2``: no step
        touches every vertex (large meshes). ``p2p_12`` may then be given on ``samples1``
        only.
    return_energy : bool
        Also return the off-diagonal energy of the final functional map, a measure of
        how far it is from an isometry (lower is better; comparable between candidate
        maps of the same pair).

    Returns
    -------
    p2p_12 : (n1,) int64 — refined map; and ``energy`` (float) if requested.
    """
    if k_end > min(basis1.k, basis2.k) or k_start < 1 or k_start > k_end:
        raise InvalidOptionError(
            f"ZoomOut needs 1 <= k_start <= k_end <= {min(basis1.k, basis2.k)}, "
            f"got k_start={k_start}, k_end={k_end}"
        )
    p2p = np.asarray(p2p_12, dtype=np.int64)
    rows1 = None if samples1 is None else np.asarray(samples1, dtype=np.int64)
    rows2 = None if samples2 is None else np.asarray(samples2, dtype=np.int64)
    if samples_only and (rows1 is None or rows2 is None):
        raise InvalidOptionError("samples_only needs samples1 and samples2")
    # a map given on samples1 only (aligned with it) or on every vertex of mesh 1; the two
    # coincide when samples1 holds every vertex (then it is arange: see euclidean_farthest_point_sampling)
    sub = p2p if rows1 is None or len(p2p) == len(rows1) else p2p[rows1]
    ks = list(range(k_start, k_end + 1, step))
    if ks[-1] != k_end:
        ks.append(k_end)
    qr = None if rows1 is None else np.linalg.qr(basis1.evecs[rows1, :k_end])
    C = None
    for k in ks:
        C = functional_map_from_p2p(basis1, basis2, sub, k, k, rows1, qr)
        sub = p2p_from_functional_map(basis1, basis2, C, rows1, rows2)
    C = functional_map_from_p2p(basis1, basis2, sub, k_end, k_end, rows1, qr)
    if samples_only:
        return (sub, functional_map_energy(C)) if return_energy else sub
    full = p2p_from_functional_map(basis1, basis2, C, None, rows2 if final_on_samples else None)
    if not return_energy:
        return full
    return full, functional_map_energy(C)


def functional_map_energy(C: np.ndarray) -> float:
    """Distance of ``C`` from orthonormality, ``‖CᵀC − I‖_F / k`` (0 for an isometry)."""
    k = C.shape[0]
    return float(np.linalg.norm(C.T @ C - np.eye(C.shape[1])) / k)


#: above this many target vertices the full-resolution map searches only near the coarse image.
#: The image moves little once the map is refined, and 64 spatial candidates hold it: on the
#: 5k-vertex dev sets (tosca_r5k, both remeshed sets, the non-isometric family; all pairs) the
#: restricted search moved no set's mean error by more than 1.6 % (three of four by under
#: 0.5 %) and saved about 0.25 s per pair against brute force (then the limit was 8000).
BRUTE_FORCE_MAX = 1000


def full_resolution_map(basis1: LaplacianBasis, basis2: LaplacianBasis, C_21: np.ndarray,
                        coarse_12: np.ndarray, V2: np.ndarray, *, n_candidates: int = 64,
                        neighbours: np.ndarray | None = None) -> np.ndarray:
    """Map every vertex of mesh 1 to every candidate vertex of mesh 2 through ``C_21``.

    For target meshes up to :data:`BRUTE_FORCE_MAX` vertices this is the plain nearest
    neighbour of each row of ``Φ1`` among all rows of ``Φ2 C_21ᵀ``
    (:func:`p2p_from_functional_map`): O(n1 n2 k). Above, each
    vertex ``i`` only considers the ``n_candidates`` vertices of mesh 2 nearest in space
    to its coarse image ``coarse_12[i]`` (e.g. a map onto a few thousand samples): O(n1 c k),
    which turns minutes into a second at 25k vertices. ``neighbours`` may pass the table of
    every mesh-2 vertex's spatial neighbours, ``(n2, c)`` (:func:`spatial_neighbours`), when
    the map is refined several times; otherwise they are searched for the distinct coarse
    images, O(u log n2).
    """
    if len(V2) <= BRUTE_FORCE_MAX:
        return p2p_from_functional_map(basis1, basis2, C_21)
    from geoshape.geometry._kernels import nearest_among_candidates

    E1, E2 = aligned_bases(basis1, basis2, C_21)
    coarse = np.asarray(coarse_12, dtype=np.int64)
    if neighbours is None:
        uniq, inverse = np.unique(coarse, return_inverse=True)
        cand = spatial_neighbours(V2, n_candidates, rows=uniq)[inverse]
    else:
        cand = neighbours[coarse]
    return nearest_among_candidates(np.ascontiguousarray(E1), np.ascontiguousarray(E2),
                                    np.ascontiguousarray(cand))


def spatial_neighbours(V: np.ndarray, n_candidates: int = 64, rows: np.ndarray | None = None) -> np.ndarray:
    """The ``min(n_candidates, n)`` vertices nearest in space to each vertex of ``rows``
    (default: every vertex), nearest first: ``(len(rows), c)`` int64. KD-tree, O(r c log n)."""
    V = np.asarray(V, dtype=np.float64)
    return k_nearest(V, V if rows is None else V[rows], n_candidates)[1]


def soft_read_off(basis1: LaplacianBasis, basis2: LaplacianBasis, p2p_12: np.ndarray, V2: np.ndarray,
                  rings2: sp.csr_matrix, temperature: float) -> np.ndarray:
    """One more ZoomOut step whose point map is read off softly: ``p2p_12 (n1,)`` refined.

    The functional map ``C_21`` of ``p2p_12`` on the whole bases; then for each vertex of
    mesh 1 the vertices of mesh 2 in the ring around its current image (row ``p2p_12[i]`` of
    ``rings2``, e.g. :func:`~geoshape.geometry.mesh.vertex_rings`) are weighted by how near
    they are in the aligned spectral bases (:func:`aligned_bases`), relative to the nearest
    (weight ``exp(-(s − s_min) / (temperature · s_min))`` of squared distances ``s``), and the
    vertex taken is the one nearest their weighted mean position. A nearest neighbour keeps
    the noise of the highest basis functions (a vertex jumps between rows about as near);
    the mean over the near ones averages it out. Rings, not spatial neighbours: a mean over
    two limbs that touch would land between them.
    ``temperature`` has no unit (> 0; 1: a candidate twice as far in squared distance as the
    nearest weighs e⁻¹ of it). O((n1 + n2) k² + n1 c (k + 3)) time for rings of c vertices.
    """
    from geoshape.geometry._kernels import soft_nearest_in_rows

    if not temperature > 0:
        raise InvalidOptionError(f"the soft read-off needs a temperature > 0, got {temperature!r}")
    k = min(basis1.k, basis2.k)
    p2p = np.asarray(p2p_12, dtype=np.int64)
    E1, E2 = aligned_bases(basis1, basis2, functional_map_from_p2p(basis1, basis2, p2p, k, k))
    return soft_nearest_in_rows(np.ascontiguousarray(E1), np.ascontiguousarray(E2),
                                rings2.indptr.astype(np.int64), rings2.indices.astype(np.int64), p2p,
                                np.ascontiguousarray(V2, dtype=np.float64), float(temperature))
