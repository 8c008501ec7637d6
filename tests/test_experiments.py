"""The chapter-4 experiments run end to end through the CLI with tiny settings."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from geoshape.__main__ import main


@pytest.fixture(autouse=True)
def _results_file(tmp_path, monkeypatch):
    """Never touch docs/RESULTS.md from the tests."""
    monkeypatch.setenv("GEOSHAPE_RESULTS", str(tmp_path / "RESULTS.md"))


def _run(tmp_path, name, *extra):
    out = tmp_path / "out"
    results = tmp_path / "RESULTS.md"
    assert main(["experiment", name, "--out", str(out), *extra]) == 0
    for ext in ("png", "csv", "json"):
        assert (out / f"{name}.{ext}").stat().st_size > 0
    with open(out / f"{name}.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    meta = json.loads((out / f"{name}.json").read_text())["meta"]
    text = results.read_text()
    assert f"<!-- BEGIN experiment-{name} -->" in text
    return rows, meta


def _finite(rows, *columns):
    for r in rows:
        for c in columns:
            assert math.isfinite(float(r[c])), (c, r[c])


@pytest.mark.slow
def test_scaling(tmp_path):
    rows, meta = _run(tmp_path, "scaling", "--tosca", "none", "--generated", "snake",
                      "--base-vertices", "150", "--ratios", "0.7,0.4", "--landmarks", "20")
    assert len(rows) == 4 and {r["scaling"] for r in rows} == {"sqrt", "none"}
    _finite(rows, "mean_error", "vertex_difference", "seconds")
    assert all(int(r["vertex_difference"]) > 0 for r in rows)
    assert meta["notes"] == []


@pytest.mark.slow
def test_gaussian_width(tmp_path):
    rows, _ = _run(tmp_path, "gaussian-width", "--tosca", "none", "--generated", "snake",
                   "--base-vertices", "120", "--spikes", "5,10", "--rhos", "0.5,2", "--landmarks", "20",
                   "--repeats", "1")
    assert len(rows) == 4
    _finite(rows, "mean_error", "rho", "on_spikes", "seconds")
    assert {int(r["spikes"]) for r in rows} == {5, 10}


@pytest.mark.slow
def test_switching(tmp_path):
    rows, _ = _run(tmp_path, "switching", "--tosca", "none", "--generated", "snake",
                   "--base-vertices", "500", "--k", "4")
    assert [r["partner"] for r in rows][1:] == ["stretched x1.5", "part x2"]
    for r in rows:
        for c in ("switches_truth", "flips_truth", "switches_cost", "flips_cost", "agree"):
            assert 0 <= int(r[c]) <= 4
        assert len(r["perm_truth"].split()) == 4


@pytest.mark.slow
def test_reordering(tmp_path):
    rows, _ = _run(tmp_path, "reordering", "--generated", "snake", "--generated-vertices", "500",
                   "--tosca-pairs", "0", "--k", "3")
    assert [r["method"] for r in rows] == ["exhaustive", "greedy", "pairwise"]
    _finite(rows, "cost", "cost_ratio", "seconds")
    assert rows[0]["same_as_exhaustive"] == "True"
    assert all(float(r["cost_ratio"]) >= 1 - 1e-9 for r in rows)


@pytest.mark.slow
def test_stretching(tmp_path):
    rows, meta = _run(tmp_path, "stretching", "--tosca", "none", "--generated", "biped",
                      "--base-vertices", "1000", "--landmarks", "50")
    assert [r["variant"].split()[0] for r in rows] == ["x", "y", "z", "part"]
    _finite(rows, "mean_error", "seconds")
    # a moderately stretched copy of a mesh is matched back to itself closely
    assert max(float(r["mean_error"]) for r in rows) < 0.05
    assert meta["settings"]["factor"] == 1.5


def test_no_data_is_reported(tmp_path):
    from geoshape.bench.experiments.reordering import run_experiment

    rows = run_experiment(tmp_path, generated=("snake",), generated_vertices=500, tosca_pairs=1, k=3,
                          data_dir=tmp_path / "missing", results=False)
    meta = json.loads((tmp_path / "reordering.json").read_text())["meta"]
    assert meta["notes"] == ["tosca_r5k not found: generated meshes only"]
    assert {r["source"] for r in rows} == {"generated"}


def test_truth_alignment_recovers_a_signed_permutation():
    from geoshape.bench.experiments.switching import truth_alignment

    rng = np.random.default_rng(0)
    A = rng.normal(size=(200, 4))
    B = A[:, [1, 0, 2, 3]] * [1, -1, 1, -1]
    perm, signs, corr, _ = truth_alignment(A, B, np.arange(200), np.arange(200))
    assert perm.tolist() == [1, 0, 2, 3] and signs.tolist() == [-1, 1, 1, -1]
    np.testing.assert_allclose(corr, 1.0)


def test_bad_options(tmp_path, capsys):
    assert main(["experiment", "scaling", "--out", str(tmp_path), "--no-results", "--tosca", "none",
                 "--generated", "none"]) == 2
    assert "no meshes" in capsys.readouterr().err
    assert main(["experiment", "gaussian-width", "--out", str(tmp_path), "--no-results", "--tosca", "none",
                 "--rhos", "0,1"]) == 2
    assert main(["experiment", "scaling", "--out", str(tmp_path), "--no-results", "--ratios", "1.5"]) == 2


@pytest.mark.parametrize("name", ["scaling", "gaussian-width", "switching", "reordering", "stretching"])
def test_help_lists_experiment(name, capsys):
    assert main(["experiment", name, "--help"]) == 0
    assert "--out" in capsys.readouterr().out
