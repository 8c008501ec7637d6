"""Pictures of a 3-D correspondence (thesis Fig. 4.7 style) and cumulative geodesic-error
curves, headless.

The target is coloured smoothly by position (bounding-box RGB); each source vertex takes
the colour of its image under ``p2p_12``. A good map paints matching parts alike.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


def transferred_colors(V2, p2p_12) -> tuple[np.ndarray, np.ndarray]:
    """(source colours (n1, 4), target colours (n2, 4)) in [0, 1] for a map 1 → 2."""
    from geoshape.plot.colormap import position_colors

    target = position_colors(V2)
    return target[np.asarray(p2p_12)], target


def plot_correspondence(path: str | os.PathLike, V1, F1, V2, F2, p2p_12, *, title: str | None = None,
                        elev: float = 15.0, azim: float = -70.0, size: int = 500) -> Path:
    """Write a PNG with the source (left, coloured through the map) and the target (right)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from geoshape.io.atomic import save_figure_atomic
    from geoshape.plot.meshes import draw_mesh

    src_rgba, tgt_rgba = transferred_colors(V2, p2p_12)
    fig = plt.figure(figsize=(2 * size / 100, size / 100), dpi=100)
    try:
        for col, (V, F, rgba, label) in enumerate(
            ((V1, F1, src_rgba, "source (through the map)"), (V2, F2, tgt_rgba, "target"))
        ):
            ax = fig.add_subplot(1, 2, col + 1, projection="3d")
            draw_mesh(ax, np.asarray(V, float), np.asarray(F), rgba[np.asarray(F)].mean(axis=1),
                      elev=elev, azim=azim)
            ax.set_title(label, fontsize=9)
        if title:
            fig.suptitle(title, fontsize=10)
        fig.subplots_adjust(left=0, right=1, bottom=0, top=0.9, wspace=0)
        return save_figure_atomic(fig, path)
    finally:
        plt.close(fig)


def plot_error_curves(curves: dict, path: str | os.PathLike, *, title: str | None = None,
                      thresholds=None, sym_aware: bool = False):
    """Draw the cumulative geodesic-error curves of several methods on one plot.

    Parameters
    ----------
    curves : dict
        ``{method name: errors}`` with ``errors`` a (k,) array (several pairs may be
        concatenated), or ``{name: geodesic_errors(...) result}``.
    path : str or PathLike
        Output image, written atomically; format from the extension.
    title : str or None
    thresholds : (T,) array_like or None
        Default 0 … 0.25.
    sym_aware : bool
        Plot the symmetry-aware errors of result dicts instead of the direct ones.

    Returns
    -------
    pathlib.Path
    """

    from geoshape.metrics.correspondence import cumulative_error_curve
    from geoshape.plot.figures import save_curves

    lines = []
    for name, value in curves.items():
        if isinstance(value, dict):
            value = value["errors_sym_aware" if sym_aware else "errors"]
        th, frac = cumulative_error_curve(value, thresholds)
        mean = float(np.mean(value)) if np.size(value) else float("nan")
        lines.append((f"{name} (mean {mean:.3f})", th, 100 * frac))
    return save_curves(lines, path, xlabel="geodesic error / sqrt(area)", ylabel="% correspondences",
                       ylim=(0, 101), title=title, legend_loc="lower right")
