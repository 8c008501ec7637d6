"""The persistent shape index: resume after a kill, bad files, backends, queries."""

from __future__ import annotations

import json
import signal
import sqlite3
import subprocess
import sys
import time

import numpy as np
import pytest

from geoshape.retrieval.descriptors import descriptor_params
from geoshape.retrieval.index import ShapeIndex


def _write_meshes(folder, n: int, seed: int = 0):
    """``n`` small closed meshes (randomly stretched icospheres and capsules)."""
    import trimesh

    from geoshape.io.mesh_io import save_mesh

    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k in range(n):
        m = trimesh.creation.icosphere(2) if k % 2 == 0 else trimesh.creation.capsule(1.0, 0.4)
        V = np.asarray(m.vertices) * rng.uniform(0.5, 2.0, size=3)
        p = folder / f"shape{k:02d}.off"
        save_mesh(p, V, np.asarray(m.faces))
        paths.append(p)
    return paths


def _rows(db):
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=30)
    try:
        return con.execute("SELECT path, descriptor, added FROM entries").fetchall()
    except sqlite3.OperationalError:  # table not created yet
        return []
    finally:
        con.close()


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "geoshape", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize("descriptor", [["--descriptor", "shd"], []], ids=["shd", "default"])
def test_resume_after_kill_loses_and_duplicates_nothing(tmp_path, descriptor):
    """Also with the default descriptors (the fused method's components, computed together
    per file): whole files per batch, nothing lost or computed twice."""
    from collections import Counter

    from geoshape.retrieval.index import DEFAULT_INDEX_DESCRIPTORS

    per = 1 if descriptor else len(DEFAULT_INDEX_DESCRIPTORS)  # rows per file
    paths = _write_meshes(tmp_path / "meshes", 20)
    db = tmp_path / "idx.db"
    cmd = [sys.executable, "-m", "geoshape", "index", "add", str(db), str(tmp_path / "meshes"),
           *descriptor, "--jobs", "1", "--batch-size", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    seen = []
    deadline = time.time() + 120
    try:
        while time.time() < deadline:
            if db.exists():
                n = len(_rows(db))
                seen.append(n)
                if n >= 2 * per:
                    break
            if proc.poll() is not None:
                break
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    first = _rows(db)
    assert 2 * per <= len(first) < 20 * per, f"kill came too late or too early: {len(first)} rows"
    # a concurrent reader only ever saw whole batches (2 files each, all their descriptors)
    assert all(n % (2 * per) == 0 for n in seen), seen
    r = _cli("index", "add", db, tmp_path / "meshes", *descriptor, "--jobs", "1",
             "--batch-size", "4", "--json")
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary["skipped_unchanged"] == len(first)
    assert summary["added"] == 20 * per - len(first)
    rows = _rows(db)
    count = Counter(p for p, _, _ in rows)
    assert sorted(count) == sorted(str(p.resolve()) for p in paths)  # every file
    assert set(count.values()) == {per}  # each descriptor once
    before = {(p, d): t for p, d, t in first}
    assert all(before[(p, d)] == t for p, d, t in rows if (p, d) in before)  # not recomputed


def test_bad_and_unsupported_files_are_reported_and_skipped(tmp_path):
    _write_meshes(tmp_path / "m", 3)
    (tmp_path / "m" / "corrupt.off").write_text("OFF\n4 2 0\n0 0 0\n1 0 0\nnot numbers\n")
    odd = tmp_path / "cloud.xyz"
    odd.write_text("0 0 0\n")
    db = tmp_path / "idx.db"
    r = _cli("index", "add", db, tmp_path / "m", odd, "--descriptor", "d2", "--jobs", "1")
    assert r.returncode == 1
    assert "corrupt.off" in r.stderr and "cloud.xyz" in r.stderr
    assert "Traceback" not in r.stderr
    assert "3 descriptors added" in r.stdout and "2 files failed" in r.stdout
    assert len(_rows(db)) == 3


def test_changed_file_is_redescribed(tmp_path):
    from geoshape.io.mesh_io import load_mesh, save_mesh

    paths = _write_meshes(tmp_path / "m", 2)
    with ShapeIndex(tmp_path / "i.db") as idx:
        assert idx.add([tmp_path / "m"], ["d2"], backend="serial").added == 2
        V, F = load_mesh(paths[0])
        save_mesh(paths[0], V * [1.0, 3.0, 1.0], F)
        rep = idx.add([tmp_path / "m"], ["d2"], backend="serial")
        assert (rep.added, rep.skipped) == (1, 1)
        assert idx.count() == 2


@pytest.mark.slow
def test_dask_and_processes_give_identical_descriptors(tmp_path):
    pytest.importorskip("distributed")
    _write_meshes(tmp_path / "m", 4)
    stores = {}
    for backend in ("processes", "dask"):
        with ShapeIndex(tmp_path / f"{backend}.db") as idx:
            rep = idx.add([tmp_path / "m"], ["evd", "d2"], backend=backend, n_jobs=2)
            assert rep.added == 8 and not rep.failed
            stores[backend] = {d: idx.load(d, descriptor_params(d, "geodesic" if d == "evd" else None))
                               for d in ("evd", "d2")}
    for d in ("evd", "d2"):
        pa, Xa = stores["processes"][d]
        pb, Xb = stores["dask"][d]
        assert pa == pb
        assert np.array_equal(Xa, Xb)


@pytest.mark.slow
def test_query_finds_itself_and_reranks(tmp_path):
    from geoshape.io.mesh_io import load_mesh

    paths = _write_meshes(tmp_path / "m", 6)
    with ShapeIndex(tmp_path / "i.db") as idx:
        idx.add([tmp_path / "m"], ["evd", "ccd"], backend="serial")
        V, F = load_mesh(paths[2])
        hits, timing = idx.query_mesh(V, F, "evd", top=3)
        assert hits[0].path == str(paths[2].resolve()) and hits[0].distance < 1e-9
        assert [h.rank for h in hits] == [1, 2, 3]
        hits, _ = idx.query_mesh(V, F, "evd", top=3, rerank="ccd")
        assert hits[0].path == str(paths[2].resolve())
        assert all(h.first_distance is not None for h in hits)
    r = _cli("index", "query", tmp_path / "i.db", paths[2], "--descriptor", "evd", "--top", "2", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert len(out["results"]) == 2 and out["results"][0]["rank"] == 1
    # the default (fused) needs its components, which this index does not hold: named error
    r = _cli("index", "query", tmp_path / "i.db", paths[2])
    assert r.returncode == 2 and "fused" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.slow
def test_default_index_stores_and_ranks_by_the_fused_method(tmp_path):
    """``index add`` without descriptors stores the fused default's components; ``query``
    without one ranks by their fusion (the all-pairs fused row, up to symmetrisation)."""
    from geoshape.io.mesh_io import load_mesh
    from geoshape.retrieval.fusion import FUSED_WEIGHTS
    from geoshape.retrieval.index import DEFAULT_INDEX_DESCRIPTORS, DEFAULT_QUERY_METHOD
    from geoshape.retrieval.meshes import retrieval3d_matrix

    assert DEFAULT_QUERY_METHOD == "fused"
    assert set(DEFAULT_INDEX_DESCRIPTORS) == {n for n, w in FUSED_WEIGHTS.items() if w > 0}
    paths = _write_meshes(tmp_path / "m", 6)
    db = tmp_path / "i.db"
    r = _cli("index", "add", db, tmp_path / "m", "--jobs", "1", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["added"] == 6 * len(DEFAULT_INDEX_DESCRIPTORS)
    with ShapeIndex(db) as idx:
        assert {s["descriptor"] for s in idx.summary()} == set(DEFAULT_INDEX_DESCRIPTORS)
        V, F = load_mesh(paths[2])
        hits, _ = idx.query_mesh(V, F, top=6)
        assert hits[0].path == str(paths[2].resolve()) and hits[0].distance < 1e-9
        reranked, _ = idx.query_mesh(V, F, top=3, rerank="lcdp")
        assert reranked[0].path == str(paths[2].resolve()) and len(reranked) == 3
    # same neighbours, in the same order, as the query's row of the fused all-pairs matrix
    order = [str(p.resolve()) for p in sorted(paths)]
    D = retrieval3d_matrix(order, "fused", backend="serial", progress=False)["D"]
    row = D[order.index(str(paths[2].resolve()))]
    assert [h.path for h in hits][:2] == [order[i] for i in np.argsort(row, kind="stable")[:2]]
    r = _cli("index", "query", db, paths[2], "--top", "2", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["descriptor"] == "fused" and out["results"][0]["path"] == str(paths[2].resolve())


def test_query_over_10000_rows_ranks_by_distance(tmp_path):
    """Query speed is measured by the benchmarks, not here; this checks the answer."""
    rng = np.random.default_rng(1)
    X = np.sort(rng.random((10000, 20)), axis=1)[:, ::-1]
    from geoshape.retrieval.descriptors import descriptor_distances, descriptor_params, params_key

    pk = params_key(descriptor_params("evd"))
    with ShapeIndex(tmp_path / "big.db") as idx:
        idx.insert_rows((f"/synthetic/{k}.off", "evd", pk, "0" * 64, X[k], 0.0)
                        for k in range(len(X)))
        first = idx.query_descriptor(X[5], "evd", top=10)  # loads and caches
        hits = idx.query_descriptor(X[5], "evd", top=10)  # served from the cache: same answer
    assert [(h.path, h.distance) for h in hits] == [(h.path, h.distance) for h in first]
    assert hits[0].path == "/synthetic/5.off"
    assert len(hits) == 10 and all(a.distance <= b.distance for a, b in zip(hits, hits[1:], strict=False))
    d = descriptor_distances("evd", [X[5]], X)[0]  # brute force: the 10 nearest rows, in order
    assert [h.path for h in hits] == [f"/synthetic/{k}.off" for k in np.lexsort((np.arange(len(d)), d))[:10]]


def test_missing_index_and_bad_descriptor(tmp_path):
    r = _cli("index", "query", tmp_path / "none.db", tmp_path / "x.off")
    assert r.returncode == 2 and "no such index" in r.stderr
    r = _cli("index", "add", tmp_path / "a.db", tmp_path, "--descriptor", "bogus")
    assert r.returncode == 2 and "descriptor must be one of" in r.stderr
