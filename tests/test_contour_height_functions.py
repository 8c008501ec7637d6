"""Height functions (Wang et al. 2012): invariances, start point, mirror images, and the
methods that use them."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.contour.descriptors import height_functions
from geoshape.errors import InvalidOptionError
from geoshape.geometry.contour import mirror_contour


@pytest.fixture(scope="module")
def shape():
    t = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    r = 1 + 0.3 * np.cos(3 * t) + 0.15 * np.sin(2 * t)
    return np.c_[r * np.cos(t), r * np.sin(t)]


def _similar(P, theta=0.9, scale=2.5, shift=(4.0, -7.0)):
    R = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    return scale * P @ R.T + np.asarray(shift)


@pytest.mark.parametrize("scale", ["centroid", "perimeter"])
def test_invariant_to_rotation_translation_scale(shape, scale):
    H = height_functions(shape, scale=scale)
    assert H.shape == (80, 25)
    assert np.allclose(height_functions(_similar(shape), scale=scale), H, atol=1e-12)


@pytest.mark.parametrize("k", [1, 13, 79])
def test_start_point_is_a_cyclic_shift(shape, k):
    # Point i of the rolled contour is point i - k of the original.
    H = height_functions(shape, n_groups=10, decay=0.2)
    assert np.allclose(height_functions(np.roll(shape, k, axis=0), n_groups=10, decay=0.2),
                       np.roll(H, k, axis=0), atol=1e-12)


@pytest.mark.parametrize("options", [dict(), dict(n_groups=79, decay=None), dict(n_groups=7)])
def test_mirror_image_reverses_the_runs(shape, options):
    # Mirror point i is the reflection of point -i: its heights are the original's in
    # reverse contour order; the sign (positive inside) is kept.
    H = height_functions(shape, **options)
    Hm = height_functions(mirror_contour(shape), **options)
    assert np.allclose(Hm, H[(-np.arange(80)) % 80, ::-1], atol=1e-12)


def test_raw_heights_are_signed_distances_to_the_tangent(shape):
    H = height_functions(shape, n_groups=79, decay=None, scale="centroid") * np.sqrt(79)
    s = np.linalg.norm(shape - shape.mean(axis=0), axis=1).mean()
    t = shape[1] - shape[-1]
    n = np.array([-t[1], t[0]]) / np.linalg.norm(t)
    assert np.allclose(H[0], (shape[1:] - shape[0]) @ n / s, atol=1e-12)


def test_circle_is_the_same_everywhere_and_convex_heights_are_inside():
    t = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    H = height_functions(np.c_[np.cos(t), np.sin(t)], n_groups=5)
    assert np.allclose(H, H[0]) and (H > 0).all()


def test_bad_options(shape):
    with pytest.raises(InvalidOptionError, match="n_groups"):
        height_functions(shape, n_groups=0)
    with pytest.raises(InvalidOptionError, match="decay"):
        height_functions(shape, decay=0.0)
    with pytest.raises(InvalidOptionError):
        height_functions(shape, scale="area")


def test_methods_with_height_functions_match_a_mirrored_copy(shape):
    from geoshape.contour.methods import CONTOUR_METHODS, match_contours

    P = shape
    bumpy = P * (1 + 0.2 * np.sin(5 * np.arctan2(P[:, 1], P[:, 0])))[:, None]
    Q = np.roll(1.7 * mirror_contour(P), 9, axis=0)
    for method in ("height_functions", "default_hf"):
        assert CONTOUR_METHODS[method]["mirror"] is True
        _, same = match_contours(P, Q, method=method)
        _, other = match_contours(P, bumpy, method=method)
        assert same < 1e-9 < other


def test_previous_default_is_kept():
    from geoshape.contour.methods import CONTOUR_METHODS

    old = CONTOUR_METHODS["default_2026_11"]
    assert [p[:2] for p in old["parts"]] == [("idsc", 1.0), ("shape_context", 0.5), ("gsc", 0.005)]
    assert all("normalize_by" not in p[3] for p in old["parts"])  # mean units, as then
    assert old["matcher_options"] == dict(skip_cost=0.3, n_starts=4) and old["mirror"] is True
