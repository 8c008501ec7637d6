"""The index loses nothing and writes nowhere it should not: foreign databases, failed first
adds, concurrent adds, deleted files."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys

import pytest

from geoshape.errors import DatasetError
from geoshape.retrieval.index import ShapeIndex
from tests.test_index import _rows, _write_meshes


def test_a_foreign_sqlite_database_is_refused_and_left_untouched(tmp_path):
    db = tmp_path / "other.db"
    con = sqlite3.connect(db)
    con.execute("CREATE TABLE songs (title TEXT)")
    con.execute("INSERT INTO songs VALUES ('x')")
    con.commit()
    con.close()
    before = db.read_bytes()
    _write_meshes(tmp_path / "m", 2)
    with pytest.raises(DatasetError, match="not a geoshape index .*songs.*refusing"):
        ShapeIndex(db)
    assert db.read_bytes() == before
    assert not (tmp_path / "other.db-wal").exists()


def test_a_text_file_is_refused(tmp_path):
    db = tmp_path / "notes.db"
    db.write_text("not a database at all, just some notes\n" * 10)
    with pytest.raises(DatasetError, match="not a geoshape index"):
        ShapeIndex(db)


def test_a_first_add_that_stores_nothing_leaves_no_file(tmp_path):
    db = tmp_path / "new.db"
    with pytest.raises(DatasetError):
        with ShapeIndex(db) as idx:
            idx.add([tmp_path / "no-such-folder"], ["d2"], backend="serial")
    assert not db.exists() and not list(tmp_path.glob("new.db*"))
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "broken.off").write_text("OFF\n3 1 0\n0 0 0\n")
    done = subprocess.run([sys.executable, "-m", "geoshape", "index", "add", str(db), str(tmp_path / "bad"),
                           "--descriptor", "d2", "--backend", "serial"], capture_output=True, text=True)
    assert done.returncode == 1 and "broken.off" in done.stderr
    assert not list(tmp_path.glob("new.db*"))


def test_an_existing_index_survives_a_failed_add(tmp_path):
    _write_meshes(tmp_path / "m", 2)
    db = tmp_path / "idx.db"
    with ShapeIndex(db) as idx:
        idx.add([tmp_path / "m"], ["d2"], backend="serial")
    with pytest.raises(DatasetError), ShapeIndex(db) as idx:
        idx.add([tmp_path / "missing"], ["d2"], backend="serial")
    assert len(_rows(db)) == 2


@pytest.mark.slow
@pytest.mark.parametrize("descriptor", [["--descriptor", "shd"], []], ids=["shd", "default"])
def test_two_concurrent_adds_on_a_fresh_database_compute_each_row_once(tmp_path, descriptor):
    from geoshape.retrieval.index import DEFAULT_INDEX_DESCRIPTORS

    per = 1 if descriptor else len(DEFAULT_INDEX_DESCRIPTORS)  # rows per file
    _write_meshes(tmp_path / "m", 12)
    db = tmp_path / "fresh.db"
    cmd = [sys.executable, "-m", "geoshape", "index", "add", str(db), str(tmp_path / "m"),
           *descriptor, "--backend", "serial", "--batch-size", "2", "--json"]
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1] for o in outs]
    added = [json.loads(o[0])["added"] for o in outs]
    rows = _rows(db)
    assert len(rows) == 12 * per and len({r[0] for r in rows}) == 12
    assert sum(added) == 12 * per, added  # nothing computed twice


def test_deleted_files_are_never_returned_and_prune_removes_them(tmp_path):
    from geoshape.io.mesh_io import load_mesh

    paths = _write_meshes(tmp_path / "m", 4)
    db = tmp_path / "idx.db"
    with ShapeIndex(db) as idx:
        idx.add([tmp_path / "m"], ["d2"], backend="serial")
    V, F = load_mesh(paths[0])
    paths[0].unlink()
    with ShapeIndex(db) as idx:
        hits, _ = idx.query_mesh(V, F, "d2", top=4)
        assert str(paths[0].resolve()) not in [h.path for h in hits] and len(hits) == 3
        assert idx.prune() == [str(paths[0].resolve())]
        assert idx.count() == 3


@pytest.mark.slow
def test_racing_first_adds_never_delete_the_database(tmp_path):
    """Two adds of the same two files on a new database: whichever finds its files claimed by
    the other must not remove the file the other is writing (repeated to meet the race)."""
    paths = _write_meshes(tmp_path / "m", 2)
    for trial in range(4):
        db = tmp_path / f"race{trial}.db"
        cmd = [sys.executable, "-m", "geoshape", "index", "add", str(db), *map(str, paths),
               "--descriptor", "shd", "--backend", "serial"]
        procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                 for _ in range(2)]
        outs = [p.communicate(timeout=300) for p in procs]
        assert [p.returncode for p in procs] == [0, 0], [o[1] for o in outs]
        assert db.exists() and len(_rows(db)) == 2, f"trial {trial}: the database was lost"
