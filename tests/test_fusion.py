"""Late fusion of dissimilarity matrices (geoshape.retrieval.fusion) and the ``fused`` method."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.errors import InvalidOptionError
from geoshape.metrics.retrieval import retrieval_metrics
from geoshape.retrieval.fusion import FUSED_WEIGHTS, fuse_distances


def _dist(X):
    return np.linalg.norm(X[:, None, :] - X[None, :, :], axis=-1)


def _planted(seed=0, per=6):
    """Classes 0..3; component A separates 0 / 1 (2 and 3 share one cloud), B separates 2 / 3."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.arange(4), per)
    centres_a = {0: (0.0, 0.0), 1: (10.0, 0.0), 2: (0.0, 10.0), 3: (0.0, 10.0)}
    centres_b = {0: (0.0, 10.0), 1: (0.0, 10.0), 2: (0.0, 0.0), 3: (10.0, 0.0)}
    XA = np.array([centres_a[c] for c in labels]) + rng.normal(0, 1.0, (len(labels), 2))
    XB = np.array([centres_b[c] for c in labels]) + rng.normal(0, 1.0, (len(labels), 2))
    return _dist(XA), _dist(XB), labels


def _nn(D, labels):
    return retrieval_metrics(D, list(labels))["nearest_neighbor"]


def test_unit_free_under_component_scaling():
    A, B, _ = _planted()
    for adaptive in (True, False):
        ref = fuse_distances({"a": A, "b": B}, {"a": 0.3, "b": 0.7}, adaptive=adaptive)
        scaled = fuse_distances({"a": 7.5 * A, "b": 1e-3 * B}, {"a": 0.3, "b": 0.7}, adaptive=adaptive)
        np.testing.assert_allclose(scaled, ref, rtol=1e-12, atol=1e-14)
    # weights need not sum to 1: only their ratios matter
    ref = fuse_distances({"a": A, "b": B}, {"a": 0.3, "b": 0.7})
    np.testing.assert_allclose(fuse_distances({"a": A, "b": B}, {"a": 3, "b": 7}), ref, rtol=1e-12)


def test_planted_components_complement_each_other():
    A, B, labels = _planted()
    assert _nn(A, labels) < 1 and _nn(B, labels) < 1
    for adaptive in (True, False):
        D = fuse_distances({"a": A, "b": B}, {"a": 0.5, "b": 0.5}, adaptive=adaptive)
        assert _nn(D, labels) == 1.0
        m = retrieval_metrics(D, list(labels))["first_tier"]
        assert m > max(retrieval_metrics(X, list(labels))["first_tier"] for X in (A, B))


def test_symmetric_zero_diagonal_and_rectangular():
    A, B, _ = _planted()
    D = fuse_distances({"a": A, "b": B}, {"a": 1, "b": 2})
    assert np.allclose(D, D.T) and np.all(np.diag(D) == 0) and np.all(D >= 0)
    R = fuse_distances({"a": A[:5, 5:], "b": B[:5, 5:]}, {"a": 1, "b": 2})
    assert R.shape == (5, len(A) - 5)
    # single component, fixed weights: its row-normalised matrix (then symmetrised)
    S = fuse_distances({"a": A}, {"a": 1.0}, adaptive=False)
    off = ~np.eye(len(A), dtype=bool)
    med = np.array([np.median(r[o]) for r, o in zip(A, off, strict=True)])
    N = A / med[:, None]
    assert np.allclose(S, 0.5 * (N + N.T))


@pytest.mark.parametrize("weights, match", [
    ({"a": -0.5, "b": 1.0}, "'a' must be non-negative"),
    ({"a": 0.0, "b": 0.0}, "all zero"),
    ({"a": 1.0, "c": 1.0}, "unknown component 'c'"),
    ({"a": 1.0}, "no fusion weight for component.*'b'"),
    ({"a": float("nan"), "b": 1.0}, "'a' must be finite"),
])
def test_bad_weights_raise_naming_the_problem(weights, match):
    A, B, _ = _planted()
    with pytest.raises(InvalidOptionError, match=match):
        fuse_distances({"a": A, "b": B}, weights)


def test_bad_matrices_and_k():
    A, B, _ = _planted()
    with pytest.raises(InvalidOptionError, match="shape"):
        fuse_distances({"a": A, "b": B[:-1]}, {"a": 1, "b": 1})
    with pytest.raises(InvalidOptionError, match="finite and non-negative"):
        fuse_distances({"a": -A, "b": B}, {"a": 1, "b": 1})
    with pytest.raises(InvalidOptionError, match="k must be a positive integer"):
        fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1}, k=0)


def test_fused_method_registered():
    from geoshape.retrieval.descriptors import RETRIEVAL_METHODS, method_descriptors

    assert "fused" in RETRIEVAL_METHODS
    assert method_descriptors("fused") == tuple(n for n, w in FUSED_WEIGHTS.items() if w > 0)
    assert abs(sum(FUSED_WEIGHTS.values()) - 1) < 1e-12
    with pytest.raises(InvalidOptionError, match="descriptor must be one of"):
        method_descriptors("nope")


def test_fused_method_on_meshes_matches_fusing_its_components():
    from conftest import icosphere

    from geoshape.retrieval.descriptors import descriptor_distance_matrix
    from geoshape.retrieval.meshes import retrieval3d_matrix

    V, F = icosphere(2)
    meshes = [(V * np.array(s), F) for s in ([1, 1, 1], [1.1, 1, 1], [3, 1, 1], [3, 1.1, 1])]
    res = retrieval3d_matrix(meshes, "fused", backend="serial", progress=False)
    D = res["D"]
    assert D.shape == (4, 4) and np.allclose(D, D.T) and np.all(np.diag(D) == 0)
    assert set(res["seconds_per_mesh"]) == set(FUSED_WEIGHTS)
    mats = {n: descriptor_distance_matrix(n, res["descriptors"][n]) for n in FUSED_WEIGHTS}
    np.testing.assert_allclose(D, fuse_distances(mats, FUSED_WEIGHTS))
    assert D[0, 1] < D[0, 2] and D[2, 3] < D[2, 0]


def _two_regimes(seed=0, per=6):
    """Classes 0, 1 tight in B and overlapping in A ("rigid": extrinsic sees them); classes 2, 3
    tight in A and scattered in B ("articulated": extrinsic sees noise)."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.arange(4), per)
    ca = {0: (0.0, 0.0), 1: (1.0, 0.0), 2: (10.0, 0.0), 3: (0.0, 10.0)}
    sa = {0: 1.0, 1: 1.0, 2: 0.3, 3: 0.3}
    cb = {0: (0.0, 0.0), 1: (10.0, 0.0), 2: (5.0, 5.0), 3: (5.0, 5.0)}
    sb = {0: 0.3, 1: 0.3, 2: 6.0, 3: 6.0}
    noise = lambda s: rng.normal(0, 1, (len(labels), 2)) * np.array([s[c] for c in labels])[:, None]  # noqa: E731
    XA = np.array([ca[c] for c in labels]) + noise(sa)
    XB = np.array([cb[c] for c in labels]) + noise(sb)
    return _dist(XA), _dist(XB), labels


def test_sharper_per_query_weighting_picks_the_component_that_sees_the_query():
    for seed in range(3):
        A, B, labels = _two_regimes(seed)
        def ft(D, labels=labels):
            return retrieval_metrics(D, list(labels))["first_tier"]

        fixed = fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1}, adaptive=False)
        mild = fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1}, reference={}, power=1)
        sharp = fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1}, reference={"a": 0.5, "b": 0.5})
        assert _nn(sharp, labels) == 1.0
        assert ft(sharp) >= ft(mild) >= ft(fixed) > max(ft(A), ft(B))


def test_calibration_and_the_earlier_rule():
    from geoshape.retrieval.fusion import (
        FUSED_GAP_REFERENCE,
        FUSED_POWER,
        GAP_FLOOR,
        query_gaps,
        typical_gaps,
    )

    A, B, _ = _planted()
    # reference={} and power=1: the uncalibrated rule W_c ∝ w_c max(gap_c, floor)
    ga, gb = (np.maximum(query_gaps(X), GAP_FLOOR) for X in (A, B))
    off = ~np.eye(len(A), dtype=bool)
    na, nb = (X / np.array([np.median(r[o]) for r, o in zip(X, off, strict=True)])[:, None] for X in (A, B))
    wa, wb = 0.3 * ga, 0.7 * gb
    D = (wa[:, None] * na + wb[:, None] * nb) / (wa + wb)[:, None]
    D = 0.5 * (D + D.T)
    np.fill_diagonal(D, 0)
    np.testing.assert_allclose(fuse_distances({"a": A, "b": B}, {"a": 0.3, "b": 0.7}, reference={}, power=1),
                               D, rtol=1e-12, atol=1e-14)
    # only the ratios of the references matter (same factor on every component cancels)
    r = {"a": 0.4, "b": 0.8}
    np.testing.assert_allclose(fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1}, reference=r),
                               fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1},
                                              reference={n: 0.5 * v for n, v in r.items()}), rtol=1e-10)
    # power 0 is the fixed-weight fusion
    np.testing.assert_allclose(fuse_distances({"a": A, "b": B}, {"a": 1, "b": 2}, power=0),
                               fuse_distances({"a": A, "b": B}, {"a": 1, "b": 2}, adaptive=False), rtol=1e-12)
    # typical gaps: the median of the query gaps; the library covers its own components
    t = typical_gaps({"a": A})
    assert t["a"] == pytest.approx(float(np.median(query_gaps(A))))
    assert all(0 < FUSED_GAP_REFERENCE[c] <= 1 for c in FUSED_WEIGHTS)
    assert FUSED_POWER > 0
    with pytest.raises(InvalidOptionError, match="power"):
        fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1}, power=-1)
    with pytest.raises(InvalidOptionError, match="reference gap of 'a'"):
        fuse_distances({"a": A, "b": B}, {"a": 1, "b": 1}, reference={"a": 0.0})
    with pytest.raises(InvalidOptionError, match="all_pairs needs a square"):
        query_gaps(A[:3], all_pairs=True)


def test_l2_distances_are_exact_for_equal_vectors():
    """A stored copy of the query must be at distance 0 (the index's top hit), so L2 is taken
    from the differences, not from the cancelling |x|² + |y|² − 2 x·y."""
    from geoshape.retrieval.descriptors import descriptor_distances

    rng = np.random.default_rng(0)
    X = rng.uniform(100, 200, (3, 272))
    D = descriptor_distances("shd", X, X.copy())
    assert np.all(np.diag(D) == 0.0)
    np.testing.assert_allclose(D, np.linalg.norm(X[:, None] - X[None], axis=-1), rtol=1e-12)


def test_estimated_row_with_the_whole_database_is_the_fused_row():
    """Given the whole database as its sample and the exact nearest distances, the row fused
    from outside statistics is the (1, M) row of ``fuse_distances``; with a sample its
    distances keep the same order when the sample's medians are the database's."""
    from geoshape.retrieval.fusion import FUSED_K, fuse_estimated_row

    rng = np.random.default_rng(2)
    rows = {"evd_heat": rng.random(60), "shd": 7.0 * rng.random(60), "pcavox": 0.1 * rng.random(60)}
    weights = {"evd_heat": 0.2, "shd": 0.3, "pcavox": 0.5}
    full = fuse_distances({c: r[None] for c, r in rows.items()}, weights, all_pairs=False)[0]
    near = {c: np.sort(r)[:FUSED_K] for c, r in rows.items()}
    est = fuse_estimated_row(rows, rows, near, weights)
    assert np.allclose(est, full, rtol=1e-12)
    # a subset scored with the full statistics: the same numbers for those items
    part = fuse_estimated_row({c: r[10:20] for c, r in rows.items()}, rows, near, weights)
    assert np.allclose(part, full[10:20], rtol=1e-12)
    with pytest.raises(InvalidOptionError, match="non-negative"):
        fuse_estimated_row({**rows, "shd": -rows["shd"]}, rows, near, weights)
