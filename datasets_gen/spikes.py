"""Outlier spikes on a mesh (the contamination experiment of the thesis, §4.7).

A spike is made by picking a face at random, adding a vertex at its centroid joined to
the three corners (the face becomes three faces) and pulling that vertex off the surface
along the face normal. Original vertices are neither moved nor renumbered, so the ground
truth between the clean and the spiky mesh is the identity on ids ``0 .. n-1``; spike
vertices are appended after them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from geoshape._options import check_whole
from geoshape.errors import InvalidOptionError
from geoshape.geometry.mesh import face_normals
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = ["Spiked", "add_spikes"]


class Spiked(NamedTuple):
    """A mesh with spikes added.

    Attributes
    ----------
    V : (n + k, 3) float64
        Original vertices (unchanged, ids ``0..n-1``) followed by the k spike tips.
    F : (m + 2k, 3) int64
        Faces: each chosen face is replaced in place by its first sub-face, the other
        two sub-faces are appended.
    faces : (k,) int64
        Index (in the input ``F``) of the face each spike grew from, in spike order.
    offsets : (k,) float64
        Signed distance of each tip from its face plane along the face's unit normal.
    mesh : object
        The same mesh in the caller's kind: a trimesh / Open3D / pymeshlab mesh when one was
        passed in (:func:`geoshape.io.interop.mesh_input`), else the ``(V, F)`` pair.
    """

    V: np.ndarray
    F: np.ndarray
    faces: np.ndarray
    offsets: np.ndarray
    mesh: object = None


@mesh_input(returns_mesh=True)
def add_spikes(V, F, count: int, height: float, *, seed: int = 0) -> Spiked:
    """Add ``count`` spikes pulled ``height`` × (bounding-box diagonal) off random faces.

    Parameters
    ----------
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int
    count : int
        Number of spikes, ``0 <= count <=`` number of non-degenerate faces. Faces are
        drawn without replacement (one spike per face). 10–50 is the thesis' range.
    height : float
        Distance of each tip from its face plane, as a fraction of the diagonal of the
        mesh's axis-aligned bounding box; ``>= 0``. Tips go along the face normal given
        by the face's winding (outwards on a consistently oriented closed mesh).
    seed : int
        Seed of the face draw; same inputs and seed give the same output.

    Returns
    -------
    Spiked
        ``(V, F, faces, offsets, mesh)`` with ``V[:n]`` identical to the input; ``mesh`` is
        the spiky mesh in the caller's kind (a trimesh in, a trimesh out).

    Raises
    ------
    InvalidMeshError
        Bad ``(V, F)``.
    InvalidOptionError
        Negative or non-integer ``count``, more spikes than usable faces, negative or
        non-finite ``height``.

    Notes
    -----
    Time O(n + m), memory O(n + m).

    Examples
    --------
    >>> import trimesh
    >>> s = trimesh.creation.icosphere(2)
    >>> out = add_spikes(s.vertices, s.faces, 10, 0.05, seed=1)
    >>> out.V.shape[0] - len(s.vertices), out.F.shape[0] - len(s.faces)
    (10, 20)
    """
    V, F = check_mesh(V, F, name="mesh to spike")
    count = check_whole("spike count", count, 0)
    try:
        height = float(height)
    except (TypeError, ValueError):
        raise InvalidOptionError(f"spike height must be a number >= 0, got {height!r}") from None
    if not math.isfinite(height) or height < 0:
        raise InvalidOptionError(
            f"spike height must be a finite fraction of the bounding-box diagonal >= 0, got {height!r}"
        )
    n, m = len(V), len(F)
    cross = face_normals(V, F, unit=False)  # (m, 3)
    norm = np.linalg.norm(cross, axis=1)
    usable = np.flatnonzero(norm > 0)
    if count > len(usable):
        raise InvalidOptionError(
            f"cannot add {count} spikes: the mesh has {m} faces, {len(usable)} of them "
            "non-degenerate (one spike per face)"
        )
    rng = np.random.default_rng(seed)
    chosen = np.sort(rng.choice(usable, size=count, replace=False)).astype(np.int64)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    offset = height * diag
    normals = cross[chosen] / norm[chosen, None]
    centroids = V[F[chosen]].mean(axis=1)
    tips = centroids + offset * normals
    tip_ids = n + np.arange(count, dtype=np.int64)
    a, b, c = F[chosen, 0], F[chosen, 1], F[chosen, 2]
    F_out = F.copy()
    F_out[chosen] = np.column_stack([a, b, tip_ids])
    extra = np.concatenate([np.column_stack([b, c, tip_ids]), np.column_stack([c, a, tip_ids])])
    return Spiked(
        V=np.concatenate([V, tips]),
        F=np.concatenate([F_out, extra]),
        faces=chosen,
        offsets=np.full(count, offset),
    )
