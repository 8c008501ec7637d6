"""geoshape.geometry.knn: known answers, ties, the high-dimensional path, every backend."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.errors import InvalidOptionError
from geoshape.geometry.knn import (
    KD_TREE_MAX_DIM,
    KNNIndex,
    available_backends,
    k_nearest,
    kd_tree,
    nearest,
    nearest_searcher,
)


def brute_force(P, Q, k):
    """Distances and indices of the k nearest rows, in double precision, stable order."""
    D = np.linalg.norm(Q[:, None, :] - P[None, :, :], axis=2)
    idx = np.argsort(D, axis=1, kind="stable")[:, :k]
    return np.take_along_axis(D, idx, axis=1), idx


def grid(shape):
    """Integer grid points, row-major, as float (n, len(shape))."""
    axes = [np.arange(s, dtype=np.float64) for s in shape]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(shape))


@pytest.mark.parametrize("shape", [(7, 5), (4, 5, 6)])
def test_nearest_of_a_grid(rng, shape):
    G = grid(shape)
    pick = rng.integers(0, len(G), 60)
    offset = rng.uniform(-0.45, 0.45, (60, len(shape)))  # stays in the picked point's cell
    dist, idx = nearest(G, G[pick] + offset)
    assert idx.dtype == np.int64 and dist.dtype == np.float64
    assert np.array_equal(idx, pick)
    assert np.allclose(dist, np.linalg.norm(offset, axis=1))
    # the grid points themselves are their own nearest, at distance 0
    dist, idx = nearest(G, G)
    assert np.array_equal(idx, np.arange(len(G))) and np.all(dist == 0.0)


def test_k_nearest_sorted_distances(rng):
    P, Q = rng.random((200, 3)), rng.random((30, 3))
    dist, idx = k_nearest(P, Q, 6)
    assert dist.shape == idx.shape == (30, 6)
    assert np.all(np.diff(dist, axis=1) >= 0)
    d_ref, i_ref = brute_force(P, Q, 6)
    assert np.array_equal(idx, i_ref) and np.allclose(dist, d_ref)
    # k = 1 stays 2D; k above n is clamped to n
    assert k_nearest(P, Q, 1)[1].shape == (30, 1)
    dist, idx = k_nearest(P[:4], Q, 10)
    assert idx.shape == (30, 4) and np.array_equal(np.sort(idx, axis=1), np.tile(np.arange(4), (30, 1)))


def test_k_nearest_known_answer_on_a_line():
    P = np.column_stack([np.arange(10.0), np.zeros(10)])
    dist, idx = k_nearest(P, np.array([[3.2, 0.0]]), 4)
    assert np.array_equal(idx[0], [3, 4, 2, 5])
    assert np.allclose(dist[0], [0.2, 0.8, 1.2, 1.8])


def test_ties_resolve_to_a_tied_point_and_the_same_one_everywhere(rng):
    # queries at cell centres of a grid: 4 (2D) equidistant grid points each
    G = grid((6, 6))
    Q = G[rng.integers(0, len(G), 40)] + 0.5
    dist, idx = nearest(G, Q)
    assert np.allclose(dist, np.sqrt(0.5))
    assert np.allclose(np.linalg.norm(G[idx] - Q, axis=1), dist)
    # every entry point breaks the tie the same way (callers mix them)
    assert np.array_equal(nearest_searcher(G)(Q), idx)
    assert np.array_equal(KNNIndex(G).query(Q, k=1)[1], idx)
    assert np.array_equal(k_nearest(G, Q, 1)[1][:, 0], idx)
    assert np.array_equal(nearest(G, Q)[1], idx)  # and again: deterministic
    # duplicated points: one of the copies, at distance 0
    P = np.repeat(rng.random((20, 3)), 3, axis=0)
    dist, idx = nearest(P, P[::3])
    assert np.all(dist == 0.0) and np.array_equal(idx // 3, np.arange(20))


def test_high_dimensional_path_equals_brute_force(rng):
    d = KD_TREE_MAX_DIM + 4
    P, Q = rng.random((500, d)), rng.random((300, d))
    dist, idx = nearest(P, Q, block=64)  # several blocks, the last one partial
    d_ref, i_ref = brute_force(P, Q, 1)
    assert np.array_equal(idx, i_ref[:, 0])
    assert np.allclose(dist, d_ref[:, 0], rtol=0, atol=1e-12)  # recomputed in double precision
    assert np.array_equal(nearest_searcher(P)(Q), idx)
    # exact duplicates in high dimension: one of the copies, at distance 0 (which copy is a
    # tie in single precision, broken by the BLAS kernel: it changed with an OpenBLAS update)
    dup = np.concatenate([P[:50], P[:50]])
    dist, idx = nearest(dup, P[:50])
    assert np.all(dist == 0.0) and np.array_equal(idx % 50, np.arange(50))


def test_high_dimensional_k_nearest_is_exact(rng):
    P, Q = rng.random((300, 20)), rng.random((25, 20))
    dist, idx = k_nearest(P, Q, 5)
    d_ref, i_ref = brute_force(P, Q, 5)
    assert np.array_equal(idx, i_ref) and np.allclose(dist, d_ref)


@pytest.mark.parametrize("backend", available_backends())
@pytest.mark.parametrize("dim", [2, 3, 5])
def test_every_backend_matches_brute_force(backend, dim):
    rng = np.random.default_rng(2024 + dim)
    P, Q = rng.random((400, dim)), rng.random((70, dim))
    d_ref, i_ref = brute_force(P, Q, 7)
    dist, idx = KNNIndex(P, backend).query(Q, k=7)
    assert idx.dtype == np.int64
    assert np.array_equal(idx, i_ref) and np.allclose(dist, d_ref)
    dist, idx = nearest(P, Q, backend=backend)
    assert np.array_equal(idx, i_ref[:, 0]) and np.allclose(dist, d_ref[:, 0])
    dist, idx = k_nearest(P, Q, 3, backend=backend)
    assert np.array_equal(idx, i_ref[:, :3]) and np.allclose(dist, d_ref[:, :3])


def test_kd_tree_helper_supports_tree_operations(rng):
    P = rng.random((100, 3))
    tree = kd_tree(P)
    hits = tree.query_ball_point(P[:5], r=0.0)
    assert [list(h) for h in hits] == [[i] for i in range(5)]


def test_invalid_arguments(rng):
    P = rng.random((10, 3))
    with pytest.raises(InvalidOptionError, match="'scipy'"):
        KNNIndex(P, "flann")
    with pytest.raises(InvalidOptionError, match="k must be"):
        KNNIndex(P).query(P, k=11)
    with pytest.raises(InvalidOptionError, match="queries must have shape"):
        KNNIndex(P).query(rng.random((4, 2)))
    with pytest.raises(InvalidOptionError, match="points must have shape"):
        KNNIndex(np.zeros((0, 3)))
