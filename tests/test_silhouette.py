"""Silhouette images → masks → contours: polarity, grey levels, closure, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from geoshape.errors import GeoshapeError, InvalidImageError
from geoshape.geometry.contour import contour_from_image, extract_contour, signed_area
from geoshape.io.silhouette import load_silhouette


def _disk_mask(size=64, r=20, center=(32, 32)):
    yy, xx = np.mgrid[:size, :size]
    return (yy - center[0]) ** 2 + (xx - center[1]) ** 2 <= r**2


def _save(path, array, mode="L"):
    Image.fromarray(array.astype(np.uint8), mode=mode).save(path)
    return path


def test_polarity_white_on_black_and_black_on_white(tmp_path):
    mask = _disk_mask()
    a = load_silhouette(_save(tmp_path / "a.png", mask * 255))
    b = load_silhouette(_save(tmp_path / "b.png", (~mask) * 255))
    assert np.array_equal(a, mask) and np.array_equal(b, mask)


def test_grey_image_thresholded_at_mid_level(tmp_path):
    mask = _disk_mask()
    rng = np.random.default_rng(0)
    grey = np.where(mask, 180, 60) + rng.integers(-20, 20, mask.shape)
    got = load_silhouette(_save(tmp_path / "g.png", grey))
    assert np.array_equal(got, mask)


def test_unreadable_and_missing_files_are_named(tmp_path):
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"not an image")
    with pytest.raises(InvalidImageError, match="broken.png"):
        load_silhouette(bad)
    with pytest.raises(InvalidImageError, match="nothere.png"):
        load_silhouette(tmp_path / "nothere.png")


def test_single_grey_level_rejected(tmp_path):
    with pytest.raises(InvalidImageError, match="single grey level"):
        load_silhouette(_save(tmp_path / "flat.png", np.full((32, 32), 128)))


def test_contour_ccw_uniform_and_on_the_boundary():
    mask = _disk_mask(r=20)
    P = extract_contour(mask, n_points=80)
    assert P.shape == (80, 2)
    assert signed_area(P) > 0
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    assert seg.std() / seg.mean() < 0.15
    # x = column, y = -row; radius of the traced boundary ~ 20 px
    r = np.linalg.norm(P - [32, -32], axis=1)
    assert abs(r.mean() - 20) < 1.0


def test_largest_component_outer_boundary_only():
    mask = _disk_mask(r=20)
    mask[30:34, 30:34] = False  # a hole
    mask[2:4, 2:4] = True  # a speck
    P = extract_contour(mask, n_points=60)
    assert np.linalg.norm(P - [32, -32], axis=1).min() > 15


def test_border_touching_shape_closes():
    mask = np.zeros((40, 40), dtype=bool)
    mask[:, 10:30] = True  # touches top and bottom
    P = extract_contour(mask, n_points=50)
    assert P.shape == (50, 2) and signed_area(P) > 0
    assert P[:, 1].max() > 0 and P[:, 1].min() < -39


@pytest.mark.parametrize(
    "mask, message",
    [
        (np.zeros((10, 10), bool), "no object"),
        (np.ones((10, 10), bool), "every pixel"),
        (np.pad(np.ones((1, 1), bool), 4), "pixels"),
        (np.zeros((0, 0), bool), "non-empty"),
    ],
)
def test_bad_masks(mask, message):
    with pytest.raises(InvalidImageError, match=message):
        extract_contour(mask, name="m")


def test_contour_from_image_names_file(tmp_path):
    path = _save(tmp_path / "empty.png", np.zeros((16, 16)))
    with pytest.raises(GeoshapeError, match="empty.png"):
        contour_from_image(path)
