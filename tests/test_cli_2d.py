"""The 2D command-line contract: match2d, retrieval2d (atomic, clean failure), bench, demo."""

from __future__ import annotations

import json

import numpy as np
import pytest
from geoshape_datasets_gen.silhouettes2d import generate_silhouettes

from geoshape.__main__ import main


@pytest.fixture(scope="module")
def silhouettes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sil")
    generate_silhouettes(folder, per_class=2, classes=("person", "star", "snake"), seed=0)
    return folder


def test_match2d_writes_pairs_and_plot(silhouettes, tmp_path, capsys):
    out, fig = tmp_path / "pairs.csv", tmp_path / "fig.png"
    code = main(["match2d", str(silhouettes / "person_0.png"), str(silhouettes / "person_1.png"),
                 "--method", "gsc", "--out", str(out), "--plot", str(fig)])
    assert code == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "a_index,b_index,a_x,a_y,b_x,b_y" and len(lines) == 101
    assert fig.stat().st_size > 1000
    assert "cost" in capsys.readouterr().out


def test_each_method_traces_contours_its_own_way(silhouettes, tmp_path):
    """default matches 144 smoothed points, gsc 100 raw ones; --n-points overrides the count only."""
    from geoshape.contour.methods import contour_tracing
    from geoshape.contour.retrieval import retrieval_on_folder, shape_distance_matrix
    from geoshape.geometry.contour import contour_from_image

    a, b = str(silhouettes / "person_0.png"), str(silhouettes / "star_0.png")
    cases = (("default", [], 144), ("gsc", [], 100), ("default", ["--n-points", "64"], 64))
    for method, extra, rows in cases:
        out = tmp_path / f"{method}{len(extra)}.csv"
        assert main(["match2d", a, b, "--method", method, "--out", str(out), *extra]) == 0
        assert len(out.read_text().splitlines()) == rows + 1
    tracing = contour_tracing("default")
    assert tracing["smoothing"] > 0 and contour_tracing("gsc")["smoothing"] == 0
    by_folder = retrieval_on_folder(silhouettes, "default", backend="serial")
    contours = [contour_from_image(silhouettes / name, **tracing) for name in by_folder["files"]]
    assert np.allclose(by_folder["D"], shape_distance_matrix(contours, "default", backend="serial"))


def test_match2d_bad_method_and_bad_image(silhouettes, tmp_path, capsys):
    assert main(["match2d", str(silhouettes / "person_0.png"), str(silhouettes / "star_0.png"),
                 "--method", "nope"]) == 2
    assert "method must be one of" in capsys.readouterr().err
    blank = tmp_path / "blank.png"
    from PIL import Image

    Image.fromarray(np.zeros((20, 20), np.uint8)).save(blank)
    assert main(["match2d", str(blank), str(silhouettes / "star_0.png")]) == 2
    assert "blank.png" in capsys.readouterr().err


def test_retrieval2d_outputs(silhouettes, tmp_path):
    matrix, js, fig = tmp_path / "D.npy", tmp_path / "m.json", tmp_path / "D.png"
    code = main(["retrieval2d", str(silhouettes), "--method", "gsc", "--matrix", str(matrix),
                 "--json", str(js), "--plot", str(fig), "--backend", "serial"])
    assert code == 0
    D = np.load(matrix)
    assert D.shape == (6, 6) and np.allclose(D, D.T)
    report = json.loads(js.read_text())
    assert report["files"][0] == "person_0.png" and len(report["top_k_counts"]) == 5
    assert {"bulls_eye", "map", "seconds", "top_k_total"} <= set(report)
    assert fig.stat().st_size > 1000


def test_retrieval2d_bad_file_stops_cleanly(silhouettes, tmp_path, capsys):
    import shutil

    folder = tmp_path / "set"
    shutil.copytree(silhouettes, folder)
    (folder / "star_1.png").write_bytes(b"garbage")
    matrix = tmp_path / "D.npy"
    assert main(["retrieval2d", str(folder), "--matrix", str(matrix), "--backend", "serial"]) == 2
    assert "star_1.png" in capsys.readouterr().err
    assert not matrix.exists()
    (folder / "star_1.png").unlink()
    assert main(["retrieval2d", str(folder), "--matrix", str(matrix), "--backend", "serial"]) == 2
    assert "star_1.png" in capsys.readouterr().err
    assert not matrix.exists() and not list(tmp_path.glob(".D.npy*"))


def test_bench_lists_2d_benchmarks(capsys):
    assert main(["bench", "--help"]) == 0
    out = capsys.readouterr().out
    assert "kimia99" in out and "tari1000" in out


@pytest.mark.slow
def test_demo_runs(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--per-class", "2", "--method", "gsc"]) == 0
    for name in ("match2d.png", "retrieval_matrix.png", "metrics.md", "metrics.json",
                 "silhouettes/labels.csv", "correspondence3d.png", "correspondence3d_map.txt"):
        assert (tmp_path / name).is_file()
    assert "bull's-eye" in capsys.readouterr().out
    summary = json.loads((tmp_path / "metrics.json").read_text())["correspondence3d"]
    # two poses of one generated biped: the map keeps left and right (not the mirror image,
    # which would reverse the orientation of the mapped triangles) and lands on the truth
    # (before the distortion tie-break it chose a map 0.09 diagonals off, as isometric as it)
    assert summary["orientation"] > 0
    assert summary["median_error"] < 0.02


def test_a_path_the_system_refuses_is_one_line_and_exit_2(tmp_path, capsys):
    """A folder name longer than the file system allows (OSError, not a GeoshapeError) stops
    the command with one line naming it, not a traceback."""
    too_long = str(tmp_path / ("x" * 300))
    matrix = tmp_path / "D.npy"
    assert main(["retrieval2d", too_long, "--matrix", str(matrix), "--backend", "serial"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("geoshape retrieval2d: error: ") and "x" * 300 in err[0]
    assert "File name too long" in err[0] and not matrix.exists()


def test_an_argument_too_long_for_a_path_is_not_taken_for_one(tmp_path, capfd):
    """The isolated command line looks for input files among the arguments; a long method
    list is not a path and must not stop it with a traceback."""
    from geoshape.cli.isolation import can_isolate

    if not can_isolate():
        pytest.skip("needs fork (POSIX)")
    methods = "default," + "x" * 300
    status = main(["bench", "mirror2d", "--matrix-dir", str(tmp_path), "--methods", methods, "--no-write"],
                  isolate=True)
    assert status == 2 and "method must be one of" in capfd.readouterr().err  # the child's stderr
