"""Scaffolding shared by the pictures: a headless figure, a matrix image with class
boundaries, and a plot of several labelled curves — each written atomically.
"""

from __future__ import annotations

import os

import numpy as np

from geoshape.io.atomic import save_figure_atomic

__all__ = ["new_figure", "draw_class_boundaries", "save_matrix_image", "save_curves"]


def new_figure(figsize):
    """A Matplotlib ``Figure`` on the Agg canvas: no pyplot, no display, no global state."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def draw_class_boundaries(ax, labels) -> None:
    """Thin lines between consecutive runs of equal labels on a matrix image (≤ 60 classes)."""
    labels = list(labels)
    cuts = [k for k in range(1, len(labels)) if labels[k] != labels[k - 1]]
    if len(cuts) < 60:
        for c in cuts:
            ax.axhline(c - 0.5, color="tab:orange", lw=0.4)
            ax.axvline(c - 0.5, color="tab:orange", lw=0.4)


def save_matrix_image(M, path: str | os.PathLike, *, labels=None, title: str = "", vmin=None, vmax=None,
                      dpi: int = 120) -> None:
    """Grey image of an ``(N, N)`` matrix with a colour bar and, when ``labels`` (N,) are given,
    class boundaries where consecutive labels differ."""
    M = np.asarray(M, dtype=np.float64)
    fig = new_figure((6, 5.4))
    ax = fig.add_subplot(111)
    im = ax.imshow(M, cmap="gray", interpolation="nearest", vmin=vmin, vmax=vmax)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    if labels is not None and len(labels) == len(M):
        draw_class_boundaries(ax, labels)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=dpi)


def save_curves(curves: list, path: str | os.PathLike, *, xlabel: str, ylabel: str, xlim=None, ylim=None,
                title: str | None = None, legend_loc: str = "best", marker: str | None = None):
    """Several labelled curves ``[(label, x, y), …]`` on one 5 × 4 in. plot; returns the path."""
    fig = new_figure((5, 4))
    ax = fig.add_subplot(1, 1, 1)
    for label, x, y in curves:
        ax.plot(x, y, label=label, **({"marker": marker, "ms": 3} if marker else {}))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if xlim is not None:
        ax.set_xlim(*xlim)
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title)
    if curves:
        ax.legend(loc=legend_loc)
    return save_figure_atomic(fig, path, dpi=120)
