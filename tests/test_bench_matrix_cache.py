"""Saved all-pairs matrices of the 2D benchmarks (``--matrix-dir``) carry what they were computed
with, so ``geoshape bench rerank`` never re-ranks a matrix of a method whose entry has changed."""

from __future__ import annotations

import numpy as np

from geoshape.bench import rerank as bench_rerank
from geoshape.bench.retrieval2d import load_matrix, matrix_spec, save_matrix


def test_a_saved_matrix_is_read_back_only_under_the_same_spec(tmp_path, monkeypatch):
    D = np.arange(9.0).reshape(3, 3)
    save_matrix(tmp_path, "kimia99", "idsc", D)
    assert np.array_equal(load_matrix(tmp_path, "kimia99", "idsc"), D)
    assert load_matrix(tmp_path, "kimia99", "default") is None  # never saved
    # another point count is another matrix
    save_matrix(tmp_path, "tari1000", "idsc", D, n_points=64)
    assert matrix_spec("tari1000", "idsc", 64) != matrix_spec("tari1000", "idsc")
    assert load_matrix(tmp_path, "tari1000", "idsc") is None
    # a matrix without its spec file (an older version's) is not trusted
    (tmp_path / "kimia99_idsc.spec").unlink()
    assert load_matrix(tmp_path, "kimia99", "idsc") is None


def test_the_spec_follows_the_registry_entry(monkeypatch):
    from geoshape.contour import methods

    before = matrix_spec("kimia99", "idsc")
    changed = dict(methods.CONTOUR_METHODS["idsc"], matcher_options=dict(skip_cost=0.5, n_starts=4))
    monkeypatch.setitem(methods.CONTOUR_METHODS, "idsc", changed)
    assert matrix_spec("kimia99", "idsc") != before


def test_bench_rerank_recomputes_a_stale_matrix_once(tmp_path, monkeypatch, capsys):
    from geoshape.contour import methods, retrieval

    calls = []

    def fake_retrieval(folder, method):
        calls.append(method)
        return {"D": np.full((2, 2), float(len(calls)))}

    monkeypatch.setattr(retrieval, "retrieval_on_folder", fake_retrieval)
    np.save(tmp_path / "kimia99_idsc.npy", np.zeros((2, 2)))  # saved before specs existed
    first = bench_rerank._matrix("kimia99", tmp_path, tmp_path, "idsc")
    assert calls == ["idsc"] and first[0, 0] == 1.0
    assert "stale" in capsys.readouterr().out
    again = bench_rerank._matrix("kimia99", tmp_path, tmp_path, "idsc")
    assert calls == ["idsc"] and np.array_equal(again, first)  # current: read, not recomputed
    changed = dict(methods.CONTOUR_METHODS["idsc"], matcher_options=dict(skip_cost=0.5, n_starts=4))
    monkeypatch.setitem(methods.CONTOUR_METHODS, "idsc", changed)
    third = bench_rerank._matrix("kimia99", tmp_path, tmp_path, "idsc")
    assert calls == ["idsc", "idsc"] and third[0, 0] == 2.0
