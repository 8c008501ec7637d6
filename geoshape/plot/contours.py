"""Pictures of 2D results: matched contours (thesis Fig. 3.5 style) and dissimilarity matrices.

Matplotlib is used with the non-interactive Agg canvas; files are written atomically.
"""

from __future__ import annotations

import os

import numpy as np

from geoshape.io.atomic import save_figure_atomic
from geoshape.plot.figures import new_figure, save_matrix_image

__all__ = ["plot_contour_matching", "match_colours", "match_plot_layout", "cyclic_colours",
           "plot_distance_matrix"]


#: Default number of matches joined by a line in :func:`plot_contour_matching` (``--lines``):
#: the colours carry the matching; a few lines only tie the two shapes together.
DEFAULT_MATCH_LINES = 12

#: Colour of points left unmatched (RGBA).
UNMATCHED_COLOUR = (0.72, 0.72, 0.72, 1.0)


def cyclic_colours(n: int) -> np.ndarray:
    """``(n, 4)`` RGBA colours around a hue circle (a cyclic map: the last point is close to the
    first), the HSV wheel at saturation 0.85 and value 0.9 as in the HTML viewer.

    >>> cyclic_colours(4).shape
    (4, 4)
    """
    from matplotlib.colors import hsv_to_rgb

    hue = np.arange(int(n)) / max(int(n), 1)
    rgb = hsv_to_rgb(np.column_stack([hue, np.full_like(hue, 0.85), np.full_like(hue, 0.9)]))
    return np.column_stack([rgb, np.ones(len(hue))])


def match_colours(n_a: int, n_b: int, p2p_12) -> tuple[np.ndarray, np.ndarray]:
    """Colours of the points of two matched contours: corresponding points coloured alike.

    Parameters
    ----------
    n_a, n_b : int
        Number of points of the first and second contour.
    p2p_12 : (n_a,) int
        Point of the second contour matched to each point of the first; ``-1`` = unmatched.

    Returns
    -------
    colours_a : (n_a, 4) float64 RGBA
        A cyclic colour map along the first contour (:func:`cyclic_colours`); unmatched points grey.
    colours_b : (n_b, 4) float64 RGBA
        Each matched point takes the colour of its partner (of its first partner in the first
        contour's order when several points match it); points no one matched are grey
        (:data:`UNMATCHED_COLOUR`).

    >>> a, b = match_colours(3, 4, [2, 1, 1])
    >>> bool((a[0] == b[2]).all() and (a[1] == b[1]).all() and (b[0] == UNMATCHED_COLOUR).all())
    True
    """
    p2p = np.asarray(p2p_12, dtype=np.int64).ravel()
    if len(p2p) != n_a or (p2p >= n_b).any() or (p2p < -1).any():
        raise ValueError(f"p2p_12 must hold {n_a} indices in [-1, {n_b - 1}], got {len(p2p)} values "
                         f"in [{p2p.min(initial=0)}, {p2p.max(initial=0)}]")
    colours_a = cyclic_colours(n_a)
    matched = p2p >= 0
    colours_a[~matched] = UNMATCHED_COLOUR
    colours_b = np.tile(np.asarray(UNMATCHED_COLOUR, dtype=np.float64), (n_b, 1))
    idx = np.flatnonzero(matched)[::-1]  # reversed: the first partner is written last and wins
    colours_b[p2p[idx]] = colours_a[idx]
    return colours_a, colours_b


def match_plot_layout(P, Q, *, gap: float = 0.35) -> tuple[np.ndarray, np.ndarray]:
    """Plot coordinates of two contours side by side, as :func:`plot_contour_matching` draws them.

    ``P`` and ``Q`` are in ``(x, y)`` with y up, i.e. ``(column, -row)`` as returned by
    :func:`geoshape.geometry.contour.contour_from_image`, so a shape keeps the orientation it has in
    its image (the top of the image is drawn at the top). Each shape is centred on its bounding box
    and scaled uniformly (aspect ratio kept) to unit height, or to a width of 3 if it is flatter
    than that; ``P`` is put on the left and ``Q`` on the right, ``gap`` times the wider shape's
    width apart.
    """
    def normalised(X):
        X = np.asarray(X, dtype=np.float64)
        X = X - (X.min(axis=0) + X.max(axis=0)) / 2
        return X / max(float(np.ptp(X[:, 1])), float(np.ptp(X[:, 0])) / 3, 1e-12)

    A, B = normalised(P), normalised(Q)
    space = gap * max(np.ptp(A[:, 0]), np.ptp(B[:, 0]), 0.3)
    A = A - [A[:, 0].max() + space / 2, 0.0]
    B = B - [B[:, 0].min() - space / 2, 0.0]
    return A, B


def plot_contour_matching(P, Q, p2p_12, path: str | os.PathLike, *, title: str = "",
                          lines: int = DEFAULT_MATCH_LINES, gap: float = 0.35) -> None:
    """Both contours side by side, corresponding points coloured alike (thesis Fig. 3.5 style).

    The first contour is coloured by a cyclic colour map along it; each point of the second takes
    the colour of its match, points left unmatched are grey (:func:`match_colours`). The shapes are
    upright as in their images, with equal aspect (:func:`match_plot_layout`); the first point of
    ``P`` and its match are ringed in black.

    Parameters
    ----------
    P : (N, 2) array
    Q : (M, 2) array
        Contours in ``(x, y)`` with y up, as :func:`geoshape.geometry.contour.contour_from_image`.
    p2p_12 : (N,) int
        Match in ``Q`` of each point of ``P`` (``-1``: unmatched).
    path : path-like
        Output image (format from the extension, e.g. ``.png``).
    lines : int
        Number of matches, evenly spaced along ``P``, joined by a thin line (0: none; at most all).
    gap : float
        Horizontal space between the shapes, as a fraction of the wider shape's width.
    """
    from matplotlib.collections import LineCollection

    P = np.asarray(P, dtype=np.float64)
    Q = np.asarray(Q, dtype=np.float64)
    p2p = np.asarray(p2p_12, dtype=np.int64).ravel()
    colours_a, colours_b = match_colours(len(P), len(Q), p2p)
    A, B = match_plot_layout(P, Q, gap=gap)
    fig = new_figure((8, 4.5))
    ax = fig.add_subplot(111)
    size = float(np.clip(2400 / max(len(P), len(Q)), 4, 30))  # marker area, smaller when dense
    for X, colours in ((A, colours_a), (B, colours_b)):
        # Each edge takes the colour of the point it starts from: the contour reads as a colour band.
        segments = np.stack([X, np.roll(X, -1, axis=0)], axis=1)
        ax.add_collection(LineCollection(segments, colors=colours, linewidths=2.2, zorder=2))
        ax.scatter(X[:, 0], X[:, 1], s=size, c=colours, edgecolors="none", zorder=3)
    n_lines = min(max(int(lines), 0), len(P))
    if n_lines:
        idx = np.unique(np.linspace(0, len(P), n_lines, endpoint=False).astype(np.int64))
        idx = idx[p2p[idx] >= 0]
        seg = np.stack([A[idx], B[p2p[idx]]], axis=1)
        ax.add_collection(LineCollection(seg, colors="black", linewidths=0.5, alpha=0.45, zorder=1))
    if p2p[0] >= 0:
        ax.scatter([A[0, 0], B[p2p[0], 0]], [A[0, 1], B[p2p[0], 1]], s=4 * size + 20,
                   facecolors="none", edgecolors="black", linewidths=1.0, zorder=4)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.axis("off")
    if title:
        ax.set_title(title)
    fig.text(0.5, 0.02, "colour: position along the left contour; each matched point on the right takes "
             "its partner's colour; grey: unmatched", ha="center", fontsize=8, color="0.35")
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    save_figure_atomic(fig, path, dpi=120)


def plot_distance_matrix(D, path: str | os.PathLike, *, labels=None, title: str = "") -> None:
    """Image of a dissimilarity matrix (dark = similar, as thesis Fig. 3.7), class ticks.

    ``labels`` (N,) marks class boundaries when items of a class are contiguous.
    """
    save_matrix_image(D, path, labels=labels, title=title, dpi=120)
