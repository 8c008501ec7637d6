"""Silhouette images → binary masks → closed contours ``(N, 2)``.

Polarity is detected, not assumed: the object is the class (after thresholding) that does
*not* dominate the image border, so white-on-black and black-on-white images both work.
Grey-level images are thresholded at mid-level, halfway between the darkest and the
brightest value (robust for silhouettes, where the two levels are far apart; Otsu's threshold
can land at the edge of a flat plateau and cut one class). An image with a single grey level
has no object and is rejected.

Contours are the outer boundary of the largest 8-connected foreground component (specks
and holes are ignored), traced with sub-pixel accuracy by ``skimage.measure.find_contours``
on a zero-padded mask (so shapes touching the border still close), resampled uniformly by
arc length and oriented counter-clockwise in ``(x, y)`` coordinates with ``y`` pointing up
(image row ``r`` becomes ``y = -r``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from geoshape.errors import InvalidImageError

__all__ = ["load_silhouette", "extract_contour", "contour_from_image"]

#: Fewest foreground pixels accepted for a shape.
MIN_PIXELS = 4


def load_silhouette(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as a boolean object mask.

    Parameters
    ----------
    path : path-like
        Any format Pillow reads (PNG, PGM, BMP, GIF, JPEG, TIFF, …). Colour images are
        converted to grey; an alpha channel, when the colour channels are constant, is used
        as the grey level.

    Returns
    -------
    mask : (h, w) bool
        ``True`` on the object. Polarity: after thresholding, the class occupying more
        than half of the image border is background.

    Raises
    ------
    InvalidImageError
        Unreadable or missing file, empty image, or an image with a single grey level
        (no object can be separated), naming the file.
    """
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
                rgba = np.asarray(im.convert("RGBA"), dtype=np.float64)
                grey = rgba[..., :3].mean(axis=2)
                grey = rgba[..., 3] if np.ptp(grey) == 0 else grey
            else:
                grey = np.asarray(im.convert("F"), dtype=np.float64)
    except FileNotFoundError:
        raise InvalidImageError(f"{path}: no such image file") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise InvalidImageError(f"{path}: cannot read image ({exc})") from None
    return _binarize(grey, name=str(path))


def _binarize(grey: np.ndarray, name: str) -> np.ndarray:
    if grey.ndim != 2 or grey.size == 0:
        raise InvalidImageError(f"{name}: empty image (shape {grey.shape})")
    if not np.isfinite(grey).all():
        raise InvalidImageError(f"{name}: image has NaN or infinite values")
    lo, hi = float(grey.min()), float(grey.max())
    if hi <= lo:
        raise InvalidImageError(f"{name}: image has a single grey level ({lo:g}): no object")
    mask = grey > 0.5 * (lo + hi)
    border = np.concatenate([mask[0], mask[-1], mask[1:-1, 0], mask[1:-1, -1]])
    if border.mean() > 0.5:
        mask = ~mask
    return mask


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
    from skimage import measure

    from geoshape.geometry.contour import orient_ccw, resample_contour

    if n_points < 8:
        from geoshape.errors import InvalidOptionError

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
    from scipy import ndimage

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
    return extract_contour(load_silhouette(path), n_points, name=str(path))
