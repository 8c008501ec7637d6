"""Database-level re-ranking of a dissimilarity matrix, shared by 2D and 3D retrieval.

A pairwise measure ranks each query's neighbours by itself; re-ranking lets the whole
collection vote: two shapes are close when their neighbourhoods are close. The method here
is the *locally constrained diffusion process* (Yang, Koknar-Tezel & Latecki, CVPR 2009):

1. affinities ``W_ij = exp(-D_ij² / (σ_i σ_j))`` of the symmetrised matrix, with a local
   width ``σ_i`` = the distance from ``i`` to its ``k``-th nearest neighbour (self-tuning,
   Zelnik-Manor & Perona 2004), so the kernel is unit-free and adapts to dense and sparse
   parts of the collection;
2. a transition matrix restricted to each item's ``k`` nearest neighbours,
   ``P_K = D_K^-1 W_K`` (rows sum to one);
3. diffusion ``A ← P_K A P_Kᵀ`` from ``A = P`` (the full transition matrix), ``iterations``
   times. Entry ``A_ij`` is the probability that walks from ``i`` and ``j`` meet.

The result is returned as a dissimilarity (lower = more similar): ``1 - A_ij / max_j A_ij``
per row. No labels are used; the output is deterministic (no randomness, ties broken by
index). Cost: O(N² k) time per iteration (``P_K`` has ``k`` entries per row), O(N²) memory.

>>> import numpy as np
>>> x = np.r_[0.0, 0.1, 0.2, 5.0, 5.1, 5.2]
>>> D = np.abs(x[:, None] - x[None, :])
>>> R = rerank(D, k=3)
>>> bool(R[0, :3].max() < R[0, 3:].min())  # the first block stays before the second
True
"""

from __future__ import annotations

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError

__all__ = ["RERANK_METHODS", "RERANK_DEFAULTS", "rerank", "rerank_and_score", "check_rerank_method"]

#: Registered re-ranking methods (what ``--rerank`` accepts).
RERANK_METHODS = ("lcdp",)

#: Default parameters per method, chosen by cross-validation across the 2D dev collections
#: (``geoshape bench rerank``, which also shows each one halved and doubled).
RERANK_DEFAULTS = {"lcdp": {"k": 4, "iterations": 5}}


def check_rerank_method(method: str) -> str:
    """``method`` if it is registered, else :class:`InvalidOptionError` listing the valid ones."""
    return check_choice("re-ranking method", method, RERANK_METHODS)


def _check_matrix(D) -> np.ndarray:
    D = np.asarray(D, dtype=np.float64)
    if D.ndim != 2 or D.shape[0] != D.shape[1]:
        raise InvalidOptionError(f"re-ranking needs a square N x N matrix, got shape {D.shape}")
    if D.shape[0] < 3:
        raise InvalidOptionError(f"re-ranking needs at least 3 items, got {D.shape[0]}")
    if not np.all(np.isfinite(D)):
        bad = int(np.count_nonzero(~np.isfinite(D)))
        raise InvalidOptionError(
            f"re-ranking needs finite dissimilarities; the matrix has {bad} NaN/inf entries"
        )
    return D


def _check_int(name: str, value, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise InvalidOptionError(f"{name} must be an integer ≥ {low}, got {value!r}")
    return int(value)


def rerank(D, method: str = "lcdp", *, k: int | None = None, iterations: int | None = None) -> np.ndarray:
    """Re-rank an all-pairs dissimilarity matrix by diffusion over the collection.

    Parameters
    ----------
    D : (N, N) array_like of float
        Dissimilarities, rows = queries, lower = more similar (any scale; may be
        asymmetric, it is symmetrised). Finite, N ≥ 3.
    method : str
        One of :data:`RERANK_METHODS`.
    k : int, optional
        Neighbours kept per item (and the rank that sets its local width); default from
        :data:`RERANK_DEFAULTS`, clipped to ``N - 1``.
    iterations : int, optional
        Diffusion steps; default from :data:`RERANK_DEFAULTS`.

    Returns
    -------
    R : (N, N) float64
        Re-ranked dissimilarities in [0, 1], rows = queries, zero on the diagonal.

    Raises
    ------
    InvalidOptionError
        Unknown method, a matrix that is not square, has fewer than 3 rows or holds
        NaN/inf, or a bad ``k``/``iterations``.

    Notes
    -----
    O(N² k · iterations) time, O(N²) memory; 1400 shapes with the defaults take
    about a second (``geoshape bench rerank``).
    """
    check_rerank_method(method)
    D = _check_matrix(D)
    n = len(D)
    defaults = RERANK_DEFAULTS[method]
    k = min(_check_int("k", defaults["k"] if k is None else k, 1), n - 1)
    iterations = _check_int("iterations", defaults["iterations"] if iterations is None else iterations, 0)
    S = 0.5 * (D + D.T)
    S = S - min(float(S.min()), 0.0)  # tolerate negative scores: one shift keeps order and symmetry
    np.fill_diagonal(S, 0.0)
    order = np.argsort(S, axis=1, kind="stable")  # (N, N); column 0 is normally the item itself
    sigma = S[np.arange(n), order[:, k]]
    sigma = np.where(sigma > 0, sigma, np.maximum(sigma.max(), 1e-300))
    W = np.exp(-(S**2) / (sigma[:, None] * sigma[None, :]))
    P = W / W.sum(axis=1, keepdims=True)
    import scipy.sparse as sp

    rows = np.repeat(np.arange(n), k + 1)
    cols = order[:, : k + 1].ravel()  # itself and its k nearest
    weights = W[rows, cols].reshape(n, k + 1)
    weights /= weights.sum(axis=1, keepdims=True)
    PK = sp.csr_matrix((weights.ravel(), (rows, cols)), shape=(n, n))  # k + 1 entries a row
    A = P
    for _ in range(iterations):
        A = PK @ (PK @ A.T).T  # P_K A P_Kᵀ, two sparse-dense products: O(N² k)
    A = 0.5 * (A + A.T)
    np.fill_diagonal(A, A.max(axis=1))  # each item stays its own nearest
    top = A.max(axis=1, keepdims=True)
    return 1.0 - A / np.where(top > 0, top, 1.0)


def rerank_and_score(D, labels, method: str = "lcdp", **params) -> dict:
    """``{"D": re-ranked matrix, "metrics": its retrieval scores, "seconds_rerank": s}``;
    metrics are empty when every label is unique (nothing to score)."""
    import time

    from geoshape.metrics.retrieval import retrieval_metrics

    t0 = time.perf_counter()
    R = rerank(D, method, **params)
    seconds = time.perf_counter() - t0
    labels = list(labels)
    return {"D": R, "seconds_rerank": seconds,
            "metrics": retrieval_metrics(R, labels) if len(set(labels)) < len(labels) else {}}
