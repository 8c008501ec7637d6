"""Proximity anchors between two 3D embeddings and the anchored match (thesis §4.3 step 5;
the 2D proximity heuristic of §3.1.3 is :func:`geoshape.contour.matching.proximity_match`).

Anchors: the pair of smallest embedding distance, then pairs penalised for lying near
the previous anchors (minus half the normalised geodesic distance to the nearest one). Each
vertex ``i`` of mesh 1 is then matched to

    argmin_j  z(i, j) + Σ_l α_l |g1(i, a1_l) − g2(j, a2_l)|

with ``z`` the embedding distance divided by the embedding's mean radius and ``g`` the
geodesic distance divided by each mesh's largest distance to the anchor, so both terms
are O(1). No dense n1 × n2 matrix is formed: candidates are each vertex's
``n_candidates`` nearest neighbours in the embedding, rescored. Time O(n1 c (k + h)) after
the KD-tree, memory O(n1 c).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoshape.geometry.knn import k_nearest


def _scale(A: np.ndarray) -> float:
    return float(np.linalg.norm(A - A.mean(0), axis=1).mean()) or 1.0


def proximity_anchors(A, B, geodesic1: Callable[[int], np.ndarray], geodesic2: Callable[[int], np.ndarray],
                      *, n_anchors: int = 3, n_candidates: int = 20):
    """Choose ``n_anchors`` anchor pairs.

    Parameters
    ----------
    A : (n1, k), B : (n2, k) — aligned embeddings
    geodesic1, geodesic2 : callables
        ``geodesicX(v)`` returns the (n,) geodesic distances from vertex ``v``.

    Returns
    -------
    anchors : list of (i, j)
    G1 : (n_anchors, n1) normalised geodesic distances from the anchors on mesh 1
    G2 : (n_anchors, n2) likewise on mesh 2
    """
    scale = _scale(A)
    dist, cand = k_nearest(B, A, n_candidates)
    z = dist / scale
    anchors, G1, G2 = [], [], []
    penalty = np.zeros_like(z)
    for _ in range(n_anchors):
        score = z - penalty
        i, c = np.unravel_index(int(np.argmin(score)), score.shape)
        j = int(cand[i, c])
        anchors.append((int(i), j))
        g1 = np.asarray(geodesic1(int(i)), dtype=np.float64)
        g2 = np.asarray(geodesic2(j), dtype=np.float64)
        g1 = g1 / (g1[np.isfinite(g1)].max() or 1.0)
        g2 = g2 / (g2[np.isfinite(g2)].max() or 1.0)
        G1.append(g1)
        G2.append(g2)
        # penalise closeness to the anchors so far: -½ (g1(i) + g2(j)) with g the distance to
        # the *nearest* previous anchor (for the second anchor this is the thesis' rule; the
        # minimum keeps later anchors away from every earlier one, where a sum can tie)
        penalty = 0.5 * (np.min(G1, axis=0)[:, None] + np.min(G2, axis=0)[cand])
    return anchors, np.asarray(G1), np.asarray(G2)


def anchored_match(A, B, G1, G2, *, alphas=None, n_candidates: int = 20) -> np.ndarray:
    """Rescore each vertex's embedding neighbours with the anchor-distance term; return p2p_12."""
    h = len(G1)
    alphas = np.ones(h) if alphas is None else np.asarray(alphas, dtype=np.float64)
    dist, cand = k_nearest(B, A, n_candidates)
    score = dist / _scale(A)
    for l in range(h):
        score = score + alphas[l] * np.abs(G1[l][:, None] - G2[l][cand])
    return cand[np.arange(len(A)), score.argmin(axis=1)]
