"""Telling a map from its mirror image: orientation of mapped triangles.

Intrinsic methods cannot tell left from right on a bilaterally symmetric shape: the
direct and the mirrored map cost the same. A mirror map reverses the orientation of
triangles. :func:`orientation_score` maps each triangle of mesh 1 through ``p2p_12`` and
compares the mapped triangle's normal with mesh 2's vertex normals there: +1 when every
mapped triangle keeps its orientation, −1 for a perfect reflection. Both meshes are
first given outward normals (sign of the enclosed signed volume), so the score does not
depend on each file's winding convention. O(m1) time.
"""

from __future__ import annotations

import numpy as np


def _face_normals(V, F):
    return np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])


def outward_sign(V, F) -> float:
    """+1 if the faces are wound so normals point out of the enclosed volume, else −1."""
    vol = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum()
    return 1.0 if vol >= 0 else -1.0


def vertex_normals(V, F) -> np.ndarray:
    """(n, 3) area-weighted unit vertex normals."""
    N = np.zeros_like(V)
    fn = _face_normals(V, F)
    for c in range(3):
        np.add.at(N, F[:, c], fn)
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)


def orientation_score(V1, F1, V2, F2, p2p_12) -> float:
    """Mean orientation agreement in [−1, 1] of mesh-1 triangles mapped onto mesh 2.

    Triangles collapsed by the map (two corners on one vertex) are ignored; the rest are
    weighted equally.
    """
    p2p = np.asarray(p2p_12)
    G = p2p[F1]
    keep = (G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 0] != G[:, 2])
    if not keep.any():
        return 0.0
    G = G[keep]
    mapped = _face_normals(V2, G) * outward_sign(V1, F1)
    N2 = vertex_normals(V2, F2) * outward_sign(V2, F2)
    ref = N2[G].sum(axis=1)
    return float(np.mean(np.sign(np.einsum("ij,ij->i", mapped, ref))))
