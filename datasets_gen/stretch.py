"""Non-isometric deformations with identity ground truth: axis scaling and part stretching.

Both deformations move vertices only; faces and vertex ids are unchanged, so vertex ``i``
of the stretched mesh corresponds to vertex ``i`` of the input.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from geoshape.errors import InvalidOptionError
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = ["stretch_axes", "stretch_part", "StretchedPart", "graph_distances", "MAX_PART_FACTOR"]

# Along the stretch direction the map t -> t + (s - 1) w(d) t stays monotone for the
# cosine falloff while s < ~2.47; the limit keeps a margin so stretched parts never fold.
MAX_PART_FACTOR = 2.25


@mesh_input(returns_mesh=True)
def stretch_axes(V, F, scale, *, about=None) -> np.ndarray:
    """Scale a mesh non-uniformly along the coordinate axes.

    Parameters
    ----------
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int
        Only validated (connectivity is unchanged).
    scale : (3,) array_like of float
        Positive factors for x, y, z.
    about : (3,) array_like of float, optional
        Fixed point of the scaling; the vertex centroid by default.

    Returns
    -------
    V : (n, 3) float64
        Stretched vertices (same ids, use with the input ``F``). Given one mesh object
        instead of ``V, F``: the stretched mesh in that object's kind.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [2, 0, 0], [0, 2, 0]]); F = np.array([[0, 1, 2]])
    >>> stretch_axes(V, F, [2, 1, 1], about=[0, 0, 0])[1]
    array([4., 0., 0.])
    """
    V, F = check_mesh(V, F, name="mesh to stretch")
    try:
        s = np.asarray(scale, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InvalidOptionError(f"scale must be three positive numbers, got {scale!r}") from None
    if s.shape != (3,) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise InvalidOptionError(f"scale must be three positive finite numbers, got {scale!r}")
    c = V.mean(axis=0) if about is None else np.asarray(about, dtype=np.float64).reshape(3)
    return (V - c) * s + c


@mesh_input
def graph_distances(V, F, source: int, limit: float = np.inf) -> np.ndarray:
    """Shortest-path distances along mesh edges from one vertex (Dijkstra).

    Parameters
    ----------
    V : (n, 3) float64
    F : (m, 3) int64
    source : int
    limit : float
        Stop exploring beyond this distance (farther vertices get ``inf``).

    Returns
    -------
    d : (n,) float64

    Notes
    -----
    Time O(m log n) at most, less with a small ``limit``; memory O(n + m).
    """
    from scipy.sparse.csgraph import dijkstra

    from geoshape.geometry.mesh import edge_graph

    G = edge_graph(V, F, raw_lengths=True)  # symmetric
    return dijkstra(G, directed=True, indices=int(source), limit=limit)


class StretchedPart(NamedTuple):
    """Result of :func:`stretch_part`.

    Attributes
    ----------
    V : (n, 3) float64
        Deformed vertices (ids and faces unchanged).
    weights : (n,) float64
        Falloff weight in [0, 1] of each vertex (0 outside the geodesic ball).
    center : int
        Vertex id at the centre of the ball.
    direction : (3,) float64
        Unit direction of the stretch.
    mesh : object
        The same mesh in the caller's kind: a trimesh / Open3D / pymeshlab mesh when one was
        passed in (:func:`geoshape.io.interop.mesh_input`), else the ``(V, F)`` pair.
    """

    V: np.ndarray
    weights: np.ndarray
    center: int
    direction: np.ndarray
    mesh: object = None


@mesh_input(returns_mesh=True)
def stretch_part(
    V,
    F,
    *,
    radius: float,
    factor: float,
    center: int | None = None,
    direction=None,
    seed: int = 0,
) -> StretchedPart:
    """Stretch one part of a mesh: a geodesic ball scaled along a direction, smoothly.

    Each vertex ``v`` at graph-geodesic distance ``d < R`` from the centre vertex ``c``
    moves to ``v + (factor - 1) w(d) ((v - c) . u) u`` with the cosine falloff
    ``w(d) = (1 + cos(pi d / R)) / 2``; vertices outside the ball do not move.

    Parameters
    ----------
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int
    radius : float
        Ball radius ``R`` as a fraction of the bounding-box diagonal, > 0.
    factor : float
        Stretch factor along ``u`` at the ball centre, in (0, MAX_PART_FACTOR]
        (values > 1 lengthen, < 1 shorten; the bound keeps the map fold-free along ``u``).
    center : int, optional
        Centre vertex id; drawn with ``seed`` when omitted.
    direction : (3,) array_like, optional
        Stretch direction; by default the principal axis (largest-variance direction)
        of the ball's vertices, i.e. along a limb when the ball sits on one.
    seed : int
        Seed used only to draw ``center``.

    Returns
    -------
    StretchedPart
        ``(V, weights, center, direction, mesh)``.

    Raises
    ------
    InvalidOptionError
        Radius not positive, factor outside (0, MAX_PART_FACTOR], centre out of range,
        zero direction.

    Notes
    -----
    Time O(m log n) (one truncated Dijkstra), memory O(n + m).
    """
    V, F = check_mesh(V, F, name="mesh to stretch")
    n = len(V)
    try:
        radius, factor = float(radius), float(factor)
    except (TypeError, ValueError):
        raise InvalidOptionError("radius and factor must be numbers") from None
    if not (math.isfinite(radius) and radius > 0):
        raise InvalidOptionError(
            f"radius must be a positive fraction of the bounding-box diagonal, got {radius!r}"
        )
    if not (0 < factor <= MAX_PART_FACTOR):
        raise InvalidOptionError(f"factor must lie in (0, {MAX_PART_FACTOR}], got {factor!r}")
    if center is None:
        center = int(np.random.default_rng(seed).integers(n))
    elif isinstance(center, bool) or not (0 <= int(center) < n) or int(center) != center:
        raise InvalidOptionError(f"center must be a vertex id in [0, {n - 1}], got {center!r}")
    center = int(center)
    R = radius * float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    d = graph_distances(V, F, center, limit=R)
    inside = d < R
    w = np.zeros(n)
    w[inside] = 0.5 * (1.0 + np.cos(np.pi * d[inside] / R))
    c = V[center]
    if direction is None:
        X = V[inside] - V[inside].mean(axis=0)
        if len(X) < 2:
            raise InvalidOptionError("radius is too small: the ball holds a single vertex")
        _, _, vt = np.linalg.svd(X, full_matrices=False)
        u = vt[0]
    else:
        u = np.asarray(direction, dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(u)) or np.linalg.norm(u) == 0:
            raise InvalidOptionError(f"direction must be a non-zero 3-vector, got {direction!r}")
        u = u / np.linalg.norm(u)
    t = (V - c) @ u  # (n,)
    V_out = V + ((factor - 1.0) * w * t)[:, None] * u[None, :]
    return StretchedPart(V_out, w, center, u)
