"""Shape context (Belongie, Malik & Puzicha 2002) of the points of a closed contour.

For each point, a log-polar histogram of where the other points lie: distances normalised by
the mean pairwise distance (scale invariance), angles measured from the tangent at the point
(rotation invariance). The same histogramming is reused by the inner-distance shape context
with inner distances and inner angles in place of Euclidean ones.
"""

from __future__ import annotations

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError
from geoshape.io.validate import check_contour

__all__ = ["log_polar_histograms", "contour_tangent_angles", "shape_context"]


def contour_tangent_angles(P: np.ndarray) -> np.ndarray:
    """Angle of the tangent (central difference ``P[i+1] − P[i−1]``) at each point; ``(N,)``."""
    d = np.roll(P, -1, axis=0) - np.roll(P, 1, axis=0)
    return np.arctan2(d[:, 1], d[:, 0])


def log_polar_histograms(dist: np.ndarray, angle: np.ndarray, *, n_r: int = 5, n_theta: int = 12,
                         r_inner: float = 0.125, r_outer: float = 2.0,
                         normalize_by: str = "mean") -> np.ndarray:
    """Log-polar histograms from a distance and an angle matrix.

    Parameters
    ----------
    dist : (N, N) float
        ``dist[i, j]``: distance from point i to point j (diagonal ignored).
    angle : (N, N) float
        ``angle[i, j]``: direction of j seen from i, in radians, already relative to a
        reference direction at i.
    n_r, n_theta : int
        Radial (log-spaced between ``r_inner`` and ``r_outer``) and angular bin counts.
    normalize_by : {"mean", "median", "none"}
        Divide distances by the mean (or the median) off-diagonal distance first. The median
        is the robust choice: a part added or lost (a notch, a spur of boundary noise, a leg
        cut off) moves many long distances and so the mean, which shifts every radial bin;
        the median moves less. Where no part dominates the distances the two units are
        close, so the bins keep their meaning.

    Returns
    -------
    H : (N, n_r·n_theta) float64
        Histograms normalised to sum 1 (distance beyond ``r_outer`` is not counted;
        distance below ``r_inner`` falls in the innermost bin).

    Notes
    -----
    O(N²) time and memory.
    """
    if n_r < 1 or n_theta < 1 or not 0 < r_inner < r_outer:
        raise InvalidOptionError(
            f"need n_r, n_theta ≥ 1 and 0 < r_inner < r_outer; got {n_r}, {n_theta}, "
            f"{r_inner}, {r_outer}"
        )
    check_choice("normalize_by", normalize_by, ("mean", "median", "none"))
    N = dist.shape[0]
    off = ~np.eye(N, dtype=bool)
    if normalize_by == "none":
        d = dist
    else:
        d = dist / (dist[off].mean() if normalize_by == "mean" else np.median(dist[off]))
    edges = np.logspace(np.log10(r_inner), np.log10(r_outer), n_r + 1)
    r_bin = np.searchsorted(edges[1:], d, side="right")  # 0..n_r (n_r = outside)
    t_bin = np.floor(np.mod(angle, 2 * np.pi) / (2 * np.pi) * n_theta).astype(np.int64)
    t_bin = np.minimum(t_bin, n_theta - 1)
    valid = off & (r_bin < n_r)
    rows = np.broadcast_to(np.arange(N)[:, None], (N, N))[valid]
    cols = (r_bin * n_theta + t_bin)[valid]
    H = np.zeros((N, n_r * n_theta))
    np.add.at(H, (rows, cols), 1.0)
    H /= np.maximum(H.sum(axis=1, keepdims=True), 1.0)
    return H


def shape_context(P, *, n_r: int = 5, n_theta: int = 12, r_inner: float = 0.125,
                  r_outer: float = 2.0, rotation_invariant: bool = True,
                  normalize_by: str = "mean") -> np.ndarray:
    """Shape context histograms of every point of a contour.

    Parameters
    ----------
    P : (N, 2) array_like
        Contour points (closed, counter-clockwise).
    n_r, n_theta, r_inner, r_outer :
        Belongie et al.'s defaults: 5 log-radial bins between 1/8 and 2 mean distances,
        12 angular bins.
    rotation_invariant : bool
        Measure angles from the tangent at each point (otherwise from the x axis).
    normalize_by : {"mean", "median"}
        The distance unit (:func:`log_polar_histograms`): the paper's mean, or the median.

    Returns
    -------
    H : (N, n_r·n_theta) float64, rows sum to 1.

    Examples
    --------
    >>> t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    >>> shape_context(np.c_[np.cos(t), np.sin(t)]).shape
    (40, 60)
    """
    P = check_contour(P)
    diff = P[None, :, :] - P[:, None, :]  # (N, N, 2): from i to j
    dist = np.linalg.norm(diff, axis=2)
    angle = np.arctan2(diff[..., 1], diff[..., 0])
    if rotation_invariant:
        angle = angle - contour_tangent_angles(P)[:, None]
    return log_polar_histograms(dist, angle, n_r=n_r, n_theta=n_theta, r_inner=r_inner,
                                r_outer=r_outer, normalize_by=normalize_by)
