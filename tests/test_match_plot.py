"""The 2D match picture (``match2d --plot``): written, matched points coloured alike on both
contours, shapes upright as in their images, ``--lines`` range-checked."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from geoshape.__main__ import main
from geoshape.geometry.contour import extract_contour
from geoshape.plot.contours import (
    DEFAULT_MATCH_LINES,
    UNMATCHED_COLOUR,
    match_colours,
    match_plot_layout,
    plot_contour_matching,
)


def _top_heavy_mask(h: int = 60, w: int = 60) -> np.ndarray:
    """A 'T': a wide bar in the top rows of the image on a thin stem, so its mass is at the top."""
    mask = np.zeros((h, w), bool)
    mask[5:20, 5:55] = True
    mask[20:55, 26:34] = True
    return mask


@pytest.fixture()
def images(tmp_path):
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    Image.fromarray(_top_heavy_mask().astype(np.uint8) * 255).save(a)
    Image.fromarray(np.roll(_top_heavy_mask(), 3, axis=1).astype(np.uint8) * 255).save(b)
    return a, b


def test_the_picture_is_written(tmp_path):
    P = extract_contour(_top_heavy_mask(), 40)
    for lines in (0, DEFAULT_MATCH_LINES, 1000):
        path = tmp_path / f"m{lines}.png"
        plot_contour_matching(P, P[::-1], np.arange(40)[::-1], path, title="t", lines=lines)
        assert path.stat().st_size > 1000
        with Image.open(path) as im:
            assert im.size[0] > im.size[1] > 100


def test_matched_points_take_the_same_colour_on_both_contours():
    rng = np.random.default_rng(0)
    n_a, n_b = 50, 70
    perm = rng.permutation(n_b)[:n_a]  # one-to-one: every pair exactly alike
    ca, cb = match_colours(n_a, n_b, perm)
    assert np.array_equal(ca, cb[perm])
    unmatched_b = np.setdiff1d(np.arange(n_b), perm)
    assert np.array_equal(cb[unmatched_b], np.tile(UNMATCHED_COLOUR, (len(unmatched_b), 1)))
    # cyclic map along the first contour: all distinct, the last close to the first
    assert len(np.unique(ca, axis=0)) == n_a
    assert np.abs(ca[-1] - ca[0]).max() < 0.2 < np.abs(ca[n_a // 2] - ca[0]).max()

    # many-to-one and unmatched (-1): a point of B takes the colour of one of its partners (the first)
    p2p = rng.integers(-1, n_b, size=n_a)
    ca, cb = match_colours(n_a, n_b, p2p)
    assert np.array_equal(ca[p2p < 0], np.tile(UNMATCHED_COLOUR, ((p2p < 0).sum(), 1)))
    for j in range(n_b):
        partners = np.flatnonzero(p2p == j)
        expected = ca[partners[0]] if len(partners) else np.asarray(UNMATCHED_COLOUR)
        assert np.array_equal(cb[j], expected)
    with pytest.raises(ValueError):
        match_colours(3, 2, [0, 1, 2])


def test_a_shape_with_its_mass_at_the_top_of_the_image_is_drawn_with_it_at_the_top(tmp_path):
    P = extract_contour(_top_heavy_mask(), 80)
    A, B = match_plot_layout(P, P)
    for X in (A, B):  # the bar (wide rows) is in the upper half of the drawing
        top, bottom = X[X[:, 1] > X[:, 1].max() - 0.1], X[X[:, 1] < X[:, 1].min() + 0.1]
        assert np.ptp(top[:, 0]) > 3 * np.ptp(bottom[:, 0])
        assert np.isclose(np.ptp(X[:, 1]), 1.0)  # equal aspect: unit height, width kept in ratio
    assert A[:, 0].max() < B[:, 0].min()  # side by side, first on the left

    # and in the rendered pixels: the widest row of drawn ink is in the top half
    path = tmp_path / "m.png"
    plot_contour_matching(P, P, np.arange(80), path, lines=0)
    with Image.open(path) as im:
        rgb = np.asarray(im.convert("RGB"), dtype=np.int64)
    ink = (np.abs(rgb - rgb[:, :, :1]).max(axis=2) > 60)  # coloured (not grey/white/black) pixels
    rows = np.flatnonzero(ink.any(axis=1))
    widths = [np.ptp(np.flatnonzero(ink[r])) if ink[r].any() else 0 for r in range(len(ink))]
    widest = int(np.argmax(widths))
    assert widest < (rows.min() + rows.max()) / 2


def test_cli_lines_option(images, tmp_path, capsys):
    a, b = images
    fig = tmp_path / "fig.png"
    assert main(["match2d", str(a), str(b), "--n-points", "40", "--plot", str(fig), "--lines", "5"]) == 0
    assert fig.stat().st_size > 1000
    capsys.readouterr()
    for bad in ("-1", "4001", "x"):
        code = main(["match2d", str(a), str(b), "--plot", str(tmp_path / "g.png"), "--lines", bad])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and "--lines" in err[0]
    assert not (tmp_path / "g.png").exists()
    assert main(["match2d", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert f"default {DEFAULT_MATCH_LINES};" in help_text and "[0–4000]" in help_text
