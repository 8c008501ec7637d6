"""Headless renders of one mesh: Lambert-shaded faces on a Matplotlib 3-D axis, and a PNG
of a mesh coloured by a per-vertex scalar (thesis Fig. 4.3 eigenvector plots).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from geoshape.errors import InvalidOptionError
from geoshape.geometry.mesh import face_normals
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = ["draw_mesh", "render_mesh_png"]


def draw_mesh(ax, V: np.ndarray, F: np.ndarray, facecolors: np.ndarray, *, elev: float = 20.0,
              azim: float = -60.0) -> None:
    """Draw a mesh with per-face RGBA colours on a 3-D matplotlib axis, Lambert-shaded
    along the view direction (painter's algorithm, O(m log m))."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    tris = V[F]
    nrm = face_normals(V, F)
    e, a = np.radians(elev), np.radians(azim)
    view = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    shade = 0.35 + 0.65 * np.abs(nrm @ view)
    facecolors = np.array(facecolors, dtype=np.float64, copy=True)
    facecolors[:, :3] *= shade[:, None]
    ax.add_collection3d(Poly3DCollection(tris, facecolors=facecolors, linewidths=0))
    center = (V.max(axis=0) + V.min(axis=0)) / 2
    r = float(np.max(V.max(axis=0) - V.min(axis=0))) / 2 or 1.0
    ax.set_xlim(center[0] - r, center[0] + r)
    ax.set_ylim(center[1] - r, center[1] + r)
    ax.set_zlim(center[2] - r, center[2] + r)
    ax.set_box_aspect((1, 1, 1), zoom=1.5)
    ax.view_init(elev=elev, azim=azim)
    ax.set_axis_off()


@mesh_input
def render_mesh_png(path: str | os.PathLike, V, F, values=None, *, cmap: str = "coolwarm",
                    elev: float = 20.0, azim: float = -60.0, size: int = 600,
                    title: str | None = None) -> Path:
    """Render a mesh coloured by a per-vertex scalar (e.g. an eigenvector) to a PNG.

    Parameters
    ----------
    path : str or PathLike
        PNG file to write (atomically).
    V : (n, 3) float
    F : (m, 3) int
    values : (n,) float, optional
        Per-vertex scalar; each face gets the mean of its vertices. Default: flat grey.
    cmap : str
        Matplotlib colour map; symmetric around 0 for signed values (eigenvectors).
    elev, azim : float
        View angles in degrees.
    size : int
        Image width and height in pixels.
    title : str, optional

    Returns
    -------
    Path of the PNG.

    Notes
    -----
    Painter's-algorithm rendering with ``Poly3DCollection``: O(m log m); fine up to about
    10^5 faces.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from geoshape.io.atomic import save_figure_atomic

    V, F = check_mesh(V, F)
    if values is not None:
        values = np.asarray(values, dtype=np.float64).ravel()
        if values.shape != (len(V),):
            raise InvalidOptionError(f"values must have shape ({len(V)},), got {values.shape}")
        fv = values[F].mean(axis=1)
        lim = float(np.max(np.abs(fv))) or 1.0
        lo, hi = (-lim, lim) if fv.min() < 0 else (float(fv.min()), float(fv.max()) or 1.0)
        norm = matplotlib.colors.Normalize(vmin=lo, vmax=hi)
        facecolors = matplotlib.colormaps[cmap](norm(fv))
    else:
        facecolors = np.tile([0.75, 0.75, 0.78, 1.0], (len(F), 1))
    fig = plt.figure(figsize=(size / 100, size / 100), dpi=100)
    try:
        ax = fig.add_subplot(projection="3d")
        draw_mesh(ax, V, F, facecolors, elev=elev, azim=azim)
        fig.subplots_adjust(left=0, right=1, bottom=0, top=0.95 if title else 1)
        if title:
            ax.set_title(title)
        return save_figure_atomic(fig, path)
    finally:
        plt.close(fig)
