"""Combinatorial checks on generated meshes: manifoldness, boundary, components.

The generators promise properties (a closed manifold figure, a decimated copy without
non-manifold edges); these helpers let them verify the promise and let the tests say so.
All checks are on the face array only and cost O(m log m) for m faces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from geoshape.geometry.mesh import vertex_components


@dataclass(frozen=True)
class TopologyReport:
    """Counts describing the combinatorial structure of a triangle mesh.

    Attributes
    ----------
    n_vertices, n_faces, n_edges : int
        Counts of referenced vertices, faces and unique undirected edges.
    n_components : int
        Connected components of the face graph (faces sharing a vertex).
    n_boundary_edges : int
        Edges used by exactly one face.
    n_nonmanifold_edges : int
        Edges used by three or more faces.
    n_nonmanifold_vertices : int
        Vertices whose faces form more than one fan (a pinch point).
    n_inconsistent_edges : int
        Interior edges traversed in the same direction by both faces (winding flips).
    n_degenerate_faces : int
        Faces that repeat a vertex index.
    euler : int
        V - E + F over referenced vertices.
    """

    n_vertices: int
    n_faces: int
    n_edges: int
    n_components: int
    n_boundary_edges: int
    n_nonmanifold_edges: int
    n_nonmanifold_vertices: int
    n_inconsistent_edges: int
    n_degenerate_faces: int
    euler: int

    @property
    def manifold(self) -> bool:
        """Every edge has one or two faces, every vertex one fan, no repeated indices."""
        return (
            self.n_nonmanifold_edges == 0
            and self.n_nonmanifold_vertices == 0
            and self.n_degenerate_faces == 0
        )

    @property
    def watertight(self) -> bool:
        """Manifold, closed (no boundary edge) and consistently oriented."""
        return self.manifold and self.n_boundary_edges == 0 and self.n_inconsistent_edges == 0

    @property
    def genus(self) -> float:
        """Genus of a closed connected surface, ``(2 - euler) / 2`` (meaningless otherwise)."""
        return (2 * self.n_components - self.euler) / 2


def topology_report(F: np.ndarray) -> TopologyReport:
    """Count boundary, non-manifold and inconsistently oriented elements of ``F``.

    Parameters
    ----------
    F : (m, 3) int array
        Triangles.

    Returns
    -------
    TopologyReport

    Notes
    -----
    Time O(m log m) (sorting edges), memory O(m).

    Examples
    --------
    >>> import numpy as np
    >>> tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    >>> r = topology_report(tet)
    >>> r.watertight, r.euler, r.n_components
    (True, 2, 1)
    """
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    degenerate = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    used = np.unique(F)
    n_v = len(used)
    # directed half-edges i -> j of every face
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])  # (3m, 2)
    und = np.sort(he, axis=1)
    edges, inverse, counts = np.unique(und, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    n_e = len(edges)
    n_boundary = int(np.sum(counts == 1))
    n_nonmanifold_e = int(np.sum(counts > 2))
    # orientation: on a two-face edge the two half-edges must run opposite ways
    forward = he[:, 0] < he[:, 1]
    n_forward = np.bincount(inverse, weights=forward, minlength=n_e)
    inconsistent = (counts == 2) & (n_forward != 1)
    n_inconsistent = int(np.sum(inconsistent))
    # vertex fans: nodes are (vertex, neighbour) pairs; each face corner at v joins the
    # pairs (v, a) and (v, b) of its two edges at v; one component per vertex = one fan
    n_nonmanifold_v = 0
    if m:
        n_id = int(F.max()) + 1
        corners_v = F.ravel()  # corner k of face f is F[f, k]
        corners_a = F[:, [1, 2, 0]].ravel()
        corners_b = F[:, [2, 0, 1]].ravel()
        key_a = corners_v * n_id + corners_a
        key_b = corners_v * n_id + corners_b
        keys, node = np.unique(np.concatenate([key_a, key_b]), return_inverse=True)
        node = node.ravel()
        k = len(corners_v)
        graph = sp.coo_matrix((np.ones(k), (node[:k], node[k:])), shape=(len(keys),) * 2)
        _, label = connected_components(graph, directed=False)
        owner = keys // n_id
        fans = np.unique(np.column_stack([owner, label]), axis=0)
        per_vertex = np.bincount(fans[:, 0], minlength=n_id)
        n_nonmanifold_v = int(np.sum(per_vertex > 1))
    n_comp = 0
    if m:  # faces sharing a vertex <=> their vertices are joined by face edges
        _, comp = vertex_components(int(F.max()) + 1, F)
        n_comp = len(np.unique(comp[used]))
    return TopologyReport(
        n_vertices=n_v,
        n_faces=m,
        n_edges=n_e,
        n_components=int(n_comp),
        n_boundary_edges=n_boundary,
        n_nonmanifold_edges=n_nonmanifold_e,
        n_nonmanifold_vertices=n_nonmanifold_v,
        n_inconsistent_edges=n_inconsistent,
        n_degenerate_faces=int(degenerate.sum()),
        euler=int(n_v - n_e + m),
    )
