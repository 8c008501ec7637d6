"""Nyström extension of the top eigenvectors of a Gaussian affinity (thesis §4.5, App. B).

Only the ``l x n`` block ``C`` of affinities between ``l`` max-min samples and all
vertices is formed. With ``A = C[:, samples] = U Λ Uᵀ`` (the sample block), the
eigenvectors of the full affinity ``W`` are approximated by ``Ū = Cᵀ U Λ⁻¹``; on the
samples this reproduces ``U`` exactly, elsewhere it extends it by the cross-affinities.

Eigenvalue scale. ``A`` has ``l`` unit diagonal entries and ``W`` has ``n``, so
``λ_W ≈ (n / l) λ_A``; the eigenvalues returned estimate those of the full ``n x n``
affinity (``λ_A × n / l``), so they are directly comparable with an exact embedding of
the same mesh, and ``coords = Ū √λ`` has the same scale as the exact one. To compare
meshes of different ``n``, divide by ``n`` (``λ / n`` is the share of ``trace(W) = n``),
or use the sample eigenvalues ``λ_A`` with a fixed ``l`` (the EVD descriptor does so).

Orthogonalisation (default on). The extended columns of ``Ū`` are not exactly
orthogonal. With ``orthogonalize=True`` the eigenvectors are those of the Nyström
approximation ``W̄ = Ū Λ Ūᵀ`` itself: ``Ū = Q R`` (thin QR), then the eigenpairs of the
small matrix ``R Λ Rᵀ`` rotate ``Q``. This is the one-shot orthogonalisation of Fowlkes
et al. written through a QR factorisation, stable when ``A`` is nearly singular (its
eigenvalues below ``rcond × λ_max`` are discarded). The eigenvalues are then exactly
those of ``W̄`` (no ``n / l`` factor needed). Kernel centring (``center=True``) centres
``W̄`` as ``H W̄ H`` (``H = I − 11ᵀ/n``) and implies orthogonalisation.
"""

from __future__ import annotations

import numpy as np

from geoshape.errors import InvalidOptionError

__all__ = ["DEFAULT_N_SAMPLES", "nystrom_eigenpairs"]

#: default number of max-min samples (chosen from the fidelity benchmark, docs/RESULTS.md)
DEFAULT_N_SAMPLES = 50


def nystrom_eigenpairs(C: np.ndarray, samples: np.ndarray, m: int, *,
                       orthogonalize: bool = True, center: bool = False,
                       rcond: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """Approximate top-``m`` eigenpairs of an affinity from its sampled rows.

    Parameters
    ----------
    C : (l, n) float
        Affinities between the samples and all points (``C[i, samples[i]] = 1``).
    samples : (l,) int
        Column of ``C`` holding each sample.
    m : int
        Number of eigenpairs, ``m <= l``.
    orthogonalize : bool
        Return orthonormal eigenvectors of the Nyström approximation (see module doc).
    center : bool
        Eigenpairs of the centred kernel ``H W̄ H`` (implies ``orthogonalize``).
    rcond : float
        Eigenvalues of the sample block below ``rcond × max`` are left out of the
        orthogonalised approximation (at most ``m`` are kept regardless). A Gaussian of
        geodesic distances is indefinite; dividing by eigenvalues at its noise level
        amplifies noise. ``1e-4`` was best among 1e-6…1e-3 on TOSCA (docs/RESULTS.md).

    Returns
    -------
    lam : (m,) float64
        Estimated eigenvalues of the full ``n x n`` affinity, non-increasing.
    U : (n, m) float64
        Unit-norm eigenvector estimates (orthonormal when orthogonalised).

    Raises
    ------
    InvalidOptionError
        ``m > l`` or the sample block has numerical rank below ``m``.

    Notes
    -----
    Time O(l^3 + n l m) without, O(l^3 + n l^2) with orthogonalisation; memory O(n l).
    """
    from scipy.linalg import eigh

    C = np.asarray(C, dtype=np.float64)
    l, n = C.shape
    samples = np.asarray(samples, dtype=np.int64)
    if not 1 <= m <= l:
        raise InvalidOptionError(f"cannot estimate {m} eigenpairs from {l} samples (need m <= l)")
    A = C[:, samples]
    A = 0.5 * (A + A.T)
    lamA, UA = eigh(A)
    lamA, UA = lamA[::-1], UA[:, ::-1]
    # keep at least the m eigenpairs asked for, as long as they are positive
    r = max(int(np.sum(lamA > rcond * lamA[0])), m)
    if not lamA[m - 1] > 1e-12 * lamA[0]:
        raise InvalidOptionError(
            f"the affinity of the {l} samples has numerical rank {r} < {m} eigenpairs asked "
            "for; use fewer dimensions, more samples, or a smaller sigma"
        )
    if not (orthogonalize or center):
        Ubar = (C.T @ UA[:, :m]) / lamA[:m]  # (n, m), norms about sqrt(n / l)
        Ubar /= np.linalg.norm(Ubar, axis=0)
        return lamA[:m] * (n / l), Ubar
    Ubar = (C.T @ UA[:, :r]) / lamA[:r]  # (n, r); W̄ = Ubar diag(lamA) Ubarᵀ
    if center:
        Ubar -= Ubar.mean(axis=0)
    Q, R = _thin_qr(Ubar)
    S = (R * lamA[:r]) @ R.T
    sig, Z = eigh(0.5 * (S + S.T), subset_by_index=[r - m, r - 1])
    sig, Z = sig[::-1], Z[:, ::-1]
    return sig, Q @ Z


def _thin_qr(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Thin QR of a tall ``(n, r)`` matrix: Cholesky-QR twice on unit-norm columns.

    Two passes of Cholesky-QR are as accurate as Householder QR when ``X`` is not
    numerically rank-deficient, and run as matrix products (several times faster than
    LAPACK's QR here); falls back to Householder QR if a Cholesky factorisation fails.
    Returns ``Q (n, r)`` with orthonormal columns and upper-triangular ``R (r, r)``,
    ``X = Q R``. Overwrites ``X``.
    """
    from scipy.linalg import LinAlgError, cholesky, qr, solve_triangular

    norms = np.linalg.norm(X, axis=0)
    norms[norms == 0] = 1.0
    X /= norms
    R = np.diag(norms)
    Q = X
    try:
        for _ in range(2):
            Rk = cholesky(Q.T @ Q, lower=False)
            Q = solve_triangular(Rk, Q.T, trans="T", lower=False).T
            R = Rk @ R
    except LinAlgError:
        Q, Rh = qr(X * norms, mode="economic")
        return Q, Rh
    return np.ascontiguousarray(Q), R
