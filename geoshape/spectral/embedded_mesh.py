"""The embedded mesh: spectral coordinates as vertex positions, written as a mesh file
(thesis Fig. 4.1), with all ``k`` coordinates in a ``.npy`` sidecar.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["embedding_vertices", "save_embedding_mesh", "sidecar_path"]


def embedding_vertices(coords: np.ndarray, dims=(0, 1, 2)) -> np.ndarray:
    """Positions of the embedded mesh: three chosen embedding columns (zeros if fewer).

    Parameters
    ----------
    coords : (n, k) float
        Embedding coordinates.
    dims : 3 ints
        Columns used as x, y, z; columns beyond ``k`` are zeros.

    Returns
    -------
    V : (n, 3) float64
    """
    coords = np.asarray(coords, dtype=np.float64)
    out = np.zeros((coords.shape[0], 3))
    for j, d in enumerate(dims):
        if d < coords.shape[1]:
            out[:, j] = coords[:, d]
    return out


def save_embedding_mesh(path: str | os.PathLike, coords: np.ndarray, F, *,
                        sidecar: bool = True, colors=None) -> Path:
    """Write the embedded mesh: first three embedding coordinates as positions, same faces.

    Parameters
    ----------
    path : str or PathLike
        Mesh file (format from the suffix: .ply, .off, .obj, .stl, optionally .gz).
    coords : (n, k) float
        All embedding coordinates.
    F : (m, 3) int
        Faces of the original mesh.
    sidecar : bool
        Also write all ``k`` columns to ``<path without suffix>.npy`` (atomically).
    colors : (n, 3) or (n, 4), optional
        Vertex colours.

    Returns
    -------
    Path of the mesh written.
    """
    from geoshape.io.atomic import save_npy_atomic
    from geoshape.io.mesh_io import save_mesh

    path = Path(path)
    V = embedding_vertices(coords)
    save_mesh(path, V, np.asarray(F, dtype=np.int64).reshape(-1, 3), colors=colors)
    if sidecar:
        save_npy_atomic(sidecar_path(path), np.asarray(coords, dtype=np.float64))
    return path


def sidecar_path(path: str | os.PathLike) -> Path:
    """``OUT.npy`` for ``OUT.ply`` (and for ``OUT.ply.gz``)."""
    path = Path(path)
    name = path.name
    if name.endswith(".gz"):
        name = name[:-3]
    stem = name.rsplit(".", 1)[0] if "." in name else name
    return path.with_name(stem + ".npy")
