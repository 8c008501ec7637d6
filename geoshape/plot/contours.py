"""Pictures of 2D results: matched contours (thesis Fig. 3.5 style) and dissimilarity matrices.

Matplotlib is used with the non-interactive Agg canvas; files are written atomically.
"""

from __future__ import annotations

import os

import numpy as np

from geoshape.io.atomic import save_figure_atomic

__all__ = ["plot_contour_matching", "plot_distance_matrix"]


def _figure(figsize):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def plot_contour_matching(P, Q, p2p_12, path: str | os.PathLike, *, title: str = "",
                          every: int = 1, gap: float = 0.25) -> None:
    """Draw both contours side by side and a line between each matched pair.

    Parameters
    ----------
    P : (N, 2) array
    Q : (M, 2) array
    p2p_12 : (N,) int
        Match in ``Q`` of each point of ``P``.
    path : path-like
        Output image (format from the extension, e.g. ``.png``).
    every : int
        Draw one line in ``every`` points.
    gap : float
        Horizontal space between the shapes, as a fraction of their width.
    """
    P = np.asarray(P, dtype=np.float64)
    Q = np.asarray(Q, dtype=np.float64)

    def normalised(X):
        X = X - X.mean(axis=0)
        return X / max(np.ptp(X[:, 1]), 1e-12)

    A, B = normalised(P), normalised(Q)
    width = max(np.ptp(A[:, 0]), np.ptp(B[:, 0]))
    A = A - [A[:, 0].max(), 0] - [gap * width / 2 + 0.05, 0]
    B = B - [B[:, 0].min(), 0] + [gap * width / 2 + 0.05, 0]
    fig = _figure((8, 4.5))
    ax = fig.add_subplot(111)
    for X, colour in ((A, "tab:blue"), (B, "tab:red")):
        closed = np.vstack([X, X[:1]])
        ax.plot(closed[:, 0], closed[:, 1], "-", color=colour, lw=1.5)
        ax.plot(X[:, 0], X[:, 1], ".", color=colour, ms=3)
    idx = np.arange(0, len(A), max(1, int(every)))
    segs_x = np.stack([A[idx, 0], B[p2p_12[idx], 0]])
    segs_y = np.stack([A[idx, 1], B[p2p_12[idx], 1]])
    ax.plot(segs_x, segs_y, "-", color="black", lw=0.5, alpha=0.6)
    ax.plot(A[0, 0], A[0, 1], "o", color="black", ms=5)
    ax.set_aspect("equal")
    ax.axis("off")
    if title:
        ax.set_title(title)
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=120)


def draw_class_boundaries(ax, labels) -> None:
    """Thin lines between consecutive runs of equal labels on a matrix image (≤ 60 classes)."""
    labels = list(labels)
    cuts = [k for k in range(1, len(labels)) if labels[k] != labels[k - 1]]
    if len(cuts) < 60:
        for c in cuts:
            ax.axhline(c - 0.5, color="tab:orange", lw=0.4)
            ax.axvline(c - 0.5, color="tab:orange", lw=0.4)


def plot_distance_matrix(D, path: str | os.PathLike, *, labels=None, title: str = "") -> None:
    """Image of a dissimilarity matrix (dark = similar, as thesis Fig. 3.7), class ticks.

    ``labels`` (N,) marks class boundaries when items of a class are contiguous.
    """
    D = np.asarray(D, dtype=np.float64)
    fig = _figure((6, 5.4))
    ax = fig.add_subplot(111)
    im = ax.imshow(D, cmap="gray", interpolation="nearest")
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    if labels is not None and len(labels) == len(D):
        draw_class_boundaries(ax, labels)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=120)
