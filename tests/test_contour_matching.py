"""Matching contours: invariance, anchors of the proximity heuristic, DP/Hungarian, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.contour.matching import (
    batch_match_costs,
    best_match,
    cyclic_dp_match,
    hungarian_match,
    proximity_anchors,
    proximity_match,
)
from geoshape.contour.methods import CONTOUR_METHODS, match_contours, method_spec
from geoshape.contour.retrieval import shape_distance_matrix
from geoshape.errors import GeoshapeError, InvalidContourError, InvalidOptionError


@pytest.fixture(scope="module")
def silhouette_contour():
    from geoshape_datasets_gen.silhouettes2d import articulated_silhouette

    from geoshape.geometry.contour import extract_contour

    return extract_contour(articulated_silhouette("quadruped", seed=3), n_points=80)


def similar_copy(P, shift):
    th = 1.1
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    return np.roll(2.7 * P @ R.T + [40.0, -11.0], -shift, axis=0)


@pytest.mark.parametrize("method", sorted(CONTOUR_METHODS))
def test_similarity_transformed_copy_matches_point_for_point(method, silhouette_contour):
    P = silhouette_contour
    # a multiple of the height term's step (2): a term on one sampling phase (default_heights)
    # then reads the same points; an odd shift would leave it a small residue (docs/2d.md)
    shift = 8
    Q = similar_copy(P, shift)  # Q[j] = T(P[j + shift])
    p2p, cost = match_contours(P, Q, method=method)
    expected = (np.arange(len(P)) - shift) % len(P)
    assert np.mean(p2p == expected) >= 0.95
    assert cost == pytest.approx(0.0, abs=1e-2)


def test_proximity_anchors_hand_made():
    N = 10
    s = np.arange(N) / N
    C = np.ones((N, N))
    C[2, 5] = 0.0  # first anchor
    C[3, 6] = 0.2  # good, but next to the first anchor
    C[7, 0] = 0.2  # as good, and half a contour away
    anchors, d1, d2 = proximity_anchors(C, s, s)
    assert anchors[0].tolist() == [2, 5]
    assert anchors[1].tolist() == [7, 0]
    assert d1[0, 7] == pytest.approx(0.5) and d2[0, 0] == pytest.approx(0.5)


def test_proximity_anchors_on_a_known_pair(silhouette_contour):
    from geoshape.contour.descriptors import geodesic_shape_context
    from geoshape.geometry.contour import arc_length, perimeter

    P = silhouette_contour
    shift = 11
    Q = similar_copy(P, shift)
    HP, HQ = geodesic_shape_context(P), geodesic_shape_context(Q)
    C = ((HP[:, None, :] - HQ[None, :, :]) ** 2).sum(axis=2)
    anchors, _, _ = proximity_anchors(C, arc_length(P) / perimeter(P), arc_length(Q) / perimeter(Q))
    N = len(P)
    for i, j in anchors:
        assert j == (i - shift) % N  # both anchors are true correspondences
    gap = abs(int(anchors[0, 0]) - int(anchors[1, 0]))
    assert min(gap, N - gap) >= N // 8  # the penalty kept the second anchor away from the first
    p2p, cost = proximity_match(C, arc_length(P) / perimeter(P), arc_length(Q) / perimeter(Q))
    assert np.mean(p2p == (np.arange(N) - shift) % N) >= 0.95


def test_cyclic_dp_finds_shifted_diagonal_and_skips():
    N = 6
    C = np.ones((N, N))
    C[np.arange(N), (np.arange(N) + 2) % N] = 0.0
    p2p, cost = cyclic_dp_match(C, n_starts=1)
    assert p2p.tolist() == [2, 3, 4, 5, 0, 1] and cost == 0.0
    # Point 3 of contour 1 has no good partner: skipping it and point 5 of 2 is cheaper.
    C2 = np.ones((N, N))
    for i, j in [(0, 2), (1, 3), (2, 4), (4, 0), (5, 1)]:
        C2[i, j] = 0.0
    _, cost2 = cyclic_dp_match(C2, skip_cost=0.3, n_starts=N)
    assert cost2 == pytest.approx(2 * 0.3 / N)


def test_more_dp_starts_never_cost_more(silhouette_contour):
    """The starts are the best-ranked cyclic offsets, so a larger ``n_starts`` tries a superset
    of them and its cost is never higher; 8 finds cheaper matchings than 4 on some pairs, and
    every start (``n_starts = N``) on some more."""
    from geoshape_datasets_gen.silhouettes2d import articulated_silhouette

    from geoshape.contour.methods import contour_signature, signature_cost_matrices
    from geoshape.geometry.contour import extract_contour

    spec = method_spec("default", mirror=False)
    X1 = contour_signature(silhouette_contour, spec=spec).X
    N = len(silhouette_contour)
    costs = []
    for cls in ("quadruped", "person", "crab", "hand"):
        for seed in (10, 11, 12):
            Q = extract_contour(articulated_silhouette(cls, seed=seed), n_points=N)
            C = signature_cost_matrices(X1, contour_signature(Q, spec=spec).X[None], "sqeuclidean")[0]
            costs.append([cyclic_dp_match(C, n_starts=k)[1] for k in (1, 4, 8, N)])
    costs = np.array(costs)
    assert (np.diff(costs, axis=1) <= 0).all()
    assert (costs[:, 2] < costs[:, 1]).any() and (costs[:, 3] < costs[:, 2]).any()


def test_batched_dp_equals_single():
    rng = np.random.default_rng(1)
    C = rng.random((5, 12, 12))
    batch = batch_match_costs(C, "dp", n_starts=12)
    single = [cyclic_dp_match(c, n_starts=12)[1] for c in C]
    assert np.allclose(batch, single)


def test_hungarian_and_best():
    C = np.array([[1.0, 0.0, 2.0], [0.0, 0.5, 2.0], [0.2, 0.1, 3.0]])
    p2p, cost = hungarian_match(C)
    assert p2p.tolist() == [2, 0, 1] and cost == pytest.approx((2.0 + 0.0 + 0.1) / 3)
    p2p_b, cost_b = best_match(C)
    assert p2p_b.tolist() == [1, 0, 1] and cost_b == pytest.approx(0.1 / 3)


def test_distance_matrix_symmetric_zero_diagonal(silhouette_contour):
    P = silhouette_contour
    contours = [P, similar_copy(P, 3), np.roll(P * [1.0, 1.3], 5, axis=0)]
    for method in ("gsc", "idsc"):
        D = shape_distance_matrix(contours, method, backend="serial")
        assert np.allclose(D, D.T) and np.all(np.diag(D) == 0)
        assert D[0, 1] < D[0, 2]


def test_bad_options_and_inputs(silhouette_contour):
    P = silhouette_contour
    with pytest.raises(InvalidOptionError, match="'default'"):
        match_contours(P, P, method="nope")
    with pytest.raises(InvalidOptionError, match="matcher"):
        method_spec("gsc", matcher="greedy")
    with pytest.raises(InvalidOptionError, match="unknown option"):
        method_spec("gsc", colour="red")
    bad = P.copy()
    bad[4] = np.nan
    with pytest.raises(InvalidContourError, match="NaN"):
        match_contours(bad, P)
    with pytest.raises(InvalidContourError, match="at least"):
        match_contours(P[:3], P)
    with pytest.raises(GeoshapeError, match="no area"):
        match_contours(np.c_[np.arange(30.0), np.zeros(30)], P, method="gsc")
    with pytest.raises(InvalidContourError, match="same number"):
        shape_distance_matrix([P, P[:50]], "gsc", backend="serial")
