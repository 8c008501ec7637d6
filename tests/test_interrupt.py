"""Ctrl-C stops a batch within seconds with exit 130, keeps every finished file whole, leaves
no temporary, and no worker outlives the command."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import trimesh

from geoshape.io.mesh_io import save_mesh
from tests.test_index import _rows

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


def _batch_folder(folder, n_pairs: int = 12):
    rng = np.random.default_rng(0)
    m = trimesh.creation.icosphere(subdivisions=4)
    rows = []
    for i in range(n_pairs + 1):
        V = m.vertices * rng.uniform(0.8, 1.2, 3)
        save_mesh(folder / f"s{i}.off", V, m.faces)
    rows = [f"s{i}.off,s{i + 1}.off" for i in range(n_pairs)]
    (folder / "pairs.csv").write_text("source,target\n" + "\n".join(rows) + "\n")
    return len(m.vertices)


def default_sigint() -> None:
    """Give a child the default SIGINT disposition, as an interactive shell does: a test run
    started in the background (``cmd &``, some CI runners) inherits SIGINT *ignored*, and a
    command that inherits an ignored SIGINT rightly keeps ignoring it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(argv: list[str], quiet: bool = False) -> subprocess.Popen:
    """``geoshape ARGV`` in a new session (so a signal can go to its whole group, as a
    terminal's Ctrl-C does), with SIGINT at its default."""
    out = subprocess.DEVNULL if quiet else subprocess.PIPE
    return subprocess.Popen(
        [sys.executable, "-m", "geoshape", *argv], stdout=out, stderr=out, text=True, start_new_session=True,
        preexec_fn=default_sigint,
    )


def _tree(pid: int) -> set[int]:
    family = _children(pid)
    for child in list(family):
        family |= _children(child)
    return family


def _children(pid: int) -> set[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    return {int(x) for x in out.split()}


def _alive(pids) -> list[int]:
    """The processes of ``pids`` still running (a zombie waiting to be reaped is not)."""
    out = []
    for p in pids:
        try:
            with open(f"/proc/{p}/stat") as fh:
                if fh.read().rsplit(")", 1)[1].split()[0] != "Z":
                    out.append(p)
        except OSError:
            pass
    return out


@pytest.mark.slow
def test_ctrl_c_stops_correspond_batch_within_seconds(tmp_path):
    n = _batch_folder(tmp_path)
    out = tmp_path / "maps"
    proc = _start(["correspond-batch", str(tmp_path), "--out-dir", str(out), "--jobs", "2"])
    deadline = time.time() + 120
    while time.time() < deadline and not (out.is_dir() and any(out.glob("*.txt"))):
        time.sleep(0.1)
    assert proc.poll() is None, "the batch ended before it could be interrupted"
    family = _children(proc.pid)
    for child in list(family):
        family |= _children(child)
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
    _, err = proc.communicate(timeout=60)  # a hang fails here
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == ["geoshape correspond-batch: interrupted"], err
    maps = list(out.glob("*.txt"))
    assert 0 < len(maps) < 12, "it stopped early, after some maps"
    assert not list(out.glob(".*")), "temporaries left behind"
    for f in maps:
        assert len(f.read_text().splitlines()) == n  # finished maps are whole
    deadline = time.time() + 10
    while time.time() < deadline and _alive(family):
        time.sleep(0.2)
    assert not _alive(family), f"workers still running: {_alive(family)}"


@pytest.mark.slow
def test_workers_die_with_a_killed_command(tmp_path):
    _batch_folder(tmp_path)
    proc = _start(
        ["correspond-batch", str(tmp_path), "--out-dir", str(tmp_path / "maps"), "--jobs", "2"], quiet=True
    )
    deadline = time.time() + 120
    family: set[int] = set()
    while time.time() < deadline and len(family) < 3:  # the command's child and its workers
        family = _children(proc.pid)
        for child in list(family):
            family |= _children(child)
        time.sleep(0.2)
    proc.kill()
    proc.wait()
    time.sleep(2.0)
    alive = [
        p
        for p in family
        if os.path.exists(f"/proc/{p}") and open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
    ]
    assert not alive, f"processes outlived the killed command: {alive}"


def _mesh_folder(folder, n: int = 40):
    rng = np.random.default_rng(1)
    folder.mkdir()
    m = trimesh.creation.icosphere(subdivisions=4)
    rows = []
    for i in range(n):
        save_mesh(folder / f"m{i:02d}.off", m.vertices * rng.uniform(0.5, 1.5, 3), m.faces)
        rows.append(f"m{i:02d}.off,{'a' if i % 2 else 'b'}")
    (folder / "labels.csv").write_text("file,label\n" + "\n".join(rows) + "\n")


@pytest.mark.slow
@pytest.mark.parametrize("command", ["index add", "retrieval3d", "retrieval2d"])
def test_ctrl_c_stops_descriptor_batches_and_index_add_resumes(tmp_path, command):
    db, matrix = tmp_path / "idx.db", tmp_path / "D.npy"
    if command == "retrieval2d":
        from geoshape_datasets_gen.silhouettes2d import generate_silhouettes

        generate_silhouettes(tmp_path / "s", per_class=25, seed=0)  # 150 shapes, ~11k pairs
        argv = ["retrieval2d", str(tmp_path / "s"), "--matrix", str(matrix), "--n-jobs", "2"]
    else:
        _mesh_folder(tmp_path / "m")
        argv = {"index add": ["index", "add", str(db), str(tmp_path / "m"), "--batch-size", "4"],
                "retrieval3d": ["retrieval3d", str(tmp_path / "m"), "--matrix", str(matrix)]}[command]
        argv += ["--descriptor", "shd", "--jobs", "2"]
    proc = _start(argv)
    deadline = time.time() + 120  # wait for real progress: rows stored, or workers busy
    while time.time() < deadline and proc.poll() is None:
        if (db.exists() and len(_rows(db)) >= 2) if command == "index add" else len(_tree(proc.pid)) >= 3:
            break
        time.sleep(0.1)
    time.sleep(0.5)
    assert proc.poll() is None, "finished before it could be interrupted"
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)  # a hang fails here
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1].endswith(": interrupted") and "Traceback" not in err, err
    assert "leaked" not in err, err
    assert not matrix.exists() and not list(tmp_path.glob(".*tmp*"))
    if command == "index add":  # resumable: a second run completes, nothing twice
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "geoshape",
                "index",
                "add",
                str(db),
                str(tmp_path / "m"),
                "--descriptor",
                "shd",
                "--jobs",
                "2",
                "--json",
            ],
            capture_output=True,
            text=True,
        )
        assert done.returncode == 0, done.stderr
        import json

        summary = json.loads(done.stdout)
        assert summary["rows_in_index"] == 40
        assert summary["added"] + summary["skipped_unchanged"] == 40
