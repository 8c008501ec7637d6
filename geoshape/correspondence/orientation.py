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

from geoshape.errors import InvalidOptionError
from geoshape.geometry.mesh import (  # noqa: F401 (normals re-exported: their home is geometry.mesh)
    face_areas,
    face_normals,
    outward_sign,
    outward_vertex_normals,
    vertex_normals,
)


def patch_orientation_score(V1, F1, V2, F2, p2p_12, *, n_samples: int = 2000, radius: float = 0.1,
                            seed: int = 0, rows1: np.ndarray | None = None, max_neighbors: int = 400,
                            normals=None) -> float:
    """Orientation agreement of mapped *patches*, robust to a noisy map.

    For up to ``n_samples`` seeded vertices ``i`` of mesh 1, a vertex ``j`` at Euclidean
    distance ``radius … 2 radius`` (× √area of mesh 1) and the vertex ``l`` of that ring
    spanning the largest triangle with them give ``s1 = sign det[x_j − x_i, x_l − x_i, n_i]``
    (``n_i`` the outward surface normal). The same triple mapped through ``p2p_12`` gives
    ``s2`` on mesh 2 (normal at the image of ``i``). Returns the mean of ``s1 s2`` over
    triples whose mapped triangle is not degenerate: near +1 for an orientation-preserving
    map, near −1 for a mirror map. At this scale a map that is off by a few percent of √area
    still votes correctly, unlike the per-triangle :func:`orientation_score`.

    With ``rows1`` (vertex ids of mesh 1), ``p2p_12`` is given on those rows only
    (``p2p_12[t]`` is the image of ``rows1[t]``) and the triples are drawn among them: the
    map never needs to be known at every vertex (large meshes). ``normals`` may pass
    ``(outward_vertex_normals(V1, F1), outward_vertex_normals(V2, F2))`` computed once.

    Notes
    -----
    O(m1 + m2) for the normals, then O(s K) with ``s`` centres and ``K <= max_neighbors``
    KD-tree neighbours each, all vectorised.
    """
    from geoshape.geometry.knn import k_nearest

    p2p = np.asarray(p2p_12, dtype=np.int64)
    rng = np.random.default_rng(seed)
    area1 = face_areas(V1, F1).sum()
    r = radius * np.sqrt(area1)
    N1, N2 = normals if normals is not None else (outward_vertex_normals(V1, F1),
                                                   outward_vertex_normals(V2, F2))
    if rows1 is not None:  # work on the sampled rows: positions and normals of those only
        rows1 = np.asarray(rows1, dtype=np.int64)
        V1, N1 = V1[rows1], N1[rows1]
    if len(p2p) != len(V1):
        raise InvalidOptionError(f"the map has {len(p2p)} entries for {len(V1)} points of mesh 1")
    centers = rng.choice(len(V1), size=min(n_samples, len(V1)), replace=False)
    # enough neighbours to reach 2r on an evenly sampled surface (with some slack)
    expected = len(V1) * np.pi * (2 * r) ** 2 / max(area1, 1e-300)
    K = int(min(len(V1), max_neighbors, 1.5 * expected + 8))
    if K < 3:
        return 0.0
    dist, nbrs = k_nearest(V1, V1[centers], K)
    in_ring = (dist >= r) & (dist <= 2 * r)
    has_two = in_ring.sum(axis=1) >= 2
    centers, dist, nbrs, in_ring = centers[has_two], dist[has_two], nbrs[has_two], in_ring[has_two]
    if len(centers) == 0:
        return 0.0
    rows = np.arange(len(centers))
    j = nbrs[rows, np.argmax(in_ring, axis=1)]  # nearest ring vertex
    xi = V1[centers]
    # signed volume of (x_j - x_i, x_nb - x_i, n_i) for every neighbour; take the largest
    cross = np.cross((V1[j] - xi)[:, None, :], V1[nbrs] - xi[:, None, :])
    vol = np.einsum("skc,sc->sk", cross, N1[centers])
    vol = np.where(in_ring, vol, 0.0)
    widest = np.argmax(np.abs(vol), axis=1)
    l = nbrs[rows, widest]
    s1 = np.sign(vol[rows, widest])
    a, b, c = V2[p2p[centers]], V2[p2p[j]], V2[p2p[l]]
    s2 = np.sign(np.einsum("ij,ij->i", np.cross(b - a, c - a), N2[p2p[centers]]))
    votes = s1 * s2
    votes = votes[(s1 != 0) & (s2 != 0)]
    return float(votes.mean()) if len(votes) else 0.0


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
    mapped = face_normals(V2, G, unit=False) * outward_sign(V1, F1)
    N2 = vertex_normals(V2, F2) * outward_sign(V2, F2)
    ref = N2[G].sum(axis=1)
    return float(np.mean(np.sign(np.einsum("ij,ij->i", mapped, ref))))
