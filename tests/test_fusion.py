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
