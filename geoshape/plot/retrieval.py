"""Headless pictures of retrieval: similarity-matrix image, query result strips, precision–recall.

Everything draws on a matplotlib ``Figure`` (Agg, no pyplot, no display) and is written
atomically. Meshes are drawn by our own orthographic projection with flat Lambert shading
and the painter's algorithm (``PolyCollection``), O(m log m) per mesh.
"""

from __future__ import annotations

import os

import numpy as np

from geoshape.geometry.mesh import face_normals
from geoshape.io.validate import check_mesh
from geoshape.plot.figures import save_curves, save_matrix_image

__all__ = ["plot_similarity_matrix", "draw_mesh", "plot_query_strip"]


def _save(fig, path) -> None:
    from geoshape.io.atomic import save_figure_atomic

    save_figure_atomic(fig, path, dpi=110)


def plot_similarity_matrix(D, path: str | os.PathLike, *, labels=None, title: str = "") -> None:
    """Image of the similarity ``1 - D / max(D)`` (bright = similar, as thesis Fig. 4.12).

    Parameters
    ----------
    D : (N, N) float
        Dissimilarities (rows may be on different scales, e.g. after re-ranking; each row
        is divided by its own largest off-diagonal value).
    path : str or PathLike
    labels : (N,) optional
        Class boundaries are drawn where consecutive labels differ.
    """

    D = np.asarray(D, dtype=np.float64)
    off = D.copy()
    np.fill_diagonal(off, 0.0)
    scale = off.max(axis=1, keepdims=True)
    S = 1.0 - np.divide(off, scale, out=np.zeros_like(off), where=scale > 0)
    save_matrix_image(S, path, labels=labels, title=title, vmin=0, vmax=1, dpi=110)


def draw_mesh(ax, V, F, *, color=(0.72, 0.74, 0.8)) -> None:
    """Draw a mesh on a 2D axes, seen along its axis of least extent (PCA), shaded.

    Parameters
    ----------
    ax : matplotlib Axes
    V : (n, 3) float
    F : (m, 3) int
    """
    from matplotlib.collections import PolyCollection

    V, F = check_mesh(V, F)
    X = V - V.mean(axis=0)
    _, _, Wt = np.linalg.svd(X[:: max(1, len(X) // 5000)], full_matrices=False)
    X = X @ Wt.T  # columns: largest, middle, smallest extent
    P = X[:, :2]
    depth = X[F, 2].mean(axis=1)
    order = np.argsort(depth)  # far first (viewer on +z)
    nrm = face_normals(X, F)
    shade = 0.3 + 0.7 * np.abs(nrm[:, 2])
    colors = np.clip(np.asarray(color)[None, :] * shade[:, None], 0, 1)
    ax.add_collection(PolyCollection(P[F][order], facecolors=colors[order], edgecolors="none"))
    lo, hi = P.min(axis=0), P.max(axis=0)
    pad = 0.05 * float((hi - lo).max() or 1.0)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.axis("off")


def plot_query_strip(query, results, path: str | os.PathLike, *, query_title: str = "query",
                     titles=None, relevant=None) -> None:
    """Query mesh followed by its ranked results in one row.

    Parameters
    ----------
    query : (V, F)
    results : list of (V, F)
        Ranked results (e.g. the top 10).
    path : str or PathLike
    titles : list of str, optional
        One caption per result (name and distance).
    relevant : list of bool, optional
        Green caption when True, red when False.
    """
    from matplotlib.figure import Figure

    n = len(results) + 1
    fig = Figure(figsize=(1.6 * n, 2.0))
    for k in range(n):
        ax = fig.add_subplot(1, n, k + 1)
        V, F = query if k == 0 else results[k - 1]
        draw_mesh(ax, V, F, color=(0.85, 0.65, 0.4) if k == 0 else (0.72, 0.74, 0.8))
        if k == 0:
            ax.set_title(query_title, fontsize=7)
        elif titles is not None:
            col = "black"
            if relevant is not None:
                col = "tab:green" if relevant[k - 1] else "tab:red"
            ax.set_title(titles[k - 1], fontsize=6, color=col)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.02, top=0.85, wspace=0.05)
    _save(fig, path)


def plot_precision_recall(curves: dict, path: str | os.PathLike, title: str | None = None):
    """Draw several precision–recall curves on one plot and write it atomically.

    Parameters
    ----------
    curves : dict
        ``{method name: (recall, precision)}`` or ``{name: retrieval_metrics(...) dict}``.
    path : str or PathLike
        Output image; the format follows the extension (``.png``, ``.pdf``, ``.svg``).
    title : str or None

    Returns
    -------
    pathlib.Path
        The written file.
    """

    lines = []
    for name, curve in curves.items():
        r, p = (curve["pr_recall"], curve["pr_precision"]) if isinstance(curve, dict) else curve
        lines.append((str(name), r, p))
    return save_curves(lines, path, xlabel="recall", ylabel="precision", xlim=(0, 1), ylim=(0, 1.02),
                       title=title, legend_loc="lower left", marker="o")
