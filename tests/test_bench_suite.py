"""``geoshape bench correspondence --suite generalization``: metrics, tables, set reuse, smoke run."""

import argparse
import json
import math
import re

import numpy as np
import pytest

from geoshape.bench import correspondence_suite as suite
from geoshape.bench.correspondence import PairResult


def _pair(name, direct, sym=None, seconds=1.0):
    e = np.asarray(direct, dtype=float)
    return PairResult("geoshape", name, e, e if sym is None else np.asarray(sym, dtype=float), seconds)


def _planted():
    return [
        _pair("good", [0.01, 0.02, 0.025, 0.03], seconds=2.0),         # mean 0.02125, 3 of 4 ≤ 0.025
        _pair("flip", [0.3, 0.3, 0.3, 0.3], [0.05, 0.05, 0.05, 0.05], seconds=4.0),  # failure, flip
        _pair("lost", [0.2, 0.2, 0.2, 0.2], [0.15, 0.15, 0.15, 0.15], seconds=6.0),  # failure, no flip
        _pair("edge", [0.1, 0.1, 0.1, 0.1], [0.01, 0.01, 0.01, 0.01], seconds=8.0),  # exactly 0.1: no failure
        PairResult("geoshape", "crashed", error="boom"),
    ]


def test_metrics_count_failures_flips_and_thresholds():
    m = suite.set_metrics(_planted())
    assert m["pairs"] == 5 and m["crashed"] == 1
    assert m["failures"] == 3  # flip, lost, crashed (0.1 is not > 0.1)
    assert m["flips"] == 1  # only "flip": 0.05 < 0.5 × 0.3; "lost" 0.15 ≥ 0.1
    direct = [0.02125, 0.3, 0.2, 0.1]
    assert m["mean"] == pytest.approx(np.mean(direct))
    assert m["mean_sym"] == pytest.approx(np.mean([0.02125, 0.05, 0.15, 0.01]))
    assert m["median_pair"] == pytest.approx(np.median(direct))
    assert m["within_0.025"] == pytest.approx(100 * 3 / 16)  # ≤ is inclusive
    assert m["within_0.05"] == pytest.approx(100 * 4 / 16)
    assert m["median_s"] == pytest.approx(5.0)  # crashed pairs have no time


def test_metrics_without_symmetric_ground_truth_and_empty():
    m = suite.set_metrics(_planted()[:2], has_sym=False)
    assert m["failures"] == 1 and m["flips"] == 0 and math.isnan(m["mean_sym"])
    empty = suite.set_metrics([PairResult("pyfm", "x", error="no")])
    assert empty["pairs"] == 1 and empty["failures"] == 1 and math.isnan(empty["mean"])


def test_table_has_a_row_per_set_and_method():
    rows = [(s, m, suite.set_metrics(_planted(), has_sym=s != "tosca_hires"))
            for s in ("tosca_r5k", "tosca_hires", "nonisometric") for m in ("geoshape", "pyfm")]
    table = suite.suite_table(rows).splitlines()
    assert len(table) == 2 + 6
    assert "failures (> 0.1)" in table[0] and "flips" in table[0] and "≤ 0.025 (%)" in table[0]
    body = [[c.strip() for c in line.strip("|").split("|")] for line in table[2:]]
    assert [(r[0], r[1]) for r in body] == [(r[0], r[1]) for r in rows]
    assert body[0][8:10] == ["3", "1"] and body[2][4] == "—"


def test_sensitivity_variants_cover_the_required_defaults():
    variants = suite.sensitivity_variants()
    changed = [next(iter(o)) for _, o in variants]
    for name in ("distortion_samples", "distortion_power", "soft_temperature", "soft_rings", "n_keep",
                 "n_refine", "lb_k", "zoomout_samples", "descriptor_k"):
        assert changed.count(name) == 2
    assert ("lb_k 60 → 30 (×0.5)", {"lb_k": 30}) in variants
    assert ("distortion_power 2.0 → 1.0 (×0.5)", {"distortion_power": 1.0}) in variants


def test_sensitivity_fields_are_checked_and_kept_in_table_order():
    from geoshape.errors import InvalidOptionError

    assert suite.sensitivity_fields(None) == suite.SENSITIVITY_FIELDS
    assert suite.sensitivity_fields("final_k, screen_k") == ("screen_k", "final_k")
    variants = suite.sensitivity_variants(fields=("screen_k",))
    assert [o for _, o in variants] == [{"screen_k": 8}, {"screen_k": 32}]
    with pytest.raises(InvalidOptionError, match="field must be one of .*screen_k.*got 'screenk'"):
        suite.sensitivity_fields("screenk")
    with pytest.raises(InvalidOptionError, match="names no option"):
        suite.sensitivity_fields(",")


def test_seed_rows_change_only_the_seed_and_their_range_row_reads_the_default_and_them():
    assert suite.seed_variants(0) == []
    assert [o for _, o in suite.seed_variants(3)] == [{"seed": 1}, {"seed": 2}, {"seed": 3}]
    assert suite.sensitivity_fields("none") == ()
    nan = float("nan")
    means = [[0.1, 0.02], [0.5, 0.02], [0.12, nan], [0.09, 0.021]]  # default, lb_k ×0.5, seeds 1 and 2
    row = suite.seed_range_row(means, draws=2)
    assert row[0].startswith("sampling noise: the default and 2 other seeds")
    assert row[1] == "0.09–0.12 (±20 %)"  # the lb_k row is not a draw: left out
    assert row[2] == "0.02–0.021 (±5 %)"  # a set where a draw raised has one mean fewer
    means[0][0] = nan  # the default raised: no move from it to report
    assert suite.seed_range_row(means, draws=2)[1] == "—"
    # the draws skip the seed the default row ran with
    assert [o for _, o in suite.seed_variants(3, base=2)] == [{"seed": 0}, {"seed": 1}, {"seed": 3}]
    assert suite.seed_variants(1, base=2)[0][0].startswith("seed 2 → 0 ")
    from geoshape.errors import InvalidOptionError

    with pytest.raises(InvalidOptionError, match="--fields none stands alone"):
        suite.sensitivity_fields("none,lb_k")


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "2"], "--seeds adds rows to the sensitivity table: it needs --sensitivity"),
    (["--sensitivity", "--seeds", "-1"], "--seeds must be a count from 0 to 10, got -1"),
    (["--sensitivity", "--seeds", "11"], "--seeds must be a count from 0 to 10, got 11"),
    (["--sensitivity", "--fields", "none"], "--fields none leaves only the default row: give --seeds N too"),
])
def test_bad_seeds_stop_the_command_before_any_generation(tmp_path, capsys, argv, message):
    from geoshape.__main__ import main

    code = main(["bench", "correspondence", "--suite", "generalization", *argv, "--dev-dir", str(tmp_path),
                 "--no-results"])
    assert code == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_sets_are_selected_by_name_in_suite_order():
    from geoshape.errors import InvalidOptionError

    assert [s.name for s in suite.selected_sets(None)] == [s.name for s in suite.DEV_SETS]
    assert [s.name for s in suite.selected_sets("nonisometric, scape")] == ["scape", "nonisometric"]
    with pytest.raises(InvalidOptionError, match="dev set must be one of .*tosca_hires.*got 'tosca'"):
        suite.selected_sets("scape,tosca")
    with pytest.raises(InvalidOptionError, match="names no dev set"):
        suite.selected_sets(" , ")


def test_generated_set_is_reused_only_with_the_same_parameters(tmp_path, monkeypatch):
    spec = suite.DevSet("noniso", "pairs.csv", generator="nonisometric", params={"pairs": 3, "seed": 0})
    (tmp_path / "noniso").mkdir()
    (tmp_path / "noniso" / "generator.json").write_text(json.dumps({"pairs": 3, "seed": 0, "other": 1}))
    assert suite.prepare_set(spec, tmp_path) == tmp_path / "noniso"  # reused: no generator call
    calls = []
    import geoshape_datasets_gen.nonisometric as gen

    monkeypatch.setattr(gen, "write_nonisometric_set", lambda out, **kw: calls.append((out, kw)))
    stale = suite.DevSet("noniso", "pairs.csv", generator="nonisometric", params={"pairs": 4, "seed": 0})
    suite.prepare_set(stale, tmp_path, log=lambda _t: None)
    assert calls == [(tmp_path / "noniso", {"n_pairs": 4, "seed": 0})]


def test_a_remeshed_copy_of_a_generated_set_generates_its_source_first(tmp_path, monkeypatch):
    import geoshape_datasets_gen.nonisometric as noniso_gen
    import geoshape_datasets_gen.remesh as remesh_gen

    source = suite.DevSet("noniso", "pairs.csv", generator="nonisometric", params={"pairs": 2, "seed": 0})
    copy = suite.DevSet("noniso_r", "pairs.csv", generator="remesh",
                        params={"dataset": "noniso", "pairs": 2, "vertices": 700, "seed": 0})
    monkeypatch.setattr(suite, "DEV_SETS", (source, copy))
    calls = []
    monkeypatch.setattr(noniso_gen, "write_nonisometric_set", lambda out, **kw: calls.append(("noniso", out)))
    monkeypatch.setattr(remesh_gen, "write_remeshed_set",
                        lambda dataset, out, **kw: calls.append(("remesh", dataset, out, kw)))
    assert suite.prepare_set(copy, tmp_path, log=lambda _t: None) == tmp_path / "noniso_r"
    # the source is generated into the dev folder and remeshed from there, not from the data root
    assert calls == [("noniso", tmp_path / "noniso"),
                     ("remesh", tmp_path / "noniso", tmp_path / "noniso_r",
                      {"n_pairs": 2, "n_vertices": 700, "seed": 0})]


def _tiny_suite_args(tmp_path, monkeypatch, **flags) -> argparse.Namespace:
    """The suite's arguments on one tiny generated non-isometric pair, RESULTS.md in ``tmp_path``."""
    spec = suite.DevSet("tiny", "pairs.csv", generator="nonisometric",
                        params={"pairs": 1, "seed": 0, "target_vertices": 600, "templates": 1,
                                "resolution": 48})
    monkeypatch.setattr(suite, "DEV_SETS", (spec,))
    monkeypatch.setenv("GEOSHAPE_RESULTS", str(tmp_path / "RESULTS.md"))
    return argparse.Namespace(**{"dev_dir": str(tmp_path), "methods": "geoshape", "peer": "none", "limit": 1,
                                 "landmarks": 50, "seed": 0, "sensitivity": False, "no_results": False,
                                 "section": None, **flags})


def test_suite_smoke_on_a_tiny_generated_set(tmp_path, monkeypatch, capsys):
    args = _tiny_suite_args(tmp_path, monkeypatch)
    assert suite.run_suite(args) == 0
    text = (tmp_path / "RESULTS.md").read_text()
    assert f"<!-- BEGIN {suite.SECTION} -->" in text and "| tiny | geoshape | 1 |" in text
    assert (tmp_path / "tiny" / "generator.json").is_file()


def test_a_named_section_is_written_and_named_in_the_command(tmp_path, monkeypatch, capsys):
    """A run into its own section (e.g. the slow high-resolution set) leaves the suite table
    alone, and its command line says the section, so running it again rewrites the same one."""
    args = _tiny_suite_args(tmp_path, monkeypatch, section="correspondence-generalization-tiny")
    assert suite.run_suite(args) == 0
    text = (tmp_path / "RESULTS.md").read_text()
    assert "<!-- BEGIN correspondence-generalization-tiny -->" in text
    assert f"<!-- BEGIN {suite.SECTION} -->" not in text
    assert "--limit 1 --section correspondence-generalization-tiny" in text


def test_sensitivity_run_writes_its_own_section_and_leaves_the_suite_table(tmp_path, monkeypatch):
    monkeypatch.setattr(suite, "sensitivity_variants",
                        lambda fields: [("n_refine 5 → 2 (×0.5)", {"n_refine": 2})] * ("n_refine" in fields))
    args = _tiny_suite_args(tmp_path, monkeypatch, sensitivity=True, fields="n_refine")
    assert suite.run_suite(args) == 0
    text = (tmp_path / "RESULTS.md").read_text()
    assert f"<!-- BEGIN {suite.SENSITIVITY_SECTION} -->" in text
    assert f"<!-- BEGIN {suite.SECTION} -->" not in text
    rows = [line for line in text.splitlines() if line.startswith(("| default", "| n_refine"))]
    assert len(rows) == 2 and all(float(r.split("|")[2].split("(")[0]) >= 0 for r in rows)
    cells = [r.split("|")[2].strip() for r in rows]
    # mean to 4 significant digits, failures in brackets
    assert all(re.fullmatch(r"\S+ \(\d+\)", c) for c in cells)
    assert all(f"{float(c.split()[0]):.4g}" == c.split()[0] for c in cells)
    assert "--fields n_refine" in text
    assert "sampling noise" not in text  # no --seeds: no seed rows


def test_sensitivity_with_seeds_adds_the_draws_and_their_range(tmp_path, monkeypatch):
    from geoshape.bench import correspondence  # the run imports evaluate_pairs from here
    from geoshape.correspondence import mesh_matching  # and evaluate_pairs imports correspond

    seen = []

    original = correspondence.evaluate_pairs

    def recording(*a, options=None, **kw):
        seen.append(dict(options or {}))
        return original(*a, options=options, **kw)

    seeds_used = []
    real_correspond = mesh_matching.correspond

    def correspond(*a, **kw):
        seeds_used.append(kw["seed"])
        return real_correspond(*a, **kw)

    monkeypatch.setattr(correspondence, "evaluate_pairs", recording)
    monkeypatch.setattr(mesh_matching, "correspond", correspond)
    args = _tiny_suite_args(tmp_path, monkeypatch, sensitivity=True, fields="none", seeds=2)
    assert suite.run_suite(args) == 0
    assert seen == [{}, {"seed": 1}, {"seed": 2}]
    assert seeds_used == [0, 1, 2]  # the method got each row's seed (the landmarks keep --seed 0)
    text = (tmp_path / "RESULTS.md").read_text()
    assert "--fields none --seeds 2" in text
    rows = [line for line in text.splitlines() if line.startswith("| ")][1:]  # below the header
    assert [r.split("|")[1].strip()[:12] for r in rows] == ["default", "seed 0 → 1 (", "seed 0 → 2 (",
                                                            "sampling noi"]


def test_a_misspelled_sensitivity_field_stops_the_command_before_any_generation(tmp_path, capsys):
    from geoshape.__main__ import main

    code = main(["bench", "correspondence", "--suite", "generalization", "--sensitivity",
                 "--fields", "screen_k,finalk", "--dev-dir", str(tmp_path), "--no-results"])
    assert code == 2
    assert "finalk" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # nothing generated


def test_candidate_report_lists_every_refined_candidate_and_marks_the_decision(tmp_path):
    from geoshape_datasets_gen.nonisometric import write_nonisometric_set

    from geoshape.bench.correspondence import candidate_report

    write_nonisometric_set(tmp_path / "tiny", n_pairs=2, seed=0, target_vertices=600, templates=1,
                           resolution=48)
    lines = []
    rows = candidate_report(tmp_path / "tiny", "pairs.csv", ["p01_"], landmarks=50, log=lines.append)
    assert rows and {r["pair"] for r in rows} == {rows[0]["pair"]} and rows[0]["pair"].startswith("p01_")
    assert sum(r["chosen"] for r in rows) == 1
    chosen = next(r for r in rows if r["chosen"])
    pool = [r for r in rows if r["wanted"]] or rows
    best = min(pool, key=lambda r: r["decision_score"])
    # the landmark solve's twins (repaired, polished) are decided by local rigidity
    twins = [r for r in pool if {r["source"], best["source"]} == {"repaired", "polished"}
             and None not in (r["rigidity"], best["rigidity"]) and r["rigidity"] < best["rigidity"]]
    assert chosen is (twins[0] if twins else best)
    assert all(0 <= r["error"] < 2 for r in rows)
    assert lines[0].startswith("== p01_") and len(lines) == 2 + len(rows)
    assert candidate_report(tmp_path / "tiny", "pairs.csv", ["no such pair"], landmarks=50) == []


def test_candidates_naming_no_pair_exits_2(tmp_path, capsys):
    from geoshape_datasets_gen.nonisometric import write_nonisometric_set

    from geoshape.__main__ import main

    write_nonisometric_set(tmp_path / "tiny", n_pairs=1, seed=0, target_vertices=600, templates=1,
                           resolution=48)
    assert main(["bench", "correspondence", str(tmp_path / "tiny"), "--candidates", "nothing-like-this"]) == 2
    assert "no pair name contains" in capsys.readouterr().err


def test_decision_weight_variants_halve_double_and_drop_each_exponent():
    from geoshape.correspondence.pipeline import DECISION_EXPONENTS

    variants = suite.decision_weight_variants()
    assert variants[0][1] == tuple(DECISION_EXPONENTS) and variants[0][0].startswith("default")
    n = len(DECISION_EXPONENTS)
    changed = [[i for i in range(n) if e[i] != DECISION_EXPONENTS[i]] for _, e in variants[1:]]
    assert all(len(c) == 1 for c in changed) and len(variants) == 1 + 3 * n
    for i in range(n):
        assert sorted(e[i] for _, e in variants[1:] if e[i] != DECISION_EXPONENTS[i]) == [
            0.0, 0.5 * DECISION_EXPONENTS[i], 2.0 * DECISION_EXPONENTS[i]]


def test_redecided_errors_follow_the_exponents():
    """A planted pool: a smooth but distorted map (low energy, half its surface mirrored) against
    a less distorted one; each exponent changed moves the decision as the product says, a
    mirrored map never wins while a wanted one is in the pool, and a pair on which the method
    raised counts as a failure."""
    from geoshape.bench.correspondence import CandidatePool
    from geoshape.correspondence.pipeline import Candidate

    def cand(distortion, energy, share, unwanted=False, curvature=0.1):
        return Candidate(refined_map=np.zeros(2, dtype=np.int64), refined_energy=energy,
                         distortion=distortion, refined_orientation=2 * share - 1,
                         unwanted=unwanted, orientation_share=share, curvature_disagreement=curvature)

    pool = CandidatePool("p", [cand(0.10, 0.030, 0.9), cand(0.20, 0.010, 0.5), cand(0.01, 0.001, 0.1, True)],
                         [0.02, 0.30, 0.40], [0.02, 0.30, 0.03], 0, 0.02, 0.02)
    assert suite.redecided_errors([pool], (1.0, 1.0, 1.0, 1.0)).tolist() == [0.02]  # 0.0033 < 0.004
    assert suite.redecided_errors([pool], (1.0, 1.0, 1.0, 0.0)).tolist() == [0.30]  # 0.002 < 0.003
    assert suite.redecided_errors([pool], (1.0, 1.0, 1.0, 2.0)).tolist() == [0.02]  # 0.0037 < 0.008
    assert suite.redecided_errors([pool], (1.0, 0.0, 1.0, 0.0)).tolist() == [0.02]  # distortion
    assert suite.redecided_errors([pool], (1.0, 2.0, 1.0, 0.0)).tolist() == [0.30]  # 2e-5 < 9e-5
    # the curvature exponent moves the decision when the candidates' curvatures differ
    bent = CandidatePool("b", [cand(0.10, 0.030, 0.9, curvature=0.2), cand(0.10, 0.036, 0.9, curvature=0.1)],
                         [0.30, 0.02], [0.30, 0.02], 1, 0.02, 0.02)
    assert suite.redecided_errors([bent], (1.0, 1.0, 1.0, 1.0)).tolist() == [0.02]  # 4.0e-4 < 6.7e-4
    assert suite.redecided_errors([bent], (1.0, 1.0, 0.0, 1.0)).tolist() == [0.30]  # 3.3e-3 < 4.0e-3
    assert suite.redecided_errors([bent], (1.0, 1.0, 0.5, 1.0)).tolist() == [0.02]
    crashed = CandidatePool("q", [], [], [], error="bad mesh")
    errors = suite.redecided_errors([pool, crashed], (1.0, 1.0, 1.0, 0.0))
    assert errors[0] == 0.30 and np.isnan(errors[1])
    assert suite.weights_cell(errors) == "0.3 (2)"  # one pair above 0.1, one that raised
    assert suite.weights_cell(np.array([np.nan])) == "— (1)"


def test_decision_weights_run_writes_its_own_section(tmp_path, monkeypatch):
    args = _tiny_suite_args(tmp_path, monkeypatch, decision_weights=True)
    assert suite.run_suite(args) == 0
    text = (tmp_path / "RESULTS.md").read_text()
    assert f"<!-- BEGIN {suite.DECISION_WEIGHTS_SECTION} -->" in text
    assert f"<!-- BEGIN {suite.SECTION} -->" not in text
    assert "retakes the pipeline's own choice on 1 of 1 pairs" in text
    rows = [line for line in text.splitlines() if line.startswith("| ") and "(" in line.split("|")[2]]
    assert len(rows) == 1 + 3 * 4 + 1 and rows[-1].startswith("| best candidate in the pool")


@pytest.mark.parametrize("flags, message", [
    (["--decision-weights"], "--decision-weights needs --suite"),
    (["--sensitivity"], "--sensitivity needs --suite"),
    (["--suite", "generalization", "--sensitivity", "--decision-weights"], "give one"),
    (["--suite", "generalization", "--decision-weights", "--candidates", "x"], "give one"),
])
def test_suite_only_flags_are_checked(flags, message, capsys):
    from geoshape.__main__ import main

    assert main(["bench", "correspondence", *flags, "--no-results"]) == 2
    assert message in capsys.readouterr().err
