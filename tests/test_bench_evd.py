"""``geoshape bench evd`` on a small generated collection: settings table and section."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.__main__ import main
from geoshape.bench.evd import evd_from_samples, mesh_samples, parse_width
from geoshape.errors import InvalidOptionError


def test_bench_evd_writes_the_settings_table(tmp_path, monkeypatch, capsys):
    from datasets_gen.articulated3d import write_collection

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


def test_weighted_settings_match_the_library_descriptor():
    """The bench's cached computation is the library's quadrature EVD (same samples, same cells)."""
    import trimesh

    from geoshape.spectral import evd

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
