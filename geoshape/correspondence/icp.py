"""Iterative closest point: non-rigid with thin-plate splines (spectral domain) and rigid.

Non-rigid (thesis §4.3 step 4): move mesh 2's embedding ``B`` onto mesh 1's ``A`` by a
thin-plate spline fitted on ``c`` farthest-point control points of ``B``, each paired with
its current nearest point of ``A``; λ starts at the mean distance between embedded point
pairs and is annealed geometrically; stop when the controls' matches stop changing.
Cost per iteration: O(c^3 + n2 c k + (n1 + n2) log n1).

Rigid (baseline): similarity transform (rotation, translation, uniform scale) by
Procrustes on nearest neighbours, started from the PCA-aligned pose.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoshape.correspondence.tps import fit_tps
from geoshape.geometry.knn import nearest, nearest_searcher
from geoshape.geometry.procrustes import similarity_procrustes
from geoshape.geometry.sampling import euclidean_farthest_point_sampling


def mean_pair_distance(A: np.ndarray, B: np.ndarray, n: int = 200, seed: int = 0) -> float:
    """Mean distance between embedded points of ``A`` and ``B`` (on ≤ n samples of each)."""
    from scipy.spatial.distance import cdist

    rng = np.random.default_rng(seed)
    a = A[rng.choice(len(A), min(n, len(A)), replace=False)]
    b = B[rng.choice(len(B), min(n, len(B)), replace=False)]
    return float(cdist(a, b).mean())


def nonrigid_icp(A, B, *, n_iter: int = 8, n_controls: int = 300, lam: float | None = None,
                 anneal: float = 0.5, seed: int = 0, return_transform: bool = False,
                 controls: np.ndarray | None = None,
                 nearest_in_A: Callable[[np.ndarray], np.ndarray] | None = None):
    """Warp ``B (n2, k)`` towards ``A (n1, k)`` with thin-plate splines.

    ``controls`` (row indices of ``B``) replaces the farthest-point choice of the
    ``n_controls`` controls, e.g. to share them between the signed orders of one
    embedding. The nearest-point search structure on ``A`` is built once per call, or
    passed as ``nearest_in_A`` (:func:`~geoshape.geometry.knn.nearest_searcher` of ``A``)
    to share it between calls with the same ``A``.

    Returns
    -------
    B_warped : (n2, k) float64 — or, with ``return_transform``, the fitted
        :class:`~geoshape.correspondence.tps.ThinPlateSpline` (identity if no iteration ran),
        to apply to just the rows a caller needs
    info : dict with ``iterations``, ``lambdas`` (λ per iteration), ``changed`` (share of
        controls whose match changed per iteration).
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    if controls is None:
        ctrl = euclidean_farthest_point_sampling(B, n_controls, seed)
    else:
        ctrl = np.asarray(controls)
    lam = mean_pair_distance(A, B, seed=seed) if lam is None else float(lam)
    nearest_in_A = nearest_searcher(A) if nearest_in_A is None else nearest_in_A
    B_ctrl = B[ctrl]
    warped_ctrl = B_ctrl  # only the controls are warped inside the loop: O(c^2 k) per step
    tps = None
    prev = None
    info = {"iterations": 0, "lambdas": [], "changed": []}
    for _ in range(n_iter):
        match = nearest_in_A(warped_ctrl)
        changed = 1.0 if prev is None else float(np.mean(match != prev))
        info["changed"].append(changed)
        if prev is not None and changed == 0.0:
            break
        tps = fit_tps(B_ctrl, A[match], lam)
        warped_ctrl = tps(B_ctrl)
        info["lambdas"].append(lam)
        info["iterations"] += 1
        lam *= anneal
        prev = match
    if tps is None:
        tps = fit_tps(B_ctrl, B_ctrl, 0.0)
    return (tps if return_transform else tps(B)), info


def rigid_icp(X1, X2, *, n_iter: int = 50, tol: float = 1e-7) -> tuple[np.ndarray, np.ndarray]:
    """Align point set ``X2`` to ``X1`` rigidly (with uniform scale); return (X2_aligned, p2p_12).

    Starts from principal axes (the best of the 4 proper sign choices) to survive large
    rotations; then alternates nearest neighbours and Procrustes. O(iter · n log n).
    """
    X1 = np.asarray(X1, dtype=np.float64)
    X2 = np.asarray(X2, dtype=np.float64)

    def frame(X):
        c = X.mean(0)
        _, S, Vt = np.linalg.svd(X - c, full_matrices=False)
        return c, Vt, S.sum()

    c1, R1, s1 = frame(X1)
    c2, R2, s2 = frame(X2)
    best = None
    for signs in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)):
        Y = (X2 - c2) @ R2.T * signs @ R1 * (s1 / s2) + c1
        for _ in range(n_iter):
            d, j = nearest(X1, Y)
            s, R, t = similarity_procrustes(Y, X1[j])
            Y_new = s * Y @ R + t
            if np.abs(Y_new - Y).max() < tol:
                Y = Y_new
                break
            Y = Y_new
        d, _ = nearest(X1, Y)
        if best is None or d.mean() < best[0]:
            best = (float(d.mean()), Y)
    Y = best[1]
    _, p2p_12 = nearest(Y, X1)
    return Y, p2p_12
