"""``geoshape bench evd`` on a small generated collection: settings table and section."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.__main__ import main
from geoshape.bench.evd import evd_from_samples, mesh_samples, parse_width
from geoshape.errors import InvalidOptionError


def test_bench_evd_writes_the_settings_table(tmp_path, monkeypatch, capsys):
    from geoshape_datasets_gen.articulated3d import write_collection

    write_collection(tmp_path / "set", classes=["biped", "snake"], poses=2, seed=1,
                     target_vertices=600, resolution=48)
    results = tmp_path / "RESULTS.md"
    monkeypatch.setenv("GEOSHAPE_RESULTS", str(results))
    assert main(["bench", "evd", str(tmp_path / "set"), "--samples", "20,40",
                 "--widths", "max,area:0.2"]) == 0
    text = results.read_text()
    assert "<!-- BEGIN evd-settings -->" in text
    rows = [line for line in text.splitlines() if line.startswith("| 20 ") or line.startswith("| 40 ")]
    assert len(rows) == 2 * 2 * 2  # samples x widths x weightings
    # two very different classes: every setting ranks a same-class pose first
    assert all(float(r.split("|")[4]) == 1.0 for r in rows)
    assert "First tier per class" in text and "- best scale-invariant row" in text
    # the exact-spectrum reference row of the scale-invariant width
    assert any(line.startswith("| exact | area:0.2 |") for line in text.splitlines())


def test_weighted_settings_match_the_library_descriptor():
    """The bench's cached computation is the library's quadrature EVD (same samples, same cells)."""
    import trimesh

    from geoshape.retrieval.descriptors import evd

    m = trimesh.creation.icosphere(3)
    cache = mesh_samples(m.vertices, m.faces, 80, prefixes=(50, 80))
    for l in (50, 80):  # a prefix gets the exact Voronoi cells of its own samples
        ours = evd_from_samples(cache, l, "area:0.1", weighted=True)
        library = evd.evd_descriptor(m.vertices, m.faces, n_samples=l)
        # the library cuts rows at 6 sigma (affinities below 1e-7): equal to that precision
        assert np.allclose(ours, library, atol=1e-6)


def test_width_specs():
    assert parse_width("max") == ("max", 1.0)
    assert parse_width("area:0.1") == ("area", 0.1)
    assert parse_width("abs:20") == ("abs", 20.0)
    for bad in ("area:-1", "median:0.5", "mean:x", "abs:0"):
        with pytest.raises(InvalidOptionError, match="bad width"):
            parse_width(bad)


def test_reference_evd_is_the_heat_kernel_spectrum():
    """Known answer: a unit-area sphere has μ = 4π l(l + 1) with multiplicity 2l + 1."""
    from geoshape.bench.evd import reference_evd

    mu = np.repeat([4 * np.pi * l * (l + 1) for l in range(4)], [1, 3, 5, 7])
    rho = 0.1
    expected = np.sqrt(2 * np.pi) * rho * np.exp(-rho**2 * mu / 4)
    assert np.allclose(reference_evd(mu, 1.0, "area:0.1"), expected)
    # area:ρ ignores the size; abs:S at area A equals area:(S / sqrt(A))
    assert np.allclose(reference_evd(mu, 9.0, "area:0.1"), expected)
    assert np.allclose(reference_evd(mu, 9.0, "abs:0.3"), expected)
    assert not np.allclose(reference_evd(mu, 4.0, "abs:0.3"), expected)
    with pytest.raises(InvalidOptionError, match="reference rows"):
        reference_evd(mu, 1.0, "max")


def test_most_confused_pair_and_class_separation():
    from geoshape.bench.evd import class_separation, most_confused_pair

    labels = ["a", "a", "b", "b", "c", "c"]
    x = np.array([0.0, 0.2, 0.1, 0.3, 5.0, 5.1])  # a and b interleave, c is far away
    D = np.abs(x[:, None] - x[None, :])
    a, b, count = most_confused_pair(D, labels)
    assert (a, b) == ("a", "b") and count == 4  # every a and b query's one first-tier place
    y = np.array([0.0, 1.0, 10.0, 11.0])  # separated classes: no confusion
    assert most_confused_pair(np.abs(y[:, None] - y[None, :]), ["a", "a", "b", "b"]) == ("", "", 0)

    # labels need not be strings
    assert most_confused_pair(D, [1, 1, 2, 2, 3, 3])[:2] == ("1", "2")

    values = np.array([[10.0, 1.0], [10.0, 3.0], [12.0, 1.0], [12.0, 3.0]])
    gap, spread = class_separation(values, ["a", "a", "b", "b"], "a", "b")
    assert np.allclose(gap, [1 - 10 / 12, 0.0])
    assert np.allclose(spread, [0.0, 0.5])  # std 1 over mean 2 in both classes


def test_separation_table_rows_and_missing_values():
    from geoshape.bench.evd import _separation_table, class_separation

    labels = ["a", "a", "b", "b"]
    values = np.array([[0.0, 10.0, 1.0], [0.0, 10.0, 3.0], [0.0, 12.0, 1.0], [0.0, 12.0, 3.0]])
    size = np.array([1.0, 1.0, 2.0, 2.0])
    text = _separation_table([("eig", values, [(1, 1), (2, 2)]), ("size", size, None)], labels, "a", "b")
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:5]]
            for line in text.splitlines()[2:]}
    assert rows["eig, 1–1"] == ["16.7 %", "0.0 %", "n/a"]  # no spread: the ratio is undefined
    assert rows["eig, 2–2"] == ["0.0 %", "50.0 %", "0.00"]
    assert rows["size"] == ["50.0 %", "0.0 %", "n/a"]
    gap, spread = class_separation(values, labels, "a", "b")
    assert np.isnan(gap[0]) and np.isnan(spread[0])  # zero class means
    assert np.isnan(class_separation(values, labels, "a", "z")[0]).all()  # a missing class
