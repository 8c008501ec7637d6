"""Coarse-to-fine all-pairs search of 2D retrieval (``shape_distance_matrix(search=…)``).

Exact mode is the previous matrix, bit for bit; coarse-to-fine matches each query's nearest
shapes exactly (same bits as exact mode) and puts every other entry after them.
"""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.contour.matching import cyclic_dp_gram_costs
from geoshape.contour.methods import contour_signature, method_spec, pair_costs
from geoshape.contour.retrieval import nearest_mask, shape_distance_matrix
from geoshape.errors import InvalidOptionError


@pytest.fixture(scope="module")
def collection():
    """Three classes of articulated silhouettes, four instances each (60 contour points)."""
    from geoshape_datasets_gen.silhouettes2d import articulated_silhouette

    from geoshape.geometry.contour import extract_contour

    contours, labels = [], []
    for cls in ("quadruped", "person", "crab"):
        for seed in range(4):
            contours.append(extract_contour(articulated_silhouette(cls, seed=seed), n_points=60))
            labels.append(cls)
    return contours, labels


@pytest.fixture(scope="module")
def signatures(collection):
    spec = method_spec("default")
    return [contour_signature(P, spec=spec) for P in collection[0]]


@pytest.fixture(scope="module")
def exact(signatures):
    return shape_distance_matrix(None, signatures=signatures, search="exact", backend="serial")


def test_exact_mode_is_the_pairwise_definition(signatures, exact):
    """Entry (i, j), i < j, is ``pair_costs`` of shape i against shape j, to the bit."""
    spec = method_spec("default")
    n = len(signatures)
    ref = np.zeros((n, n))
    for i in range(n - 1):
        ref[i, i + 1:] = pair_costs(signatures[i], signatures[i + 1:], spec)
    ref = ref + ref.T
    assert np.array_equal(exact, ref)
    # "auto" on a collection this small (N ≤ 4 · refine_k) is the exact search.
    assert np.array_equal(shape_distance_matrix(None, signatures=signatures, backend="serial"), exact)


def test_coarse_to_fine_refines_nearest_exactly_and_ranks_the_rest_after(signatures, exact):
    k = 4
    D = shape_distance_matrix(None, signatures=signatures, search="coarse_to_fine", refine_k=k,
                              backend="serial")
    n = len(D)
    assert np.array_equal(D, D.T) and np.all(np.diag(D) == 0)
    off = ~np.eye(n, dtype=bool)
    refined = D == exact
    # every row has at least its k nearest (by the first pass) matched exactly
    assert np.all((refined & off).sum(axis=1) >= k)
    assert 0 < (refined & off).mean() < 1
    # the other entries rank after every exact entry of the matrix
    assert D[~refined].min() > D[refined & off].max()


def test_coarse_to_fine_keeps_each_rows_top_ranks(collection, signatures, exact):
    labels = np.array(collection[1])
    D = shape_distance_matrix(None, signatures=signatures, search="coarse_to_fine", refine_k=4,
                              backend="serial")
    top = 3  # the other instances of the class
    for i in range(len(D)):
        got = np.argsort(D[i], kind="stable")[1:top + 1]
        want = np.argsort(exact[i], kind="stable")[1:top + 1]
        assert got.tolist() == want.tolist()
    # and on this collection they are the class mates
    assert np.all(labels[np.argsort(exact, axis=1)[:, 1:top + 1]] == labels[:, None])


def test_coarse_to_fine_with_every_pair_refined_is_exact(signatures, exact):
    n = len(signatures)
    D = shape_distance_matrix(None, signatures=signatures, search="coarse_to_fine", refine_k=n - 1,
                              backend="serial")
    assert np.array_equal(D, exact)


def test_coarse_to_fine_processes_equal_serial(signatures):
    kw = dict(signatures=signatures, search="coarse_to_fine", refine_k=3)
    serial = shape_distance_matrix(None, backend="serial", **kw)
    parallel = shape_distance_matrix(None, backend="processes", n_jobs=2, **kw)
    assert np.array_equal(serial, parallel)


@pytest.mark.parametrize("n_starts", [2, 16])
def test_first_pass_takes_at_most_coarse_starts_per_orientation(signatures, monkeypatch, n_starts):
    from geoshape.contour import retrieval

    seen = []
    real = retrieval._coarse_block

    def spy(items_a, items_b, skip_cost, n_starts):
        seen.append(n_starts)
        return real(items_a, items_b, skip_cost, n_starts)

    monkeypatch.setattr(retrieval, "_coarse_block", spy)
    shape_distance_matrix(None, signatures=signatures, search="coarse_to_fine", refine_k=3,
                          backend="serial", n_starts=n_starts)
    assert seen == [min(n_starts, retrieval.COARSE_STARTS)]


def test_nearest_mask_is_symmetric_and_excludes_the_diagonal():
    A = np.array([[0.0, 1.0, 2.0, 3.0], [1.0, 0.0, 5.0, 6.0], [2.0, 5.0, 0.0, 0.5],
                  [3.0, 6.0, 0.5, 0.0]])
    m = nearest_mask(A, 1)
    assert np.array_equal(m, m.T) and not m.diagonal().any()
    assert sorted(zip(*np.nonzero(np.triu(m)), strict=True)) == [(0, 1), (2, 3)]


def test_single_precision_gram_costs_equal_double_on_the_same_values():
    rng = np.random.default_rng(0)
    G = rng.random((3, 2, 12, 10)).astype(np.float32)
    n1, n2 = rng.random(10) * 5, rng.random((3, 2, 12)) * 5
    assert np.array_equal(cyclic_dp_gram_costs(G, n1, n2, n_starts=4),
                          cyclic_dp_gram_costs(G.astype(np.float64), n1, n2, n_starts=4))


def test_bad_search_options(signatures, collection):
    with pytest.raises(InvalidOptionError, match="coarse_to_fine"):
        shape_distance_matrix(None, signatures=signatures, search="fast")
    with pytest.raises(InvalidOptionError, match="refine_k"):
        shape_distance_matrix(None, signatures=signatures, search="coarse_to_fine", refine_k=0)
    with pytest.raises(InvalidOptionError, match="exact"):
        shape_distance_matrix(collection[0][:3], "gsc", search="coarse_to_fine", backend="serial")


def test_speed2d_compares_with_an_exact_reference(signatures, exact, collection):
    from geoshape.bench.speed2d import _compare

    labels = collection[1]
    assert "identical" in _compare(exact, exact.copy(), labels, "ref.npy")
    D = shape_distance_matrix(None, signatures=signatures, search="coarse_to_fine", refine_k=4,
                              backend="serial")
    text = _compare(exact, D, labels, "ref.npy")
    assert "of the off-diagonal entries are the exact distances" in text and "t = 40:" in text
    assert "not compared" in _compare(exact[:3, :3], D, labels, "ref.npy")


@pytest.mark.parametrize("backend", ["serial", "processes"])
def test_search_matrix_is_its_parts_and_coarse2d_measures_recall(signatures, exact, backend):
    """The coarse-to-fine matrix is the exact one where the first pass refines and the first
    pass after it elsewhere (what ``bench coarse2d`` rebuilds without matching again); recall
    is the share of the exact first ranks inside the refined set."""
    from geoshape.contour.retrieval import COARSE_STARTS, first_pass_matrix, refined_matrix
    from geoshape.metrics.retrieval import rank_recall

    spread_power = method_spec("default").get("spread_power", 0.0)  # as bench coarse2d passes it
    coarse = first_pass_matrix(signatures, 0.3, COARSE_STARTS, spread_power=spread_power,
                               backend=backend, n_jobs=2)
    assert np.array_equal(coarse, coarse.T) and not coarse.diagonal().any()
    refine = nearest_mask(coarse, 3)
    D = shape_distance_matrix(None, signatures=signatures, search="coarse_to_fine", refine_k=3,
                              backend="serial")
    assert np.array_equal(refined_matrix(exact, coarse, refine), D)
    assert np.array_equal(rank_recall(exact, np.ones_like(refine), (5,))[5], np.ones(len(exact)))
    ranks = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]], dtype=float)
    keep = np.zeros((4, 4), dtype=bool)
    keep[0, 1] = keep[1, 3] = True
    assert np.array_equal(rank_recall(ranks, keep, (2,))[2], [0.5, 0.5, 0.0, 0.0])


def test_coarse2d_bench_rejects_bad_start_counts(tmp_path, capsys):
    from geoshape.__main__ import main

    assert main(["bench", "coarse2d", "--matrix-dir", str(tmp_path), "--starts", "4,x"]) == 2
    assert "--starts" in capsys.readouterr().err
