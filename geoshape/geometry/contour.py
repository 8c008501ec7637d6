"""Geometry of one closed 2D contour ``P (N, 2)``: tracing it from a mask, arc length,
resampling, curvature.

Contours are traced as the outer boundary of the largest 8-connected foreground component
(specks and holes are ignored), with sub-pixel accuracy by ``skimage.measure.find_contours``
on a zero-padded mask (so shapes touching the border still close), resampled uniformly by
arc length and oriented counter-clockwise in ``(x, y)`` coordinates with ``y`` pointing up
(image row ``r`` becomes ``y = -r``).

A contour is a closed polygon given by its points in order; the last point connects to the
first and is not repeated. Counter-clockwise (positive signed area) is the convention, so
that convex parts have positive signed curvature.
"""

from __future__ import annotations

import os

import numpy as np

from geoshape.errors import InvalidImageError, InvalidOptionError
from geoshape.io.validate import check_contour

__all__ = [
    "extract_contour",
    "contour_from_image",
    "signed_area",
    "orient_ccw",
    "arc_length",
    "perimeter",
    "resample_contour",
    "contour_curvature",
    "contour_geodesic_distance",
    "mirror_contour",
]


def signed_area(P: np.ndarray) -> float:
    """Signed area of the polygon (shoelace), positive when counter-clockwise. O(N)."""
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def orient_ccw(P: np.ndarray) -> np.ndarray:
    """Return ``P`` in counter-clockwise order (reversed if its signed area is negative)."""
    P = np.asarray(P, dtype=np.float64)
    return P[::-1].copy() if signed_area(P) < 0 else P


def arc_length(P: np.ndarray) -> np.ndarray:
    """Cumulative arc length at each point, ``s[0] = 0``; shape ``(N,)``. O(N)."""
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    return np.concatenate([[0.0], np.cumsum(seg[:-1])])


def perimeter(P: np.ndarray) -> float:
    """Length of the closed polygon. O(N)."""
    return float(np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1).sum())


def resample_contour(P, n_points: int) -> np.ndarray:
    """Resample a closed polygon to ``n_points`` points uniformly spaced by arc length.

    Parameters
    ----------
    P : (M, 2) array_like
        Closed polygon (first point not repeated).
    n_points : int
        Output size.

    Returns
    -------
    Q : (n_points, 2) float64
        ``Q[0] == P[0]``; consecutive points are ``perimeter / n_points`` apart along ``P``.
    """
    P = np.asarray(P, dtype=np.float64)
    closed = np.vstack([P, P[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 0])
    closed = closed[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], n_points, endpoint=False)
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def contour_curvature(P, window: int = 4, *, normalize: bool = True) -> np.ndarray:
    """Signed curvature at each point from a local cubic parametric fit.

    For point ``i`` the ``2w + 1`` points ``P[i-w .. i+w]`` (cyclically) are fitted in the
    least-squares sense by a cubic ``X(t) = (x(t), y(t))`` with ``t`` the arc length measured
    from ``P[i]``; then ``κ = (x'y'' − y'x'') / |X'|³`` at ``t = 0``. Convex points of a
    counter-clockwise contour have ``κ > 0``.

    Parameters
    ----------
    P : (N, 2) array_like
        Closed contour, N ≥ 2w + 2.
    window : int
        Half-width ``w`` of the fitting window (the thesis uses 3..5).
    normalize : bool
        Multiply by ``perimeter / 2π`` so the result is scale invariant (a circle gives 1).

    Returns
    -------
    kappa : (N,) float64

    Notes
    -----
    O(N·w) time: one 4×4 normal-equation solve per point, batched.

    Examples
    --------
    >>> t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    >>> k = contour_curvature(np.c_[3 * np.cos(t), 3 * np.sin(t)], normalize=False)
    >>> bool(np.allclose(k, 1 / 3, rtol=1e-2))
    True
    """
    P = check_contour(P)
    N = len(P)
    if window < 2 or 2 * window + 2 > N:
        raise InvalidOptionError(f"window must be in [2, {(N - 2) // 2}] for {N} points, got {window}")
    offsets = np.arange(-window, window + 1)
    idx = (np.arange(N)[:, None] + offsets[None, :]) % N  # (N, 2w+1)
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)  # seg[i] = |P[i+1] - P[i]|
    L = float(seg.sum())
    # Arc length of each window point relative to the centre (signed).
    cum = np.concatenate([[0.0], np.cumsum(np.tile(seg, 3))])  # over 3 laps
    base = N + np.arange(N)
    t = cum[base[:, None] + offsets[None, :]] - cum[base][:, None]  # (N, 2w+1)
    scale = t[:, -1:] - t[:, :1]
    scale = np.where(scale > 0, scale, 1.0)
    tn = t / scale  # conditioning
    A = np.stack([np.ones_like(tn), tn, tn**2, tn**3], axis=2)  # (N, 2w+1, 4)
    AtA = np.einsum("nki,nkj->nij", A, A)
    rhs = np.einsum("nki,nkd->nid", A, P[idx])  # (N, 4, 2)
    coef = np.linalg.solve(AtA, rhs)  # (N, 4, 2)
    d1 = coef[:, 1, :] / scale
    d2 = 2.0 * coef[:, 2, :] / scale**2
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    speed = np.linalg.norm(d1, axis=1)
    kappa = cross / np.maximum(speed, 1e-300) ** 3
    if normalize:
        kappa = kappa * (L / (2.0 * np.pi))
    return kappa


def contour_geodesic_distance(P, sources, *, normalize: bool = True) -> np.ndarray:
    """Distance along the closed contour from each source point to every point.

    Parameters
    ----------
    P : (N, 2) array_like
    sources : int or (k,) array_like of int
    normalize : bool
        Divide by the perimeter (values then lie in ``[0, 0.5]``).

    Returns
    -------
    D : (k, N) float64 (or (N,) for a scalar source); the shorter way round.
    """
    P = np.asarray(P, dtype=np.float64)
    s = arc_length(P)
    L = perimeter(P)
    src = np.atleast_1d(np.asarray(sources, dtype=np.int64))
    d = np.abs(s[None, :] - s[src][:, None])
    d = np.minimum(d, L - d)
    if normalize:
        d = d / L
    return d[0] if np.ndim(sources) == 0 else d


def mirror_contour(P) -> np.ndarray:
    """Reflect ``x → −x`` and reverse the order, so the mirror image stays counter-clockwise.

    Point ``i`` of the result is the reflection of point ``(−i) mod N`` of ``P``.
    """
    P = np.asarray(P, dtype=np.float64)
    M = P * np.array([-1.0, 1.0])
    return np.ascontiguousarray(np.roll(M[::-1], 1, axis=0))


def extract_contour(mask, n_points: int = 100, *, name: str = "mask") -> np.ndarray:
    """Outer boundary of the largest component of a mask, resampled by arc length.

    Parameters
    ----------
    mask : (h, w) array_like of bool
        Object mask (``True`` on the object).
    n_points : int
        Number of output points, uniformly spaced by arc length (≥ 8).
    name : str
        How the mask is named in errors (e.g. the image file).

    Returns
    -------
    P : (n_points, 2) float64
        Closed contour (first point not repeated), counter-clockwise, in ``(x, y)`` =
        ``(column, -row)`` pixel units. The start is the boundary point of largest ``y``
        (topmost), so it is deterministic.

    Raises
    ------
    InvalidImageError
        Empty mask, all-foreground mask, fewer than ``MIN_PIXELS`` object pixels, or a
        degenerate (zero-area) boundary.

    Notes
    -----
    Cost O(h·w) for labelling and tracing, O(n_points + boundary length) for resampling.
    """
    from scipy import ndimage
    from skimage import measure

    from geoshape.io.silhouette import MIN_PIXELS

    if n_points < 8:
        raise InvalidOptionError(f"n_points must be at least 8, got {n_points}")
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.size == 0:
        raise InvalidImageError(f"{name}: mask must be a non-empty 2D array, got shape {mask.shape}")
    mask = mask.astype(bool)
    count = int(mask.sum())
    if count == 0:
        raise InvalidImageError(f"{name}: no object pixels (empty silhouette)")
    if count == mask.size:
        raise InvalidImageError(f"{name}: every pixel is foreground (no background to separate)")
    labels = measure.label(mask, connectivity=2)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    largest = labels == int(np.argmax(sizes))
    if int(largest.sum()) < MIN_PIXELS:
        raise InvalidImageError(
            f"{name}: largest object has {int(largest.sum())} pixels (need ≥ {MIN_PIXELS})"
        )
    # Fill holes so only the outer boundary is traced.
    filled = ndimage.binary_fill_holes(largest)
    padded = np.pad(filled, 2).astype(np.float64)
    curves = measure.find_contours(padded, 0.5)
    closed = [c for c in curves if len(c) >= 4 and np.allclose(c[0], c[-1])]
    if not closed:
        raise InvalidImageError(f"{name}: the object boundary does not close")

    def area(c):
        return 0.5 * abs(np.dot(c[:, 0], np.roll(c[:, 1], -1)) - np.dot(c[:, 1], np.roll(c[:, 0], -1)))

    outer = max(closed, key=area)[:-1] - 2.0
    if area(outer) < 1.0:
        raise InvalidImageError(f"{name}: degenerate boundary (encloses no area)")
    xy = np.column_stack([outer[:, 1], -outer[:, 0]])
    xy = orient_ccw(xy)
    P = resample_contour(xy, n_points)
    start = int(np.argmax(P[:, 1] - 1e-9 * P[:, 0]))
    return np.ascontiguousarray(np.roll(P, -start, axis=0))


def contour_from_image(path: str | os.PathLike, n_points: int = 100) -> np.ndarray:
    """``extract_contour(load_silhouette(path), n_points)`` with errors naming the file."""
    from geoshape.io.silhouette import load_silhouette

    return extract_contour(load_silhouette(path), n_points, name=str(path))
