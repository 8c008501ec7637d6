"""Retrieval and correspondence metrics against hand-computed and analytic values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import grid_mesh, icosphere, shared_dataset

from geoshape.errors import GeoshapeError, InvalidOptionError
from geoshape.metrics import retrieval as M
from geoshape.metrics.correspondence import (
    GeodesicErrorEvaluator,
    cumulative_error_curve,
    geodesic_errors,
)
from geoshape.plot.correspondence import plot_error_curves
from geoshape.plot.retrieval import plot_precision_recall


def line_matrix(x):
    x = np.asarray(x, dtype=float)
    return np.abs(x[:, None] - x[None, :])


# Two classes on a line. Ranked relevance (query excluded), worked out by hand:
#   a0, a1, b1, b2 -> [1, 0, 1, 0, 0];   a2, b0 -> [0, 0, 0, 1, 1]
TOY_X = [0.0, 1.0, 5.0, 3.2, 7.0, 8.5]
TOY_LABELS = ["a", "a", "a", "b", "b", "b"]


def test_toy_ranked_relevance():
    rel, n_rel = M.ranked_relevance(line_matrix(TOY_X), TOY_LABELS)
    x_row, y_row = [1, 0, 1, 0, 0], [0, 0, 0, 1, 1]
    assert rel.astype(int).tolist() == [x_row, x_row, y_row, y_row, x_row, x_row]
    assert n_rel.tolist() == [2] * 6


def test_toy_hand_values():
    D, lab = line_matrix(TOY_X), TOY_LABELS
    assert M.top_k_counts(D, lab, max_rank=5).tolist() == [4, 0, 4, 2, 2]
    assert M.nearest_neighbor(D, lab) == pytest.approx(4 / 6)
    assert M.first_tier(D, lab) == pytest.approx((4 * 0.5 + 2 * 0) / 6)
    assert M.second_tier(D, lab) == pytest.approx((4 * 1 + 2 * 0.5) / 6)
    # class a: queries 0, 1 find one of two in the first tier, query 2 none; b likewise
    assert M.first_tier_by_class(D, lab) == pytest.approx({"a": 1 / 3, "b": 1 / 3})
    # depth 3: X rows find 2 (P = 2/3, R = 1, E = 4/5), Y rows find 0
    assert M.e_measure(D, lab, depth=3) == pytest.approx(4 * 0.8 / 6)
    # depth 32 is clipped to N - 1 = 5: every row finds both, P = 2/5, R = 1, E = 4/7
    assert M.e_measure(D, lab) == pytest.approx(4 / 7)
    dcg_x = 1 + 1 / math.log2(3)
    dcg_y = 1 / math.log2(4) + 1 / math.log2(5)
    assert M.dcg(D, lab) == pytest.approx((4 * dcg_x + 2 * dcg_y) / 6 / 2.0)
    ap_x, ap_y = (1 + 2 / 3) / 2, (1 / 4 + 2 / 5) / 2
    assert M.mean_average_precision(D, lab) == pytest.approx((4 * ap_x + 2 * ap_y) / 6)
    r, p = M.precision_recall_curve(D, lab, recall_levels=[0.0, 0.5, 1.0])
    np.testing.assert_allclose(p, [(4 + 0.8) / 6, (4 + 0.8) / 6, (4 * 2 / 3 + 0.8) / 6])


def test_bulls_eye_hand_value():
    # three classes of two; by hand the per-query shares are 1, 1, .5, .5, .5, 1
    x = [0.0, 2.9, 1.0, 20.0, 2.2, 30.0]
    lab = ["a", "a", "b", "b", "c", "c"]
    assert M.bulls_eye(line_matrix(x), lab) == pytest.approx(75.0)


def test_perfect_matrix():
    lab = np.array([0, 0, 0, 1, 1, 2, 2, 2, 2])
    D = np.where(lab[:, None] == lab[None, :], 1.0, 2.0)
    m = M.retrieval_metrics(D, lab)
    assert m["nearest_neighbor"] == 1.0
    assert m["first_tier"] == 1.0 and m["second_tier"] == 1.0
    assert m["bulls_eye"] == 100.0
    assert m["map"] == pytest.approx(1.0) and m["dcg"] == pytest.approx(1.0)
    assert m["pr_precision"] == pytest.approx([1.0] * 11)
    # ranks 1..8: classes of 3, 2 and 4 members have 2, 1 and 3 other members
    assert m["top_k_counts"] == [9, 7, 4, 0, 0, 0, 0, 0]
    assert m["top_k_total"] == 20 and m["top_k_max"] == 9 * 8
    import json

    json.dumps(m)  # JSON-friendly: plain Python types only


def test_ties_are_stable():
    # every item at the same distance: ranking follows index order, query removed
    D = np.ones((4, 4))
    rel, _ = M.ranked_relevance(D, [0, 1, 0, 1])
    assert rel.astype(int).tolist() == [[0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0]]


def test_diagonal_is_ignored():
    D = line_matrix(TOY_X)
    D2 = D.copy()
    np.fill_diagonal(D2, 99.0)
    assert M.retrieval_metrics(D, TOY_LABELS) == M.retrieval_metrics(D2, TOY_LABELS)


def test_singleton_class_warns():
    D = line_matrix([0, 1, 2, 10])
    with pytest.warns(UserWarning, match="1 queries have no other item"):
        assert M.nearest_neighbor(D, [0, 0, 0, 1]) == 1.0


def test_bad_retrieval_input():
    with pytest.raises(InvalidOptionError, match=r"square \(N, N\), got \(3, 4\)"):
        M.retrieval_metrics(np.zeros((3, 4)), [0, 0, 1])
    with pytest.raises(InvalidOptionError, match=r"one label per row of D \(3\).*\(2,\)"):
        M.retrieval_metrics(np.zeros((3, 3)), [0, 1])
    D = line_matrix([0, 1, 2])
    D[0, 2] = np.nan
    with pytest.raises(GeoshapeError, match=r"NaN or infinite.*D\[0, 2\]"):
        M.bulls_eye(D, [0, 0, 1])
    with pytest.raises(InvalidOptionError, match="max_rank"):
        M.top_k_counts(line_matrix([0, 1, 2]), [0, 0, 1], max_rank=5)


def test_rank_recall_counts_kept_first_ranks():
    """The share of each query's first ranks (query excluded, ties by index) a mask keeps; a
    depth beyond N − 1 counts every other item; a permuted collection permutes the answer."""
    rng = np.random.default_rng(3)
    X = rng.normal(size=(9, 2))
    D = np.linalg.norm(X[:, None] - X[None], axis=-1)
    everything = M.rank_recall(D, np.ones((9, 9), bool), depths=(1, 4, 30))
    assert all(np.array_equal(r, np.ones(9)) for r in everything.values())
    nearest = np.argsort(D + np.diag(np.full(9, np.inf)), axis=1)
    mask = np.zeros((9, 9), bool)
    mask[np.arange(9), nearest[:, 0]] = True  # each query's first neighbour only
    r = M.rank_recall(D, mask, depths=(1, 2, 8, 30))
    assert np.array_equal(r[1], np.ones(9)) and np.allclose(r[2], 0.5)
    assert np.allclose(r[8], 1 / 8) and np.allclose(r[30], 1 / 8)
    perm = rng.permutation(9)
    r_perm = M.rank_recall(D[np.ix_(perm, perm)], mask[np.ix_(perm, perm)], depths=(2,))
    assert np.array_equal(r_perm[2], r[2][perm])
    D_tied = np.ones((3, 3))  # all tied: the first rank is the lowest other index
    assert M.rank_recall(D_tied, np.eye(3, k=1, dtype=bool), depths=(1,))[1].tolist() == [1.0, 0.0, 0.0]


@pytest.mark.parametrize(("D", "kept", "depths", "message"), [
    (np.ones((3, 4)), np.ones((3, 4), bool), (1,), "must be square"),
    ([[0, np.nan], [1, 0]], np.ones((2, 2), bool), (1,), "NaN or infinite"),
    (np.ones((3, 3)), np.ones((2, 2), bool), (1,), "kept must be an (N, N) = (3, 3) mask"),
    (np.ones((3, 3)), np.full((3, 3), 0.5), (1,), "mask of booleans"),
    (np.ones((3, 3)), np.ones((3, 3), bool), (0,), "depths must be integers >= 1"),
    (np.ones((3, 3)), np.ones((3, 3), bool), (2.5,), "got (2.5,)"),
    (np.ones((3, 3)), np.ones((3, 3), bool), (), "depths must be integers"),
])
def test_rank_recall_rejects_bad_input(D, kept, depths, message):
    with pytest.raises(InvalidOptionError) as err:
        M.rank_recall(D, kept, depths=depths)
    assert message in str(err.value)


def test_plot_precision_recall(tmp_path):
    m = M.retrieval_metrics(line_matrix(TOY_X), TOY_LABELS)
    out = plot_precision_recall({"toy": m, "flat": ([0, 1], [0.5, 0.5])}, tmp_path / "pr.png")
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert [p.name for p in tmp_path.iterdir()] == ["pr.png"]  # no temporary left behind


# ---------------------------------------------------------------------------------------
# Correspondence
# ---------------------------------------------------------------------------------------


def mirrored_grid(nx=9, ny=5):
    """Unit square grid (area 1) and its x -> 1 - x vertex map."""
    V, F = grid_mesh(nx, ny, size=1.0)
    i, j = np.divmod(np.arange(nx * ny), ny)
    return V, F, (nx - 1 - i) * ny + j


def test_ground_truth_and_mirror_on_flat_grid():
    V, F, mirror = mirrored_grid()
    ident = np.arange(len(V))
    r = geodesic_errors(V, F, ident, ident, mirror)
    assert r["mean"] == 0 and r["mean_sym_aware"] == 0
    assert r["curve"][0] == 1.0
    # the mirror map: wrong directly, right symmetry-aware. On a flat convex square the
    # geodesic is the straight segment, so the direct error is |2x - 1| / sqrt(1).
    r = geodesic_errors(V, F, mirror, ident, mirror)
    np.testing.assert_allclose(r["errors"], np.abs(2 * V[:, 0] - 1), rtol=1e-9, atol=1e-12)
    assert r["mean"] > 0.4
    assert r["mean_sym_aware"] == 0 and r["symmetric_chosen"]
    np.testing.assert_array_equal(r["curve_sym_aware"], np.ones(51))


def test_mirror_map_on_icosphere():
    from scipy.spatial import cKDTree

    V, F = icosphere(2)
    dist, mirror = cKDTree(V).query(V * [-1.0, 1.0, 1.0])
    assert dist.max() < 1e-9  # trimesh's icosphere is symmetric in x
    ident = np.arange(len(V))
    r = geodesic_errors(V, F, mirror, None, mirror, identity_samples=None)
    assert r["mean"] > 0.1 and r["mean_sym_aware"] == 0
    assert len(r["landmarks"]) == len(V)
    # a map shifted to a neighbour is small but not zero in both scores
    r = geodesic_errors(V, F, F[:, 0][:50], F[:, 1][:50], F[:, 1][:50][::-1])
    assert 0 < r["mean"] == r["mean_sym_aware"] < 0.1
    assert not r["symmetric_chosen"]
    assert geodesic_errors(V, F, ident, identity_samples=None)["mean"] == 0


def test_exact_geodesics_on_sphere_match_great_circle():
    # polyhedral distances on a 2562-vertex icosphere of radius 1 are within 0.5 % of the
    # great-circle arc (measured 0.07 %); the heat method within 5 %.
    V, F = icosphere(4)
    rng = np.random.default_rng(7)
    s, t = rng.integers(0, len(V), 25), rng.integers(0, len(V), 25)
    keep = s != t
    s, t = s[keep], t[keep]
    arc = np.arccos(np.clip(np.sum(V[s] * V[t], axis=1), -1, 1))
    exact = GeodesicErrorEvaluator(V, F, exact_below=np.inf).distances(s, t)
    np.testing.assert_allclose(exact, arc, rtol=5e-3)
    heat = GeodesicErrorEvaluator(V, F, method="heat").distances(s, t)
    np.testing.assert_allclose(heat, arc, rtol=5e-2)
    # neighbours: the exact distance is the edge length
    e = F[:30, :2]
    d = GeodesicErrorEvaluator(V, F).distances(e[:, 0], e[:, 1])
    np.testing.assert_allclose(d, np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1), rtol=1e-9)


def test_identity_subsampling_is_seeded():
    V, F, mirror = mirrored_grid()
    a = geodesic_errors(V, F, mirror, identity_samples=10, seed=3)
    b = geodesic_errors(V, F, mirror, identity_samples=10, seed=3)
    assert len(a["landmarks"]) == 10
    np.testing.assert_array_equal(a["landmarks"], b["landmarks"])
    np.testing.assert_allclose(a["errors"], np.abs(2 * V[a["landmarks"], 0] - 1), atol=1e-12)


def test_cumulative_curve():
    th, frac = cumulative_error_curve([0.0, 0.05, 0.2, 0.3])
    assert th[0] == 0 and th[-1] == 0.25 and len(th) == 51
    assert frac[0] == 0.25 and frac[10] == 0.5 and frac[-1] == 0.75


def test_bad_correspondence_input():
    V, F, mirror = mirrored_grid()
    n = len(V)
    with pytest.raises(InvalidOptionError, match=rf"must lie in \[0, {n - 1}\].*{n + 5}"):
        geodesic_errors(V, F, np.array([0, n + 5]), np.array([0, 1]))
    with pytest.raises(InvalidOptionError, match="true_landmarks has 3 entries.*has 2"):
        geodesic_errors(V, F, np.array([0, 1]), np.array([0, 1, 2]))
    with pytest.raises(InvalidOptionError, match="integer vertex ids"):
        geodesic_errors(V, F, np.array([0.5, 1.0]), np.array([0, 1]))
    with pytest.raises(InvalidOptionError, match="identity ground truth needs one prediction"):
        geodesic_errors(V, F, np.array([0, 1]))
    with pytest.raises(InvalidOptionError, match="method must be one of.*'dijkstra'"):
        geodesic_errors(V, F, mirror, method="dijkstra")
    with pytest.raises(GeoshapeError, match="NaN"):
        V2 = V.copy()
        V2[0, 0] = np.nan
        geodesic_errors(V2, F, mirror)


def test_plot_error_curves(tmp_path):
    V, F, mirror = mirrored_grid()
    r = geodesic_errors(V, F, mirror, np.arange(len(V)), mirror)
    out = plot_error_curves({"mirror": r, "raw": r["errors"]}, tmp_path / "c.svg", sym_aware=True)
    assert out.read_text().lstrip().startswith("<?xml")


@pytest.mark.data
def test_exact_matches_whole_mesh_mmp_on_tosca():
    import gzip

    import igl
    import trimesh

    folder = shared_dataset("tosca_r5k")
    with gzip.open(folder / "vtx_5k" / "cat0.off.gz") as fh:
        m = trimesh.load(fh, file_type="off", process=False)
    V, F = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
    ev = GeodesicErrorEvaluator(V, F)
    s = np.array([0, 100, 2000, 3500])
    t = np.array([7, 4000, 2010, 3000])
    got = ev.distances(s, t)
    none = np.zeros(0, dtype=np.int64)
    for k in range(len(s)):
        ref = igl.exact_geodesic(V, F, s[k : k + 1], none, t[k : k + 1], none)[0]
        if ref <= 0.25 * ev.sqrt_area:  # certified range: exact
            assert got[k] == pytest.approx(ref, rel=1e-9)
        else:  # edge-flip length: a geodesic, never shorter than the shortest
            assert ref * (1 - 1e-9) <= got[k] <= ref * 1.05
