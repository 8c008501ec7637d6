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


def test_a_cut_off_part_stays_in_the_outline():
    # A bar cut in two by a bite: both halves are the shape, joined by a thin corridor.
    mask = np.zeros((64, 96), dtype=bool)
    mask[24:40, 8:88] = True
    mask[20:44, 46:52] = False  # the cut: halves of 608 and 576 pixels
    P = extract_contour(mask, n_points=120)
    assert P[:, 0].min() < 10 and P[:, 0].max() > 85
    assert abs(signed_area(P) - mask.sum()) < 0.1 * mask.sum()  # two halves + a 3-px corridor
    alone = extract_contour(mask, n_points=120, part_fraction=2.0)  # > 1: the largest part only
    assert alone[:, 0].min() > 45 or alone[:, 0].max() < 52


def test_join_parts_connects_every_part_and_drops_specks():
    from skimage import measure

    from geoshape.geometry.contour import join_parts

    mask = _disk_mask(size=96, r=20, center=(48, 30))
    mask |= _disk_mask(size=96, r=8, center=(48, 80))  # a part: 201 / 1257 of the largest
    mask |= _disk_mask(size=96, r=6, center=(85, 30))  # another, nearest to the big disc
    mask[2:4, 90:92] = True  # a speck: 4 pixels
    labels = measure.label(mask, connectivity=2)
    joined = join_parts(labels, min_fraction=0.02)
    assert measure.label(joined, connectivity=2).max() == 1
    assert joined[48, 80] and joined[85, 30] and not joined[2:4, 90:92].any()
    assert (joined & ~mask).sum() < 3 * (50 + 40)  # only two corridors of width 3 were added
    largest = np.bincount(labels.ravel())[1:].argmax() + 1
    assert np.array_equal(join_parts(labels, min_fraction=2.0), labels == largest)


def test_smoothing_removes_boundary_noise_at_any_scale():
    from geoshape.geometry.contour import perimeter, smooth_contour

    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    bumpy = 1 + 0.03 * np.sign(np.sin(60 * t))  # 60 square bumps of 3 % of the radius
    P = 50 * np.column_stack([bumpy * np.cos(t), bumpy * np.sin(t)])
    S = smooth_contour(P, 0.005)
    r = np.linalg.norm(S, axis=1)
    assert r.std() < 0.2 * np.linalg.norm(P, axis=1).std() and abs(r.mean() - 50) < 1.0
    big = smooth_contour(4 * P, 0.005)  # sigma is a share of the perimeter: no unit
    assert np.allclose(np.linalg.norm(big, axis=1).std() / 4, r.std(), rtol=0.05)
    assert np.array_equal(smooth_contour(P, 0.0), P)
    circle = 2 * np.pi * 50
    assert perimeter(P) > 1.5 * circle and perimeter(S) < 1.05 * circle  # the bumps' length is gone


def test_bad_tracing_settings_are_named():
    from geoshape.errors import InvalidOptionError
    from geoshape.geometry.contour import join_parts

    mask = _disk_mask()
    for bad in (-0.01, 0.5, float("nan"), float("inf")):
        with pytest.raises(InvalidOptionError, match="smoothing must be in"):
            extract_contour(mask, smoothing=bad)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(InvalidOptionError, match="part_fraction must be"):
            extract_contour(mask, part_fraction=bad)
    with pytest.raises(InvalidImageError, match="no object pixels"):
        join_parts(np.zeros((5, 5), int))


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
