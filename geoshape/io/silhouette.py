"""Silhouette images → binary masks (tracing the contour is
:func:`geoshape.geometry.contour.extract_contour`).

Polarity is detected, not assumed: the object is the class (after thresholding) that does
*not* dominate the image border, so white-on-black and black-on-white images both work.
Grey-level images are thresholded at mid-level, halfway between the darkest and the
brightest value (robust for silhouettes, where the two levels are far apart; Otsu's threshold
can land at the edge of a flat plateau and cut one class). An image with a single grey level
has no object and is rejected.

``MIN_PIXELS`` is the fewest foreground pixels a shape may have.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from geoshape.errors import InvalidImageError

__all__ = ["load_silhouette", "MIN_PIXELS", "MAX_IMAGE_PIXELS"]

#: Fewest foreground pixels accepted for a shape.
MIN_PIXELS = 4
#: Most pixels an image may have: its grey levels are held in float64 (8 bytes a pixel), so
#: 50 million pixels (about 7000 x 7000) need 400 MB; larger headers are refused unread.
MAX_IMAGE_PIXELS = 50_000_000


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
            if im.width * im.height > MAX_IMAGE_PIXELS:
                raise InvalidImageError(f"{path}: image too large ({im.width} x {im.height} pixels; "
                                        f"at most {MAX_IMAGE_PIXELS:,} are read)")
            im.load()
            if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
                rgba = np.asarray(im.convert("RGBA"), dtype=np.float64)
                grey = rgba[..., :3].mean(axis=2)
                grey = rgba[..., 3] if np.ptp(grey) == 0 else grey
            else:
                grey = np.asarray(im.convert("F"), dtype=np.float64)
    except InvalidImageError:
        raise
    except FileNotFoundError:
        raise InvalidImageError(f"{path}: no such image file") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise InvalidImageError(f"{path}: cannot read image ({exc})") from None
    except Image.DecompressionBombError as exc:  # a header announcing > 2 x MAX_IMAGE_PIXELS pixels
        raise InvalidImageError(f"{path}: image too large ({exc})") from None
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
