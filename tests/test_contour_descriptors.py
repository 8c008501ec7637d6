"""Curvature, thresholding and geodesic shape context on hand-made inputs with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.contour.descriptors import (
    curvature_map,
    geodesic_bin_edges,
    geodesic_shape_context,
    threshold_curvature,
)
from geoshape.errors import GeoshapeError, InvalidContourError, InvalidOptionError
from geoshape.geometry.contour import (
    contour_curvature,
    contour_geodesic_distance,
    mirror_contour,
    resample_contour,
    signed_area,
)


def circle(r=2.5, n=120, c=(1.0, -3.0)):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.c_[c[0] + r * np.cos(t), c[1] + r * np.sin(t)]


def test_circle_curvature_is_one_over_r_then_one():
    P = circle(r=2.5)
    k = contour_curvature(P, window=4, normalize=False)
    assert np.allclose(k, 1 / 2.5, rtol=5e-3)
    assert np.allclose(contour_curvature(P, normalize=True), 1.0, rtol=5e-3)
    # clockwise traversal flips the sign
    assert np.allclose(contour_curvature(P[::-1], normalize=False), -1 / 2.5, rtol=5e-3)


def test_curvature_sign_convex_positive_concave_negative():
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    r = 1 + 0.4 * np.cos(3 * t)  # trefoil-like flower: concave between lobes
    P = np.c_[r * np.cos(t), r * np.sin(t)]
    k = contour_curvature(P)
    assert k[0] > 0  # lobe tip
    assert k[np.argmin(np.abs(t - np.pi / 3))] < 0  # between lobes


def test_curvature_scale_rotation_invariant_after_normalisation():
    P = circle(r=1.0, n=100) * [1.0, 0.5]  # an ellipse
    R = np.array([[0.6, -0.8], [0.8, 0.6]])
    Q = 7.0 * P @ R.T + [3.0, -2.0]
    assert np.allclose(contour_curvature(P), contour_curvature(Q), atol=1e-9)


def test_hysteresis_on_hand_made_sequence():
    C = np.array([2.0, 1.0, -0.05, -0.01, -0.02, 0.5, -3.0, -0.01, 0.3, -0.01])
    # C' = 2; tau = 1/4 * mean(negatives) = 1/4 * (-3.1 / 6)
    tau = 0.25 * np.mean(C[C < 0])
    out = threshold_curvature(C, "hysteresis")
    expected = C.copy()
    expected[C >= 0] = C[C >= 0] / 2.0
    assert tau == pytest.approx(-3.1 / 6 / 4)
    amplify = [6]  # -3.0 < tau
    amplify += [3]  # tau < -0.01 < 0 with both neighbours negative
    for i in amplify:
        expected[i] = -(2 - np.exp(C[i]))
    assert np.allclose(out, expected)
    # kept: above tau with a non-negative neighbour
    for i in (2, 4, 7, 9):
        assert out[i] == C[i]


def test_hard_thresholding():
    C = np.array([4.0, 2.0, -1.0, 0.0])
    out = threshold_curvature(C, "hard")
    assert np.allclose(out, [1.0, 0.5, -(1 - np.exp(-1.0)), 0.0])
    assert np.array_equal(threshold_curvature(C, "none"), C)


def test_threshold_bad_input():
    with pytest.raises(InvalidOptionError, match="hysteresis"):
        threshold_curvature([1.0, 2.0], "soft")
    with pytest.raises(InvalidOptionError, match="finite"):
        threshold_curvature([1.0, np.nan])


def test_gsc_of_circle_is_constant_and_layout_sized():
    P = circle(n=100)
    H = geodesic_shape_context(P, threshold="none")
    assert H.shape == (100, 2 * (len(geodesic_bin_edges("thesis")) - 1))
    assert np.allclose(H, 1.0, atol=1e-2)


def test_gsc_forward_backward_swap_under_mirror():
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    r = 1 + 0.3 * np.cos(2 * t) + 0.2 * np.sin(3 * t)
    P = np.c_[r * np.cos(t), r * np.sin(t)]
    H = geodesic_shape_context(P)
    Hm = geodesic_shape_context(mirror_contour(P))
    B = H.shape[1] // 2
    idx = (-np.arange(100)) % 100
    assert np.allclose(Hm[:, :B], H[idx, B:], atol=1e-9)


def test_bin_layout_validation():
    assert geodesic_bin_edges([0, 0.5, 1.0]).tolist() == [0, 0.5, 1.0]
    with pytest.raises(InvalidOptionError, match="non-decreasing"):
        geodesic_bin_edges([0, 0.6, 1.0])
    with pytest.raises(InvalidOptionError, match="thesis"):
        geodesic_bin_edges("nope")


def test_curvature_map_shape():
    assert curvature_map(circle(n=64), n_samples=6).shape == (64, 13)


def test_geodesic_distance_and_resampling():
    P = resample_contour(circle(r=1.0, n=1000), 50)
    d = contour_geodesic_distance(P, 0)
    assert d.max() == pytest.approx(0.5, abs=1e-9) and d[25] == pytest.approx(0.5)
    assert signed_area(P) > 0


@pytest.mark.parametrize(
    "P, message",
    [
        (np.zeros((0, 2)), "at least"),
        (np.array([[0.0, 0.0]]), "at least"),
        (np.c_[np.arange(20.0), np.arange(20.0)], "no area"),
        (np.where(np.arange(40)[:, None] == 3, np.nan, circle(n=40)), "NaN"),
        (np.ones((10, 3)), "shape"),
    ],
)
def test_bad_contours_raise(P, message):
    with pytest.raises(InvalidContourError, match=message):
        contour_curvature(P)
    with pytest.raises(GeoshapeError):
        geodesic_shape_context(P)


def test_histogram_units_median_is_invariant_and_robust_to_a_far_part():
    """Median units: scale-free like the mean; a far cluster of extra points (a part added)
    moves the median unit less than the mean one, so the other points' bins move less."""
    from geoshape.contour.shape_context import log_polar_histograms

    rng = np.random.default_rng(0)
    X = rng.normal(size=(60, 2))
    angle = np.zeros((60, 60))

    def dist(Y):
        return np.linalg.norm(Y[:, None] - Y[None], axis=2)

    for unit in ("mean", "median"):
        H = log_polar_histograms(dist(X), angle, normalize_by=unit)
        assert np.array_equal(H, log_polar_histograms(3.0 * dist(X), angle, normalize_by=unit))
    Y = np.vstack([X, rng.normal(size=(12, 2)) * 0.3 + [8.0, 0.0]])  # a far part of 12 points
    moved = {}
    for unit in ("mean", "median"):
        before = log_polar_histograms(dist(X), angle[:60, :60], normalize_by=unit)
        after = log_polar_histograms(dist(Y), np.zeros((72, 72)), normalize_by=unit)[:60]
        moved[unit] = np.abs(after - before).sum()
    assert moved["median"] < 0.5 * moved["mean"]
    with pytest.raises(InvalidOptionError, match="normalize_by"):
        log_polar_histograms(dist(X), angle, normalize_by="max")
