"""Per-vertex colours from scalar fields and positions (for filters, renders and exports).

Colours are ``(n, 4)`` float64 RGBA in ``[0, 1]`` — the convention of PyMeshLab's
``v_color_matrix``; :func:`geoshape.io.mesh_io.save_mesh` converts them to bytes.
"""

from __future__ import annotations

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError

__all__ = ["COLORMAPS", "scalar_colors", "position_colors"]

#: Matplotlib colour maps offered by the filters; diverging ones first.
COLORMAPS = ("coolwarm", "RdBu_r", "viridis", "turbo", "plasma", "gray")


def scalar_colors(values, cmap: str = "coolwarm", *, symmetric: bool | None = None) -> np.ndarray:
    """Map a per-vertex scalar to RGBA colours.

    Parameters
    ----------
    values : (n,) array_like of float
        Finite values (an eigenvector, a distance…).
    cmap : str
        One of :data:`COLORMAPS`.
    symmetric : bool, optional
        Centre the colour range on 0 (``[-a, a]`` with ``a = max |values|``), right for
        signed fields such as eigenvectors. Default: True when the values change sign.

    Returns
    -------
    colors : (n, 4) float64 in [0, 1]

    Examples
    --------
    >>> scalar_colors([0.0, 1.0], "gray")[:, 0].tolist()
    [0.0, 1.0]
    """
    check_choice("colour map", cmap, COLORMAPS)
    x = np.asarray(values, dtype=np.float64).ravel()
    if not np.isfinite(x).all():
        raise InvalidOptionError(f"values to colour must be finite; got {int((~np.isfinite(x)).sum())} "
                                 "NaN or infinite values")
    if symmetric is None:
        symmetric = bool(len(x) and x.min() < 0 < x.max())
    if len(x) == 0:
        return np.zeros((0, 4))
    if symmetric:
        a = float(np.abs(x).max())
        lo, hi = -a, a
    else:
        lo, hi = float(x.min()), float(x.max())
    t = (x - lo) / (hi - lo) if hi > lo else np.full_like(x, 0.5)
    from matplotlib import colormaps

    return np.asarray(colormaps[cmap](np.clip(t, 0.0, 1.0)), dtype=np.float64)


def position_colors(V) -> np.ndarray:
    """RGB from the position of each vertex in the bounding box (x → red, y → green, z → blue).

    Parameters
    ----------
    V : (n, 3) array_like of float

    Returns
    -------
    colors : (n, 4) float64 in [0, 1], opaque

    Examples
    --------
    >>> position_colors([[0, 0, 0], [1, 2, 0]])[1].tolist()
    [1.0, 1.0, 0.5, 1.0]
    """
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    lo, hi = V.min(axis=0), V.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    rgb = np.where(hi > lo, (V - lo) / span, 0.5)
    return np.column_stack([rgb, np.ones(len(V))])
