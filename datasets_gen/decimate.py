"""Decimation ladders with exact ground truth.

Quadric edge collapse (Garland & Heckbert's QSlim, here PyMeshLab's implementation) with
*optimal placement switched off* collapses every edge onto one of its two end points, so
each vertex that survives keeps its original coordinates bit for bit. The original id of
every surviving vertex is carried through the filter in the per-vertex quality field and
then verified against the coordinates, which gives an exact decimated-to-original map:
the ground truth of the thesis' decimation experiment (§4.2.2).

Every PyMeshLab filter parameter is passed explicitly: PyMeshLab re-uses the value of any
parameter left out from the previous call of the same filter.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geoshape.errors import GeoshapeError, InvalidOptionError
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = ["Decimated", "Collapsed", "decimate_exact", "decimate_fast", "decimation_ladder", "check_ratio",
           "DEFAULT_RATIOS", "DECIMATION_BACKENDS"]

#: ``pymeshlab``: survivors keep their coordinates, ground truth = their original ids (``.ids``);
#: ``fast-simplification``: vertices move (optimal placement), ground truth = where each
#: original vertex collapsed to (``.map``).
DECIMATION_BACKENDS = ("pymeshlab", "fast-simplification")

DEFAULT_RATIOS = (0.9, 0.75, 0.5, 0.25, 0.1)


class Decimated(NamedTuple):
    """One decimated copy of a mesh.

    Attributes
    ----------
    V : (k, 3) float64
        Kept vertices; ``V[i]`` equals ``V_original[orig_ids[i]]`` exactly.
    F : (l, 3) int64
        Triangles of the decimated mesh.
    orig_ids : (k,) int64
        For each decimated vertex, its 0-based id in the original mesh (all distinct).
    fraction : float
        Achieved vertex fraction ``k / n``.
    mesh : object
        The same mesh in the caller's kind: a trimesh / Open3D / pymeshlab mesh when one was
        passed in (:func:`geoshape.io.interop.mesh_input`), else the ``(V, F)`` pair.
    """

    V: np.ndarray
    F: np.ndarray
    orig_ids: np.ndarray
    fraction: float
    mesh: object = None


class Collapsed(NamedTuple):
    """One decimated copy whose vertices may move: the ground truth is the collapse map.

    Attributes
    ----------
    V : (k, 3) float64
        Decimated vertices (positions optimised by the quadric; not original coordinates).
    F : (l, 3) int64
    collapsed_to : (n,) int64
        For each original vertex, the decimated vertex it collapsed into (every original
        vertex has one; a surviving vertex maps to itself, moved).
    fraction : float
        Achieved vertex fraction ``k / n``.
    mesh : object
        The same mesh in the caller's kind: a trimesh / Open3D / pymeshlab mesh when one was
        passed in (:func:`geoshape.io.interop.mesh_input`), else the ``(V, F)`` pair.
    """

    V: np.ndarray
    F: np.ndarray
    collapsed_to: np.ndarray
    fraction: float
    mesh: object = None


@mesh_input(returns_mesh=True)
def decimate_fast(V, F, ratio: float) -> Collapsed:
    """Decimate with fast-simplification (Fast-Quadric-Mesh-Simplification) and replay its
    collapses to get, for every original vertex, the decimated vertex it became.

    Much faster than PyMeshLab on large meshes (``geoshape bench decimate``) but vertices
    move, so the ground truth is a many-to-one map, not kept ids. ``ratio`` is the wanted
    vertex fraction in (0, 1]; the library aims at a face fraction, which is the same for
    a closed mesh. Time O(m log m).

    >>> import trimesh
    >>> m = trimesh.creation.icosphere(subdivisions=3)
    >>> d = decimate_fast(m.vertices, m.faces, 0.5)
    >>> d.collapsed_to.shape == (len(m.vertices),) and int(d.collapsed_to.max()) == len(d.V) - 1
    True
    """
    import fast_simplification

    V, F = check_mesh(V, F, name="mesh to decimate")
    ratio = check_ratio(ratio)
    if ratio == 1.0:
        return Collapsed(V.copy(), F.copy(), np.arange(len(V), dtype=np.int64), 1.0)
    _, _, collapses = fast_simplification.simplify(V, F, target_reduction=1.0 - ratio, return_collapses=True)
    Vd, Fd, mapping = fast_simplification.replay_simplification(V, F, collapses)
    Vd = np.asarray(Vd, dtype=np.float64)
    return Collapsed(Vd, np.asarray(Fd, dtype=np.int64), np.asarray(mapping, dtype=np.int64),
                     len(Vd) / len(V))


def check_ratio(ratio) -> float:
    """Return ``ratio`` as a float if it lies in (0, 1], else raise :class:`InvalidOptionError`."""
    try:
        r = float(ratio)
    except (TypeError, ValueError):
        raise InvalidOptionError(f"decimation ratio must be a number in (0, 1], got {ratio!r}") from None
    if not (0.0 < r <= 1.0) or math.isnan(r):
        raise InvalidOptionError(f"decimation ratio must lie in (0, 1], got {ratio!r}")
    return r


def _quadric_collapse(ms, target_faces: int, preserve_boundary: bool, preserve_topology: bool):
    # every parameter given: PyMeshLab keeps unpassed values from the previous call
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=int(target_faces),
        targetperc=0.0,
        qualitythr=0.3,
        preserveboundary=bool(preserve_boundary),
        boundaryweight=1.0,
        preservenormal=True,
        preservetopology=bool(preserve_topology),
        optimalplacement=False,
        planarquadric=False,
        planarweight=0.001,
        qualityweight=False,
        autoclean=True,
        selected=False,
    )


def _recover_ids(V: np.ndarray, Vd: np.ndarray, carried: np.ndarray) -> np.ndarray:
    """Original ids of decimated vertices, checked bitwise; falls back to exact lookup."""
    n = len(V)
    ids = np.rint(carried).astype(np.int64)
    ok = (ids >= 0) & (ids < n) & (carried == ids)
    ok[ok] = np.all(V[ids[ok]] == Vd[ok], axis=1)
    if not ok.all():
        # a survivor moved onto its partner's position: look the position up exactly
        from geoshape.geometry.knn import kd_tree

        bad = np.flatnonzero(~ok)
        tree = kd_tree(V)
        hits = tree.query_ball_point(Vd[bad], r=0.0)
        for i, h in zip(bad, hits, strict=True):
            exact = [j for j in h if np.array_equal(V[j], Vd[i])]
            if len(exact) != 1:
                raise GeoshapeError(
                    f"decimation moved vertex {i} to a position matching {len(exact)} original "
                    "vertices; cannot establish exact ground truth"
                )
            ids[i] = exact[0]
    if len(np.unique(ids)) != len(ids):
        raise GeoshapeError("decimation produced two vertices with the same original id")
    return ids


@mesh_input(returns_mesh=True)
def decimate_exact(
    V,
    F,
    ratio: float,
    *,
    preserve_boundary: bool = True,
    preserve_topology: bool = True,
    max_passes: int = 4,
) -> Decimated:
    """Decimate a mesh to about ``ratio`` of its vertices, keeping survivors in place.

    Parameters
    ----------
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int
    ratio : float
        Wanted fraction of vertices, in (0, 1]. ``1`` returns a copy with identity ids.
    preserve_boundary : bool
        Forbid collapses that move boundary vertices (open meshes keep their outline).
    preserve_topology : bool
        Forbid collapses that change the genus or create non-manifold edges.
    max_passes : int
        Quadric collapse is aimed at a face count; when the vertex target is missed
        (boundary or topology constraints) the filter is re-run up to this many times
        with a corrected face target.

    Returns
    -------
    Decimated
        ``(V, F, orig_ids, fraction, mesh)``; ``V == V_in[orig_ids]`` bitwise. ``fraction`` may
        exceed ``ratio`` when the constraints stop the collapse early.

    Raises
    ------
    InvalidMeshError
        Bad ``(V, F)``.
    InvalidOptionError
        ``ratio`` outside (0, 1].
    GeoshapeError
        The exact map cannot be established (should not happen for a valid mesh).

    Warns
    -----
    RuntimeWarning
        A manifold input gave a non-manifold output (only possible without
        ``preserve_topology``).

    Notes
    -----
    Time O(m log m) per pass (priority queue of edge collapses), memory O(n + m).

    Examples
    --------
    >>> import trimesh
    >>> s = trimesh.creation.icosphere(3)
    >>> d = decimate_exact(s.vertices, s.faces, 0.5)
    >>> bool((d.V == s.vertices[d.orig_ids]).all()), round(d.fraction, 2)
    (True, 0.5)
    """
    V, F = check_mesh(V, F, name="mesh to decimate")
    ratio = check_ratio(ratio)
    n = len(V)
    if ratio == 1.0:
        return Decimated(V.copy(), F.copy(), np.arange(n, dtype=np.int64), 1.0)
    import pymeshlab

    target_v = max(4, int(round(ratio * n)))
    ms = pymeshlab.MeshSet()
    ms.add_mesh(
        pymeshlab.Mesh(vertex_matrix=V, face_matrix=F, v_scalar_array=np.arange(n, dtype=np.float64))
    )
    for _ in range(max(1, int(max_passes))):
        mesh = ms.current_mesh()
        nv, nf = mesh.vertex_number(), mesh.face_number()
        if nv <= target_v:
            break
        # one interior collapse removes one vertex and two faces
        target_f = max(2, nf - 2 * (nv - target_v))
        _quadric_collapse(ms, target_f, preserve_boundary, preserve_topology)
        if ms.current_mesh().vertex_number() >= nv:  # no progress possible
            break
    mesh = ms.current_mesh()
    Vd = np.ascontiguousarray(mesh.vertex_matrix(), dtype=np.float64)
    Fd = np.ascontiguousarray(mesh.face_matrix(), dtype=np.int64)
    ids = _recover_ids(V, Vd, np.asarray(mesh.vertex_scalar_array(), dtype=np.float64))
    from geoshape_datasets_gen._topology import topology_report

    if not topology_report(Fd).manifold and topology_report(F).manifold:
        warnings.warn(
            f"decimation to {ratio:g} produced non-manifold elements from a manifold mesh "
            "(keep preserve_topology=True to avoid this)",
            RuntimeWarning,
            stacklevel=2,
        )
    return Decimated(Vd, Fd, ids, len(Vd) / n)


@mesh_input(returns_mesh=True)
def decimation_ladder(
    V,
    F,
    ratios: Sequence[float] = DEFAULT_RATIOS,
    **kwargs,
) -> list[Decimated]:
    """Decimated copies of one mesh at several vertex fractions, each mapped to the original.

    Each level is decimated from the original mesh (not from the previous level), so
    ``orig_ids`` of every level indexes the input directly.

    Parameters
    ----------
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int
    ratios : sequence of float
        Vertex fractions in (0, 1], e.g. ``(0.9, 0.75, 0.5, 0.25, 0.1)``.
    **kwargs
        Passed to :func:`decimate_exact`.

    Returns
    -------
    list of Decimated, in the order of ``ratios``.

    Notes
    -----
    Time O(len(ratios) * m log m).
    """
    ratios = [check_ratio(r) for r in ratios]
    if not ratios:
        raise InvalidOptionError("give at least one decimation ratio")
    V, F = check_mesh(V, F, name="mesh to decimate")
    return [decimate_exact(V, F, r, **kwargs) for r in ratios]


def quadric_collapse_pass(ms, n_vertices: int, *, preserve_boundary: bool) -> None:
    """One PyMeshLab quadric edge-collapse pass of ``ms``'s current mesh towards ``n_vertices``.

    Optimal placement, topology and normals preserved, planar quadrics on: the settings of
    the generators that only need a mesh of about ``n_vertices`` (no vertex ids kept, unlike
    :func:`decimate_exact`). On a closed mesh ``F ≈ 2V``, so the face target is the face count
    less twice the vertices to remove. O(m log m) for ``m`` faces.
    """
    m = ms.current_mesh()
    nv, nf = m.vertex_number(), m.face_number()
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=int(max(4, nf - 2 * (nv - n_vertices))), targetperc=0.0, qualitythr=0.5,
        preserveboundary=preserve_boundary, boundaryweight=1.0, preservenormal=True,
        preservetopology=True, optimalplacement=True, planarquadric=True, planarweight=0.001,
        qualityweight=False, autoclean=True, selected=False,
    )
