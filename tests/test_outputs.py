"""Output paths checked before work, and all-or-nothing writes (geoshape.io.outputs, atomic)."""

from __future__ import annotations

import errno
import os

import numpy as np
import pytest

from geoshape.__main__ import main
from geoshape.errors import GeoshapeError, OutputError
from geoshape.io.atomic import save_npy_atomic, staged_outputs, write_text_atomic
from geoshape.io.outputs import check_output_path


@pytest.mark.parametrize(
    "kind, name, match",
    [
        ("picture", "p.xyz", "unsupported extension '.xyz'"),
        ("npy", "m.txt", "unsupported extension '.txt'"),
        ("mesh", "m.abc", "unsupported mesh extension"),
    ],
)
def test_unsupported_extensions_are_refused(tmp_path, kind, name, match):
    with pytest.raises(OutputError, match=match):
        check_output_path(tmp_path / name, kind, option="--x")


def test_missing_folder_file_parent_and_folder_path_are_refused(tmp_path):
    (tmp_path / "f").write_text("")
    with pytest.raises(OutputError, match="does not exist"):
        check_output_path(tmp_path / "no" / "a.png", "picture")
    with pytest.raises(OutputError, match="is not a folder"):
        check_output_path(tmp_path / "f" / "a.png", "picture")
    with pytest.raises(OutputError, match="is a folder"):
        check_output_path(tmp_path, "text")
    with pytest.raises(OutputError, match="not a folder"):
        check_output_path(tmp_path / "f", "folder")
    assert check_output_path(tmp_path / "new", "folder") == tmp_path / "new"
    assert issubclass(OutputError, GeoshapeError)


def test_staged_outputs_commit_together_or_not_at_all(tmp_path):
    (tmp_path / "old.txt").write_text("earlier")
    with pytest.raises(RuntimeError):
        with staged_outputs():
            write_text_atomic(tmp_path / "a.txt", "first")
            save_npy_atomic(tmp_path / "old.txt", np.zeros(3))  # would replace an earlier file
            assert not (tmp_path / "a.txt").exists()  # not visible before the block ends
            raise RuntimeError("the last output failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.txt"]
    assert (tmp_path / "old.txt").read_text() == "earlier"
    with staged_outputs():
        write_text_atomic(tmp_path / "a.txt", "first")
        write_text_atomic(tmp_path / "b.txt", "second")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt", "old.txt"]


def test_a_full_disk_becomes_an_output_error_and_leaves_nothing(tmp_path, monkeypatch):
    real_fsync = os.fsync

    def no_space(fd):  # a full disk shows when the data is flushed
        raise OSError(errno.ENOSPC, "No space left on device")

    with staged_outputs():
        write_text_atomic(tmp_path / "ok.txt", "kept")
    monkeypatch.setattr(os, "fsync", no_space)
    with pytest.raises(OutputError, match="no space left on the device"):
        with staged_outputs():
            write_text_atomic(tmp_path / "a.txt", "x" * 100)
    monkeypatch.setattr(os, "fsync", real_fsync)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.txt"]


def test_cli_checks_outputs_before_reading_inputs(tmp_path, capsys):
    # the inputs do not exist either: the output is checked first, with one line and exit 2
    code = main(
        ["match2d", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--plot", str(tmp_path / "p.xyz")]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--plot" in err[0] and ".xyz" in err[0]


@pytest.mark.parametrize("argv, option", [
    (["embed", "m.off", "-o", "e.ply", "--seed", "-1"], "--seed"),
    (["match2d", "a.png", "b.png", "--n-points", "100000"], "--n-points"),
    (["retrieval2d", "d", "--matrix", "m.npy", "--n-jobs", "0"], "--n-jobs"),
    (["retrieval3d", "d", "--descriptor", "d2", "--matrix", "m.npy", "--rerank-k", "0"], "--rerank-k"),
    (["index", "query", "db", "m.off", "--rerank-k", "-1"], "--rerank-k"),
    (["correspond", "a.off", "b.off", "-o", "m.txt", "--seed", "x"], "--seed"),
])
def test_numeric_options_are_range_checked_at_parse_time_in_one_line(argv, option, capsys):
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and option in err[0]


def test_help_states_the_limits(capsys):
    assert main(["embed", "--help"]) == 0
    assert "[0–4294967295]" in " ".join(capsys.readouterr().out.split())


def test_a_vanishing_gaussian_width_is_refused(tmp_path, capsys):
    import trimesh

    from geoshape.io.mesh_io import save_mesh

    m = trimesh.creation.icosphere(subdivisions=1)
    save_mesh(tmp_path / "m.off", m.vertices, m.faces)
    assert main(["embed", str(tmp_path / "m.off"), "-o", str(tmp_path / "e.ply"), "--sigma", "1e-300"]) == 2
    assert "sigma" in capsys.readouterr().err
    assert not (tmp_path / "e.ply").exists()


def test_help_states_the_image_and_width_limits_the_library_enforces(capsys, tmp_path):
    from PIL import Image

    from geoshape.io.silhouette import MAX_IMAGE_PIXELS
    from geoshape.spectral.affinity import MIN_SIGMA_FACTOR

    assert main(["match2d", "--help"]) == 0
    assert f"{MAX_IMAGE_PIXELS:,}" in " ".join(capsys.readouterr().out.split())
    assert main(["embed", "--help"]) == 0
    import re

    stated = re.search(r"RHO >= ([0-9.e+-]+)\)", " ".join(capsys.readouterr().out.split()))
    assert stated and float(stated.group(1)) == MIN_SIGMA_FACTOR
    side = int(MAX_IMAGE_PIXELS**0.5) + 1
    Image.new("L", (side, side)).save(tmp_path / "big.png")
    assert main(["match2d", str(tmp_path / "big.png"), str(tmp_path / "big.png")]) == 2
    assert "image too large" in capsys.readouterr().err


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
@pytest.mark.parametrize("staged", [False, True])
def test_sigterm_removes_the_temporary_a_worker_was_writing(tmp_path, staged):
    import signal
    import time

    from geoshape.io.atomic import atomic_path, leftover_temporaries
    from geoshape.parallel import remove_unfinished_files_on_sigterm

    dest = tmp_path / "map.txt"
    ready_r, ready_w = os.pipe()
    pid = os.fork()
    if pid == 0:  # a worker, terminated while its output is still a temporary
        try:
            remove_unfinished_files_on_sigterm()
            with staged_outputs() if staged else open(os.devnull) as _:
                with atomic_path(dest) as tmp:
                    tmp.write_text("half")
                    if not staged:
                        os.write(ready_w, b"x")
                        time.sleep(30)
                os.write(ready_w, b"x")  # staged: written, waiting for the block to commit
                time.sleep(30)
        finally:
            os._exit(1)
    os.read(ready_r, 1)
    assert leftover_temporaries(dest)  # the temporary exists while the worker writes
    os.kill(pid, signal.SIGTERM)
    _, status = os.waitpid(pid, 0)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGTERM  # it still dies of SIGTERM
    assert not leftover_temporaries(dest) and not dest.exists()


def test_unfinished_files_hold_a_temporary_only_until_it_is_renamed_or_removed(tmp_path):
    from geoshape.io.atomic import atomic_path
    from geoshape.parallel import UNFINISHED_FILES

    with atomic_path(tmp_path / "a.txt") as tmp:
        assert tmp in UNFINISHED_FILES
    with staged_outputs():
        write_text_atomic(tmp_path / "b.txt", "b")
        assert len(UNFINISHED_FILES) == 1  # staged: still a temporary until the block commits
    with pytest.raises(RuntimeError), staged_outputs():
        write_text_atomic(tmp_path / "c.txt", "c")
        raise RuntimeError("the next output failed")
    assert not UNFINISHED_FILES
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]
