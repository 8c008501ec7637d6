"""Mean curvature of a triangle mesh, the one home of geoshape's curvature of surfaces.

:func:`mean_curvature` reads the mean curvature off the Laplacian of the vertex positions
(``Δx = −2 H n`` on a smooth surface), signed against the outward normal so that it does not
depend on the file's winding, and scaled by √area so that it has no unit: a sphere gives
``2√π`` at every vertex whatever its radius. O(m) after the Laplacian (robust-laplacian's
intrinsic Delaunay cotangent Laplacian, the one the Laplace–Beltrami bases use, which stays
finite on sliver triangles).
"""

from __future__ import annotations

import numpy as np

from geoshape.geometry.mesh import laplacian_matrices, outward_vertex_normals
from geoshape.io.validate import check_mesh

__all__ = ["mean_curvature"]


def mean_curvature(V, F, *, matrices: tuple | None = None) -> np.ndarray:
    """``(n,)`` mean curvature × √area of every vertex of ``V (n, 3)``, ``F (m, 3)``.

    Positive where the surface is convex seen from outside (a sphere: ``2√π`` everywhere; a
    torus of radii R > r: ``(R + 2r cos v) / (2r (R + r cos v)) × 2π √(R r)``, negative on
    the inner equator when R < 2r), negative in saddles and dents, 0 on a plane. Pointwise
    values on a coarse or irregular mesh are noisy; project them onto a few Laplace–Beltrami
    eigenfunctions to compare two meshes. A vertex of zero area gets 0; on an open mesh the
    boundary vertices are biased (their Laplacian sees one side only). ``matrices``: the
    mesh's :func:`~geoshape.geometry.mesh.laplacian_matrices`, when already built (checked). O(m)
    after the Laplacian.

    >>> import trimesh
    >>> s = trimesh.creation.icosphere(subdivisions=4, radius=3.0)
    >>> H = mean_curvature(s.vertices, s.faces)
    >>> bool(abs(np.median(H) - 2 * np.sqrt(np.pi)) < 0.01)
    True
    """
    V, F = check_mesh(V, F, name="mesh")
    L, M = laplacian_matrices(V, F, matrices=matrices)  # L x = −M Δx
    mass = np.asarray(M.diagonal()).ravel()
    area = float(mass.sum())
    curvature_normal = (L @ V) / np.maximum(2.0 * mass, 1e-300)[:, None]  # H n
    H = np.einsum("ij,ij->i", curvature_normal, outward_vertex_normals(V, F))
    H[~(mass > 0)] = 0.0
    return H * np.sqrt(max(area, 0.0))
