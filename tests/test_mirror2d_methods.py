"""``geoshape bench mirror2d --methods``: registered methods (optionally on other contour point
counts or skip costs) compared on several collections under the fixed rule."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from geoshape.bench import method_variants, mirror2d
from geoshape.errors import InvalidOptionError


def test_method_names_parse():
    assert method_variants.parse_variant("default") == ("default", 144, {})  # the default traces 144 points
    assert method_variants.parse_variant("default_100pt") == ("default_100pt", 100, {})
    assert method_variants.parse_variant("default_hf@128") == ("default_hf", 128, {})
    assert method_variants.parse_variant("default+skip0.4") == ("default", 144, {"skip_cost": 0.4})
    assert method_variants.parse_variant("default+starts16@128") == ("default", 128, {"n_starts": 16})
    weighted = method_variants.parse_variant("default_median+wgsc=0.01")[2]["parts"]
    assert [p[1] for p in weighted] == [1.0, 0.5, 0.01]  # only the named part's weight moves
    assert method_variants.parse_variant("default+parts0+smooth0.005@64") == (
        "default", 64, {"part_fraction": 0.0, "smoothing": 0.005})
    for bad in ("default+starts", "default+skipX", "default+fast", "default+starts0", "default+skip-1",
                "default@abc", "default@4", "default@128+starts8", "default+wcurvature_map=1",
                "default+wgsc=-1", "default+wgsc", "default+parts-1", "default+smooth", "default+smooth0.2"):
        with pytest.raises(InvalidOptionError, match="bad (modifier|contour point count)"):
            method_variants.parse_variant(bad)


def test_rule_uses_the_reference_for_time():
    summary = {"ref": (90.0, 0.9, 10.0), "fast": (91.0, 0.9, 19.0), "slow": (99.0, 0.99, 21.0)}
    assert mirror2d.choose(summary, "ref") == "fast"
    assert mirror2d.choose({"ref": (95.0, 0.92, 10.0), "b": (95.03, 0.91, 5.0)}, "ref") == "ref"


def _tiny_args(tmp_path, *options, per_class=3, seed=1):
    """A 3-class generated collection and ``bench mirror2d`` arguments on it (one worker,
    nothing written): ``(folder, args)``."""
    from geoshape_datasets_gen.silhouettes2d import generate_silhouettes

    folder = tmp_path / "sil"
    generate_silhouettes(folder, per_class=per_class, classes=("person", "star", "crab"), seed=seed,
                         size=96)
    parser = argparse.ArgumentParser()
    mirror2d.add_arguments(parser)
    return folder, parser.parse_args(["--matrix-dir", str(tmp_path / "work"), "--sets",
                                      f"tiny={folder}", *options, "--n-jobs", "1", "--no-write"])


def test_methods_mode_runs_and_caches(tmp_path, capsys):
    _, args = _tiny_args(tmp_path, "--methods", "height_functions,height_functions+skip0.1@64")
    assert mirror2d.run(args) == 0
    out = capsys.readouterr().out
    assert "2D default method: cross-validated choice" in out and "**chosen**" in out
    stem = mirror2d.matrix_cache_name("tiny", "height_functions+skip0.1@64")
    D = np.load(tmp_path / "work" / f"{stem}.npy")
    assert D.shape == (9, 9) and np.allclose(D, D.T)
    assert mirror2d.run(args) == 0  # from the cache: nothing recomputed
    assert "…" not in capsys.readouterr().out


def test_budget_counts_cpu_seconds_and_falls_back_to_wall_for_old_caches(tmp_path, capsys):
    """Each matrix's CPU seconds are cached beside it and the rule's budget uses them; a matrix
    cached without them (before they were recorded) puts the whole table on wall seconds, and
    the section says which."""
    import json

    _, args = _tiny_args(tmp_path, "--methods", "height_functions,height_functions+skip0.1")
    assert mirror2d.run(args) == 0
    out = capsys.readouterr().out
    assert "a method whose matrix CPU time (user + system, workers included) summed" in out
    assert "| × height_functions (CPU) |" in out
    meta = tmp_path / "work" / f"{mirror2d.matrix_cache_name('tiny', 'height_functions')}.json"
    info = json.loads(meta.read_text())
    assert info["matrix_cpu_s"] > 0
    del info["matrix_cpu_s"]
    meta.write_text(json.dumps(info))
    assert mirror2d.run(args) == 0
    out = capsys.readouterr().out
    assert "matrix wall time (cached matrices without CPU seconds) summed" in out
    assert "| × height_functions (wall) |" in out



def test_cache_is_keyed_by_what_a_method_computes(monkeypatch):
    """A registry entry that changes (``default`` taking more DP starts) gets a new cache file."""
    from geoshape.contour import methods

    before = mirror2d.matrix_cache_name("set", "default")
    assert before == mirror2d.matrix_cache_name("set", "default")
    entry = dict(methods.CONTOUR_METHODS["default"], matcher_options=dict(skip_cost=0.3, n_starts=3))
    monkeypatch.setitem(methods.CONTOUR_METHODS, "default", entry)
    assert mirror2d.matrix_cache_name("set", "default") != before


def test_cache_is_keyed_by_the_contour_tracing(monkeypatch):
    """The tracer's settings are part of what a matrix computes: changing its default, or naming
    the default explicitly, behaves like any other spec change."""
    from geoshape.geometry import contour

    plain = mirror2d.matrix_cache_name("set", "default")
    same = method_variants.effective_spec(f"default+parts{contour.PART_FRACTION}")
    assert same == method_variants.effective_spec("default")
    assert mirror2d.matrix_cache_name("set", "default+parts2") != plain
    assert mirror2d.matrix_cache_name("set", "default+smooth0.01") != plain
    monkeypatch.setattr(contour, "PART_FRACTION", 2.0)
    assert mirror2d.matrix_cache_name("set", "default") != plain


def test_pinned_defaults_keep_their_tracing_when_the_tracer_default_moves(monkeypatch):
    """Rows measured under an older default stay reproducible: ``default_100pt`` and
    ``default_128pt`` name their part fraction, ``default`` follows the tracer's."""
    from geoshape.contour.methods import contour_tracing
    from geoshape.geometry import contour

    pinned = {m: mirror2d.matrix_cache_name("set", m) for m in ("default_100pt", "default_128pt")}
    plain = mirror2d.matrix_cache_name("set", "default")
    assert contour_tracing("default_128pt")["part_fraction"] == 0.005
    assert contour_tracing("default_100pt")["part_fraction"] == 0.005
    # default_128pt is default_144pt's matcher and descriptors on its own tracing
    tracing, spec = method_variants.effective_spec("default_128pt")
    assert spec == method_variants.effective_spec("default_144pt")[1]
    assert tracing == (128, 0.005, 0.0025)
    monkeypatch.setattr(contour, "PART_FRACTION", 0.5)
    assert {m: mirror2d.matrix_cache_name("set", m) for m in pinned} == pinned
    assert mirror2d.matrix_cache_name("set", "default") != plain


def test_the_default_s_matrix_digest_is_pinned():
    """Saved matrices are found by this digest (bench mirror2d's cache, the .spec files of bench
    rerank): a refactor that changed it would silently recompute every cached matrix. Update it
    only when the default's computation really changes."""
    assert method_variants.matrix_cache_name("kimia99", "default") == "kimia99_default_011a580b"
    # the default computes what the cross-validated candidate it was chosen as computed
    spec = method_variants.effective_spec
    assert spec("default") == spec("default_zernike+spread0.25")
    pinned_zernike = method_variants.matrix_cache_name("kimia99", "default_zernike")
    assert pinned_zernike == "kimia99_default_zernike_7d86721e"
    chosen = "default_region+rorder=12+rweight=0.0125"  # the default of 2026-12-06 (night)
    assert spec("default_zernike") == spec(chosen)
    assert method_variants.matrix_cache_name("kimia99", "default_phases") == "kimia99_default_phases_e531d5dd"
    # the defaults before, pinned: their cached matrices stay valid
    assert method_variants.matrix_cache_name("kimia99", "default_144pt") == "kimia99_default_144pt_9e4dce61"
    pinned_heights = method_variants.matrix_cache_name("kimia99", "default_heights")
    assert pinned_heights == "kimia99_default_heights_d70f6ae3"


def test_heights_variants_run_and_name_their_setting_in_their_own_section(tmp_path, capsys):
    variant = "default_heights+hweight=0.5+hgroups=11+hphases=1@64"
    _, args = _tiny_args(tmp_path, "--methods", f"default@64,{variant}", "--section", "default2d-trial")
    assert mirror2d.run(args) == 0
    out = capsys.readouterr().out
    assert "## 2D default method: cross-validated choice (default2d-trial)" in out
    assert "--section default2d-trial" in out
    assert "heights term weight 0.5, skip cost 0.15, 11 runs, every 2 points of every sampling phase" in out


def test_settings_mode_builds_the_default_s_mirror_variant_from_mirrored_shapes(tmp_path, capsys):
    """``--settings``: the mirror images' descriptors (histograms and height functions) come
    from the mirrored shapes' direct ones, so setting ``on-16`` is the default's own matrix."""
    from geoshape.contour.methods import contour_tracing
    from geoshape.contour.retrieval import load_contours, shape_distance_matrix
    from geoshape.io.datasets import read_labels

    folder, args = _tiny_args(tmp_path, "--settings", "off,on-16", per_class=2, seed=2)
    work = tmp_path / "work"
    assert mirror2d.run(args) == 0
    assert "2D mirror-aware matching" in capsys.readouterr().out
    stem = mirror2d.matrix_cache_name("tiny", "default")
    D = np.load(work / f"{stem}-mirror-on-16.npy")
    contours = load_contours([it.path for it in read_labels(folder)], **contour_tracing("default"))
    np.testing.assert_allclose(D, shape_distance_matrix(contours, backend="serial"), rtol=1e-12, atol=1e-15)


def test_region_variants_name_their_setting(tmp_path, capsys):
    _, args = _tiny_args(tmp_path, "--methods", "default@64,default_region+rweight=0.1+rorder=6@64")
    assert mirror2d.run(args) == 0
    out = capsys.readouterr().out
    assert "region term weight 0.1, Zernike orders up to 6, disc of 2 equal-area radii instead" in out
