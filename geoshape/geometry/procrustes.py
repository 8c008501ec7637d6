"""Procrustes alignment: the one home of geoshape's best-rotation (Kabsch) solve.

- :func:`kabsch` — the best proper rotations between centred point sets, batched;
- :func:`similarity_procrustes` — the best similarity (scale, rotation, translation)
  between two point sets (Umeyama), built on it.

Both accept any dimension d. The rotation comes from one d × d SVD per set of the
cross-covariance ``Pᵀ Q``; a reflection is never returned (the last singular direction is
flipped when ``det(U Vᵀ) < 0``). Cost: O(k d² + d³) per set of k points.
"""

from __future__ import annotations

import numpy as np


def kabsch(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Best proper rotations ``R`` minimising ``‖P R − Q‖`` for centred point sets.

    Parameters
    ----------
    P, Q : (..., k, d) float
        Corresponding rows, each set already centred (and scaled, if wanted).

    Returns
    -------
    R : (..., d, d) float64
        Rotations (``det R = +1``), applied on the right: ``P @ R ≈ Q``.
    trace : (...,) float64
        ``tr(Rᵀ Pᵀ Q)``, the largest value of ``Σ_i ⟨p_i R, q_i⟩`` over rotations, so that the
        least squared residual is ``‖P‖² + ‖Q‖² − 2 · trace``.

    Cost: O(k d² + d³) per set, the SVDs batched in one call.

    Examples
    --------
    >>> P = np.random.default_rng(0).normal(size=(20, 3))
    >>> P -= P.mean(axis=0)
    >>> R0 = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> R, trace = kabsch(P, P @ R0)
    >>> bool(np.allclose(R, R0)), bool(np.isclose(trace, (P**2).sum()))
    (True, True)
    """
    P, Q = np.asarray(P, dtype=np.float64), np.asarray(Q, dtype=np.float64)
    U, S, Vt = np.linalg.svd(np.swapaxes(P, -1, -2) @ Q)
    sign = np.where(np.linalg.det(U @ Vt) < 0, -1.0, 1.0)  # flip the last direction: no mirror
    S[..., -1] *= sign
    U[..., :, -1] *= sign[..., None]
    return U @ Vt, S.sum(axis=-1)


def similarity_procrustes(X: np.ndarray, Y: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The similarity ``(s, R, t)`` minimising ``‖s X R + t − Y‖`` (Umeyama 1991).

    Parameters
    ----------
    X, Y : (k, d) float
        Corresponding rows.

    Returns
    -------
    s : float
        Scale (0 when the rows of ``X`` all coincide).
    R : (d, d) float64
        A proper rotation, applied on the right.
    t : (d,) float64
        Translation: ``s X R + t ≈ Y``.

    Cost: O(k d² + d³).

    >>> X = np.random.default_rng(1).normal(size=(10, 2))
    >>> R0 = np.array([[0.0, 1], [-1, 0]])
    >>> s, R, t = similarity_procrustes(X, 3 * X @ R0 + [1, 2])
    >>> round(s, 9), bool(np.allclose(R, R0)), bool(np.allclose(t, [1, 2]))
    (3.0, True, True)
    """
    X, Y = np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64)
    mx, my = X.mean(0), Y.mean(0)
    Xc, Yc = X - mx, Y - my
    R, trace = kabsch(Xc, Yc)
    s = float(trace / max((Xc**2).sum(), 1e-300))
    return s, R, my - s * mx @ R
