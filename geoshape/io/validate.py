"""Validation at the public boundary: one helper per kind of input.

Every public function that takes a mesh calls :func:`check_mesh` once (functions that take
faces and a vertex count: :func:`check_face_indices`, its face half), every function that
takes a contour calls :func:`check_contour`; the error quotes what was received.
Cost: O(n + m) for a mesh with n vertices and m faces, O(N) for a contour.
"""

from __future__ import annotations

import numpy as np

from geoshape.errors import InvalidContourError, InvalidMeshError


def check_mesh(
    V,
    F,
    *,
    name: str = "mesh",
    allow_no_faces: bool = False,
    min_vertices: int = 3,
) -> tuple[np.ndarray, np.ndarray]:
    """Coerce and check a triangle mesh.

    Parameters
    ----------
    V : (n, 3) array_like of float
        Vertex positions. Must be finite.
    F : (m, 3) array_like of int
        Triangles as 0-based vertex indices into ``V``.
    name : str
        How the mesh is named in error messages (a file name, "source mesh", …).
    allow_no_faces : bool
        Accept ``m == 0`` (a point cloud), e.g. for the structural graph.
    min_vertices : int
        Fewest vertices accepted.

    Returns
    -------
    V : (n, 3) float64, C-contiguous
    F : (m, 3) int64, C-contiguous

    Raises
    ------
    InvalidMeshError
        Wrong shapes or dtypes, NaN/inf coordinates, face indices out of range,
        too few vertices, no faces.

    Examples
    --------
    >>> V, F = check_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> V.dtype, F.dtype, F.shape
    (dtype('float64'), dtype('int64'), (1, 3))
    """
    try:
        V = np.ascontiguousarray(V, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidMeshError(f"{name}: vertices are not numeric: {exc}") from None
    if V.ndim != 2 or V.shape[1] != 3:
        raise InvalidMeshError(f"{name}: vertices must have shape (n, 3), got {V.shape}")
    if V.shape[0] < min_vertices:
        raise InvalidMeshError(
            f"{name}: needs at least {min_vertices} vertices, got {V.shape[0]}"
        )
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise InvalidMeshError(
            f"{name}: {int(bad.sum())} vertices have NaN or infinite coordinates "
            f"(first: vertex {first} = {V[first].tolist()})"
        )
    F = check_face_indices(F, V.shape[0], name=name)
    if F.shape[0] == 0 and not allow_no_faces:
        raise InvalidMeshError(f"{name}: has no faces")
    return V, F


def check_face_indices(F, n: int, *, name: str = "mesh") -> np.ndarray:
    """Coerce and check triangles as indices into ``n`` vertices (the face half of
    :func:`check_mesh`, for functions that take ``F`` and a vertex count).

    Returns ``F (m, 3)`` int64, C-contiguous (``m`` may be 0). Raises
    :class:`InvalidMeshError` for a non-integer, non-triangle or ragged array and for an
    index outside ``[0, n − 1]``. O(m).

    Examples
    --------
    >>> check_face_indices([[0.0, 1.0, 2.0]], 3).dtype
    dtype('int64')
    """
    try:
        F_in = np.asarray(F)
    except (TypeError, ValueError) as exc:  # e.g. ragged rows
        raise InvalidMeshError(f"{name}: faces are not an (m, 3) integer array: {exc}") from None
    if F_in.size == 0:
        F_in = F_in.reshape(0, 3)
    if F_in.dtype.kind not in "iu":
        if F_in.dtype.kind == "f" and np.all(np.isfinite(F_in)) and np.all(F_in == np.round(F_in)):
            F_in = F_in.astype(np.int64)
        else:
            raise InvalidMeshError(f"{name}: faces must be integers, got dtype {F_in.dtype}")
    F = np.ascontiguousarray(F_in, dtype=np.int64)
    if F.ndim != 2 or F.shape[1] != 3:
        raise InvalidMeshError(f"{name}: faces must have shape (m, 3) (triangles), got {F.shape}")
    if F.size:
        lo, hi = int(F.min()), int(F.max())
        if lo < 0 or hi >= n:
            raise InvalidMeshError(
                f"{name}: face indices must lie in [0, {n - 1}], got values in [{lo}, {hi}]"
            )
    return F


def check_contour(P, *, name: str = "contour", min_points: int = 8) -> np.ndarray:
    """Coerce and check a closed 2D contour.

    Parameters
    ----------
    P : (N, 2) array_like of float
        Points in order along the contour; the last point connects back to the first
        (do not repeat the first point at the end; a repeated closing point is dropped).
    name : str
        How the contour is named in error messages.
    min_points : int
        Fewest points accepted.

    Returns
    -------
    P : (N, 2) float64, C-contiguous

    Raises
    ------
    InvalidContourError
        Wrong shape, NaN/inf, too few points, zero perimeter or zero enclosed area
        (a degenerate contour that folds onto itself), or consecutive duplicate points only.
    """
    try:
        P = np.ascontiguousarray(P, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidContourError(f"{name}: points are not numeric: {exc}") from None
    if P.ndim != 2 or P.shape[1] != 2:
        raise InvalidContourError(f"{name}: points must have shape (N, 2), got {P.shape}")
    if not np.isfinite(P).all():
        n_bad = int((~np.isfinite(P).all(axis=1)).sum())
        raise InvalidContourError(f"{name}: {n_bad} points have NaN or infinite coordinates")
    if len(P) > 1 and np.array_equal(P[0], P[-1]):
        P = P[:-1]
    if len(P) < min_points:
        raise InvalidContourError(f"{name}: needs at least {min_points} points, got {len(P)}")
    x, y = P[:, 0], P[:, 1]
    with np.errstate(over="ignore", invalid="ignore"):  # huge coordinates: checked just below
        perimeter = float(np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1).sum())
        area = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    if perimeter <= 0:
        raise InvalidContourError(f"{name}: all points coincide (zero perimeter)")
    if not (np.isfinite(perimeter) and np.isfinite(area)):
        raise InvalidContourError(f"{name}: coordinates too large (perimeter or area overflows float64)")
    if abs(area) <= 1e-9 * perimeter * perimeter:
        raise InvalidContourError(
            f"{name}: encloses no area (degenerate: the points lie on a line or fold back)"
        )
    return P
