"""``geoshape bench retrieval3d``: methods, sets, cached matrices, the RESULTS section with re-ranking."""

import argparse

import numpy as np
import pytest

from geoshape.bench import retrieval3d as bench
from geoshape.errors import GeoshapeError


def _args(**kw):
    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    args = parser.parse_args([])
    for k, v in kw.items():
        setattr(args, k, v)
    return args


@pytest.fixture(scope="module")
def tiny_mixed(tmp_path_factory):
    """A tiny stand-in for a mixed3d folder: 3 poses each of a biped and a quadruped."""
    from geoshape_datasets_gen.articulated3d import generate_figure

    from geoshape.io.mesh_io import save_mesh

    d = tmp_path_factory.mktemp("mixed_tiny")
    rows = ["file,label"]
    for cls in ("biped", "quadruped"):
        fig = generate_figure(cls, poses=3, seed=3, target_vertices=500, resolution=48)
        for k, V in enumerate(fig.poses):
            save_mesh(d / f"{cls}{k}.off", np.asarray(V), np.asarray(fig.F))
            rows.append(f"{cls}{k}.off,{cls}")
    (d / "labels.csv").write_text("\n".join(rows) + "\n")
    return d


def test_default_methods_start_with_fused_and_cover_the_registry():
    from geoshape.retrieval.descriptors import DEFAULT_RETRIEVAL_METHOD, RETRIEVAL_METHODS

    methods = bench._methods(_args())
    assert methods[0] == DEFAULT_RETRIEVAL_METHOD == "fused"
    assert sorted(methods) == sorted(RETRIEVAL_METHODS)
    assert {"wks", "pcavox", "evd_heat", "evd_ccd"} <= set(methods)


def test_sets_accept_the_mixed_collections_and_reject_others():
    bench._check_sets(["tosca_r5k", "generated", "mixed3d", "mixed3d_s1"])
    with pytest.raises(GeoshapeError, match="nope"):
        bench._check_sets(["nope"])


def test_cache_tags_follow_the_given_folders():
    args = _args(mixed="/x/mixed3d_src", mixed_s1="/y/mine_s1")
    assert bench._cache_tag("mixed3d", args) == "mixed3d_src"
    assert bench._cache_tag("mixed3d_s1", args) == "mine_s1"
    assert bench._cache_tag("generated", args) == "generated-i2-p4"
    assert bench._cache_tag("tosca_r5k", args) == "tosca_r5k"


def test_matrix_is_the_cli_path_and_is_cached(tiny_mixed, tmp_path, monkeypatch):
    from geoshape.retrieval import meshes

    args = _args(mixed=str(tiny_mixed), cache=str(tmp_path / "cache"), n_jobs=1)
    ref = meshes.retrieval3d_on_folder(tiny_mixed, "d2", n_jobs=1, progress=False)
    res = bench._matrix("mixed3d", "d2", None, args, lambda: tiny_mixed)
    assert not res["cached"]
    np.testing.assert_allclose(res["D"], ref["D"])
    assert res["labels"] == list(ref["labels"])
    path = tmp_path / "cache" / tiny_mixed.name / "d2.npz"
    assert path.is_file()

    def boom(*a, **k):
        raise AssertionError("recomputed although cached")

    monkeypatch.setattr(meshes, "retrieval3d_on_folder", boom)
    again = bench._matrix("mixed3d", "d2", None, args, lambda: tiny_mixed)
    assert again["cached"] and again["seconds_per_mesh"] == res["seconds_per_mesh"]
    np.testing.assert_array_equal(again["D"], res["D"])
    # settings changed (different key): recomputed
    z = dict(np.load(path))
    z["key"] = "stale"
    np.savez(path, **z)
    with pytest.raises(AssertionError, match="recomputed"):
        bench._matrix("mixed3d", "d2", None, args, lambda: tiny_mixed)


def test_scores_include_lcdp_reranking():
    x = np.r_[0.0, 0.1, 0.2, 0.3, 5.0, 5.1, 5.2, 5.3]
    D = np.abs(x[:, None] - x[None, :])
    labels = ["a"] * 4 + ["b"] * 4
    met, met_rr = bench._scores(D, labels)
    for m in (met, met_rr):
        assert set(bench.METRIC_KEYS) <= set(m)
        assert m["nearest_neighbor"] == 1.0 and m["first_tier"] == 1.0


def test_run_writes_rows_with_and_without_reranking(tiny_mixed, tmp_path, monkeypatch, capsys):
    from geoshape.retrieval import meshes

    results = tmp_path / "RESULTS.md"
    monkeypatch.setenv("GEOSHAPE_RESULTS", str(results))
    args = _args(sets="mixed3d", mixed=str(tiny_mixed), descriptors="fused,d2", affinities="geodesic",
                 n_jobs=1, index_rows=0, hires=0, cache=str(tmp_path / "cache"), section="retrieval3d-test")
    assert bench.run(args) == 0
    text = results.read_text()
    assert "<!-- BEGIN retrieval3d-test -->" in text
    assert "+lcdp NN" in text and "+lcdp mAP" in text and "+lcdp E" in text
    rows = [ln for ln in text.splitlines() if ln.startswith("| mixed3d |")]
    assert [r.split(" | ")[1] for r in rows] == ["fused", "d2"]
    assert all(len(r.strip("|").split("|")) == 18 for r in rows)
    assert "--mixed DIR" in text and "--cache DIR" in text
    assert (tmp_path / "img" / "retrieval3d_pr_mixed3d.png").is_file()
    # a rerun reads every matrix from the cache and writes the same scores
    monkeypatch.setattr(meshes, "retrieval3d_on_folder",
                        lambda *a, **k: (_ for _ in ()).throw(AssertionError("recomputed")))
    assert bench.run(args) == 0
    rows2 = [ln for ln in results.read_text().splitlines() if ln.startswith("| mixed3d |")]
    assert [r.split(" | ")[4:16] for r in rows2] == [r.split(" | ")[4:16] for r in rows]


def test_cached_only_scores_the_cache_and_lists_the_rest(tiny_mixed, tmp_path, monkeypatch):
    results = tmp_path / "RESULTS.md"
    monkeypatch.setenv("GEOSHAPE_RESULTS", str(results))
    cache = tmp_path / "cache"
    args = _args(sets="mixed3d", mixed=str(tiny_mixed), descriptors="d2", affinities="geodesic", n_jobs=1,
                 index_rows=0, hires=0, cache=str(cache), section="r3d-cached")
    assert bench.run(args) == 0
    args.descriptors, args.cached_only = "d2,evd_heat", True
    assert bench.run(args) == 0
    text = results.read_text()
    assert [r.split(" | ")[1] for r in text.splitlines() if r.startswith("| mixed3d |")] == ["d2"]
    assert "Not run (no cached matrix): mixed3d: evd_heat." in text and "--cached-only" in text
    assert not (cache / tiny_mixed.name / "evd_heat.npz").exists()
