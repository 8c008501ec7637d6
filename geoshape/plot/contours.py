"""Pictures of 2D results: matched contours (thesis Fig. 3.5 style) and dissimilarity matrices.

Matplotlib is used with the non-interactive Agg canvas; files are written atomically.
"""

from __future__ import annotations

import os

import numpy as np

from geoshape.io.atomic import save_figure_atomic
from geoshape.plot.figures import new_figure, save_matrix_image

__all__ = ["plot_contour_matching", "plot_distance_matrix"]


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
    fig = new_figure((8, 4.5))
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


def plot_distance_matrix(D, path: str | os.PathLike, *, labels=None, title: str = "") -> None:
    """Image of a dissimilarity matrix (dark = similar, as thesis Fig. 3.7), class ticks.

    ``labels`` (N,) marks class boundaries when items of a class are contiguous.
    """
    save_matrix_image(D, path, labels=labels, title=title, dpi=120)
