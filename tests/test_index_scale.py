"""The index at scale: sidecar search (exact and IVF) against the all-pairs matrix, the
sidecar kept consistent with SQLite under add / prune / other writers, the stored
k-nearest-neighbour graph, diffusion re-ranking (``--rerank lcdp``)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from geoshape.errors import InvalidOptionError
from geoshape.retrieval.ann import GRAPH_K, VectorSet, pair_distances, path_hashes
from geoshape.retrieval.descriptors import descriptor_distance_matrix, descriptor_params, params_key
from geoshape.retrieval.index import ShapeIndex
from tests.test_index import _write_meshes


def _clustered(n: int, d: int, seed: int = 0, clusters: int = 12) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = np.sort(rng.gamma(2.0, 1.0, (clusters, d)), axis=1)[:, ::-1]
    return centres[rng.integers(0, clusters, n)] * np.exp(0.1 * rng.standard_normal((n, d)))


def _fill(idx: ShapeIndex, descriptor: str, X: np.ndarray, names) -> None:
    pk = params_key(descriptor_params(descriptor))
    idx.insert_rows((p, descriptor, pk, "0" * 64, x, 0.0) for p, x in zip(names, X, strict=True))


def _expected_top(D_row: np.ndarray, names: list[str], k: int) -> list[str]:
    """Top k of one all-pairs row, ties by path (as the index orders them)."""
    return [names[j] for j in sorted(range(len(names)), key=lambda j: (D_row[j], names[j]))[:k]]


@pytest.mark.parametrize("descriptor", ["evd", "shapedna", "gsv"])  # chi2, l2, l1
@pytest.mark.parametrize("search", ["auto", "brute", "ivf", "memory"])
def test_top10_equals_the_all_pairs_matrix(tmp_path, descriptor, search):
    X = _clustered(300, 20, seed=3)
    X[7] = X[11]  # a duplicate: a tie broken by path
    names = [f"/synthetic/{k:03d}.off" for k in range(len(X))]
    D = descriptor_distance_matrix(descriptor, list(X))
    with ShapeIndex(tmp_path / "i.db", search=search) as idx:
        _fill(idx, descriptor, X, names)
        for i in (0, 7, 11, 42, 299):
            hits = idx.query_descriptor(X[i], descriptor, top=10)
            assert [h.path for h in hits] == _expected_top(D[i], names, 10), (search, i)
            # (the in-memory L2 is the Gram trick: about 1e-7 where the distance is 0)
            assert np.allclose([h.distance for h in hits], np.sort(D[i])[:10], rtol=1e-9, atol=1e-6)
        assert (idx.vector_set(descriptor) is None) == (search == "memory")


def test_forced_ivf_with_few_lists_scanned_is_approximate_but_exactly_scored(tmp_path):
    X = _clustered(4000, 20, seed=5, clusters=40)
    names = [f"/s/{k:04d}.off" for k in range(len(X))]
    rng = np.random.default_rng(1)
    queries = X[rng.choice(len(X), 25, replace=False)] * np.exp(0.02 * rng.standard_normal((25, 20)))
    with ShapeIndex(tmp_path / "i.db", search="ivf", nprobe=8, min_scan=0) as idx:
        _fill(idx, "evd", X, names)
        vs = idx.vector_set("evd")
        assert vs.nlist > 8  # the IVF really skips lists
        recall = []
        for q in queries:
            hits = idx.query_descriptor(q, "evd", top=10)
            exact = pair_distances("chi2", q, X)
            truth = set(_expected_top(exact, names, 10))
            recall.append(len(truth & {h.path for h in hits}) / 10)
            for h in hits:  # whatever was found is scored with the descriptor's own distance
                assert h.distance == pytest.approx(exact[names.index(h.path)], rel=1e-12)
    assert np.mean(recall) >= 0.9, recall


def _graph(vs: VectorSet) -> dict[str, list[str]]:
    return {vs.path(i): [vs.path(j) for j in vs.nbr[i] if j >= 0] for i in range(vs.n)}


def _graph_from_scratch(names, X, metric="chi2") -> dict[str, list[str]]:
    """Each row's GRAPH_K nearest other rows over all pairs, ties by path hash."""
    h = path_hashes(names)
    out = {}
    for i in range(len(X)):
        order = np.lexsort((h, pair_distances(metric, X[i], X)))
        out[names[i]] = [names[j] for j in order if j != i][:GRAPH_K]
    return out


def test_knn_graph_pruned_by_ivf_lists_equals_the_all_pairs_one(monkeypatch):
    from geoshape.retrieval import ann

    X = _clustered(2500, 20, seed=13, clusters=25)
    X[3] = X[4]
    names = [f"/s/{k:04d}.off" for k in range(len(X))]
    meta = {"index_id": "t", "descriptor": "evd", "params": "{}", "version": 0, "metric": "chi2",
            "shape": [20]}
    vs = VectorSet.build(meta, names, X)
    assert vs.nlist > 1
    monkeypatch.setattr(ann, "GRAPH_IVF_MIN", 0)
    vs.build_graph()
    assert _graph(vs) == _graph_from_scratch(names, X)


def test_knn_graph_after_incremental_changes_equals_the_one_built_from_scratch(tmp_path):
    X = _clustered(500, 20, seed=7)
    X[3] = X[4] = X[5]  # ties at distance 0
    names = [f"/s/{k:03d}.off" for k in range(len(X))]
    db = tmp_path / "g.db"
    with ShapeIndex(db) as idx:
        _fill(idx, "evd", X[:200], names[:200])
        assert _graph(idx.vector_set("evd", graph=True)) == _graph_from_scratch(names[:200], X[:200])
        _fill(idx, "evd", X[200:350], names[200:350])  # added rows
        with ShapeIndex(db) as other:  # another writer: deletes and a changed row
            with other._writing() as conn:
                conn.executemany("DELETE FROM entries WHERE path = ?",
                                 [(names[k],) for k in range(0, 350, 9)])
            X2 = X.copy()
            X2[10] *= 1.5
            _fill(other, "evd", X2[10:11], names[10:11])
        vs = idx.vector_set("evd")
        assert vs.has_graph  # kept once built
        live = [k for k in range(350) if k % 9]
        assert _graph(vs) == _graph_from_scratch([names[k] for k in live], X2[live])
        _fill(idx, "evd", X[350:], names[350:])
        live += list(range(350, 500))
        assert _graph(idx.vector_set("evd")) == _graph_from_scratch([names[k] for k in live], X2[live])
    with ShapeIndex(db) as idx:  # persisted: read back from the sidecar
        vs = idx.vector_set("evd")
        assert vs.has_graph and _graph(vs) == _graph_from_scratch([names[k] for k in live], X2[live])


def test_sidecar_follows_add_prune_and_other_writers(tmp_path):
    from geoshape.io.mesh_io import load_mesh

    paths = _write_meshes(tmp_path / "m", 8)
    db = tmp_path / "idx.db"
    with ShapeIndex(db) as idx:
        idx.add(paths[:5], ["d2"], backend="serial")
        V, F = load_mesh(paths[6])
        first, _ = idx.query_mesh(V, F, "d2", top=8)
        assert len(first) == 5
        sidecar = idx._sidecar_path("d2", params_key(descriptor_params("d2")))
        v1 = VectorSet.load(sidecar).version
        idx.add(paths, ["d2"], backend="serial")
        assert VectorSet.load(sidecar).version > v1  # refreshed by add
        hits, _ = idx.query_mesh(V, F, "d2", top=8)
        assert hits[0].path == str(paths[6].resolve()) and hits[0].distance < 1e-12
        with ShapeIndex(db, search="memory") as ref:
            expect, _ = ref.query_mesh(V, F, "d2", top=8)
        assert [(h.path, h.distance) for h in hits] == [(h.path, h.distance) for h in expect]
        # the log is trimmed up to the saved version
        assert idx._conn.execute("SELECT COUNT(*) FROM changes").fetchone()[0] == 0
        paths[1].unlink()
        paths[2].unlink()
        assert sorted(idx.prune()) == sorted(str(p.resolve()) for p in paths[1:3])
        hits, _ = idx.query_mesh(V, F, "d2", top=8, skip_missing=False)
        assert len(hits) == 6 and not {str(p.resolve()) for p in paths[1:3]} & {h.path for h in hits}
        assert VectorSet.load(sidecar).n == 6
    # a sidecar that is not whole is never trusted: rebuilt from SQLite
    sidecar.write_bytes(sidecar.read_bytes()[:200])
    with ShapeIndex(db) as idx:
        again, _ = idx.query_mesh(V, F, "d2", top=8, skip_missing=False)
    assert [h.path for h in again] == [h.path for h in hits]
    assert VectorSet.load(sidecar).n == 6
    # nor one of another index with the same name
    other = tmp_path / "other.db"
    with ShapeIndex(other) as idx:
        idx.add(paths[6:7], ["d2"], backend="serial")
    (tmp_path / "other.db.ann").mkdir(exist_ok=True)
    (tmp_path / "other.db.ann" / sidecar.name).write_bytes(sidecar.read_bytes())
    with ShapeIndex(other) as idx:
        assert [h.path for h in idx.query_mesh(V, F, "d2", top=8)[0]] == [str(paths[6].resolve())]


def test_stale_in_memory_sidecar_is_brought_up_to_date(tmp_path):
    X = _clustered(120, 20, seed=9)
    names = [f"/s/{k:03d}.off" for k in range(len(X))]
    db = tmp_path / "w.db"
    with ShapeIndex(db) as reader, ShapeIndex(db) as writer:
        _fill(writer, "evd", X[:100], names[:100])
        assert reader.query_descriptor(X[110], "evd", top=1)[0].path != names[110]
        _fill(writer, "evd", X[100:], names[100:])
        assert reader.query_descriptor(X[110], "evd", top=1)[0].path == names[110]
        with writer._writing() as conn:
            conn.execute("DELETE FROM entries WHERE path = ?", (names[110],))
        assert reader.query_descriptor(X[110], "evd", top=1)[0].path != names[110]


def test_lcdp_over_the_graph_matches_the_in_memory_diffusion_on_a_small_collection(tmp_path):
    X = _clustered(40, 20, seed=11, clusters=3)
    names = [f"/s/{k:02d}.off" for k in range(len(X))]
    q = X[5] * 1.01
    out = {}
    for search in ("brute", "memory"):
        with ShapeIndex(tmp_path / "d.db", search=search) as idx:
            if search == "brute":
                _fill(idx, "evd", X, names)
            out[search] = idx.query_descriptor(q, "evd", top=10, rerank="lcdp", rerank_k=40)
    assert [h.path for h in out["brute"]] == [h.path for h in out["memory"]]
    assert np.allclose([h.distance for h in out["brute"]], [h.distance for h in out["memory"]])
    assert all(h.first_distance is not None and 0.0 <= h.distance <= 1.0 for h in out["brute"])
    with ShapeIndex(tmp_path / "d.db") as idx, pytest.raises(InvalidOptionError, match="lcdp"):
        idx.query_descriptor(q, "evd", rerank="diffusion")


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "geoshape", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def test_cli_rerank_lcdp_and_a_bad_rerank_name(tmp_path):
    paths = _write_meshes(tmp_path / "m", 6)
    db = tmp_path / "i.db"
    r = _cli("index", "add", db, tmp_path / "m", "--descriptor", "d2", "--backend", "serial")
    assert r.returncode == 0, r.stderr
    r = _cli("index", "query", db, paths[2], "--descriptor", "d2", "--rerank", "lcdp", "--top", "4", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["rerank"] == "lcdp" and len(out["results"]) == 4
    assert out["results"][0]["path"] == str(paths[2].resolve())
    assert all("first_distance" in h for h in out["results"])
    r = _cli("index", "query", db, paths[2], "--descriptor", "d2", "--rerank", "bogus")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "'lcdp'" in r.stderr and "'ccd'" in r.stderr and "bogus" in r.stderr
    r = _cli("index", "query", db, paths[2], "--descriptor", "d2", "--search", "ivf", "--top", "2")
    assert r.returncode == 0, r.stderr


def _fused_rows(n: int, seed: int = 0, clusters: int = 10) -> dict[str, np.ndarray]:
    """Clustered synthetic rows for the fused method's five components (short pcavox grids,
    8³ cells; spreads near-degenerate in some clusters)."""
    rng = np.random.default_rng(seed)
    which = rng.integers(0, clusters, n)
    out = {}
    for c, d in (("evd_heat", 20), ("shapedna", 20), ("shd", 32), ("wks", 16)):
        centres = rng.gamma(2.0, 1.0, (clusters, d))
        out[c] = centres[which] * np.exp(0.1 * rng.standard_normal((n, d)))
    G = np.abs(rng.standard_normal((clusters, 512))) * (rng.random((clusters, 512)) < 0.3)
    G = G[which] * np.exp(0.1 * rng.standard_normal((n, 512)))
    G /= np.linalg.norm(G, axis=1, keepdims=True)
    s1 = rng.uniform(0.6, 1.0, clusters)[which]
    out["pcavox"] = np.c_[G, np.ones(n), s1, 0.5 * s1]
    return out


def test_fused_query_over_a_candidate_list_matches_the_exact_scan(tmp_path, monkeypatch):
    """Above FUSED_SCAN_MAX a fused query scores candidates from each component's search
    (pcavox through its lower-bound sidecar) with sampled medians. With every shape in
    the sample it is the exact scan; with a small sample and candidate list it still finds
    most of the exact top 10; the lower-bound sidecar follows new rows."""
    import geoshape.retrieval.index as index_module

    rows = _fused_rows(240)
    names = [f"/synthetic/{k:03d}.off" for k in range(240)]
    rng = np.random.default_rng(9)
    queries = [{c: X[i] * np.exp(0.02 * rng.standard_normal(X.shape[1])) if c != "pcavox" else X[i]
                for c, X in rows.items()} for i in (0, 17, 101, 239)]
    with ShapeIndex(tmp_path / "i.db", search="brute") as idx:
        for c, X in rows.items():
            _fill(idx, c, X, names)
        exact = [idx.query_descriptor(q, "fused", top=10) for q in queries]
        monkeypatch.setattr(index_module, "FUSED_SCAN_MAX", 0)
        monkeypatch.setattr(index_module, "FUSED_SAMPLE", 1000)  # every shape: exact medians
        for q, want in zip(queries, exact, strict=True):
            hits = idx.query_descriptor(q, "fused", top=10)
            assert [h.path for h in hits] == [h.path for h in want]
            assert np.allclose([h.distance for h in hits], [h.distance for h in want], rtol=1e-9)
        assert idx.vector_set("pcavox") is None and idx.vector_set("pcavox", lower_bound=True).n == 240
        monkeypatch.setattr(index_module, "FUSED_SAMPLE", 48)
        monkeypatch.setattr(index_module, "FUSED_CANDIDATES", 12)
        found = [{h.path for h in idx.query_descriptor(q, "fused", top=10)} for q in queries]
        recall = np.mean([len(f & {h.path for h in w}) / 10 for f, w in zip(found, exact, strict=True)])
        assert recall >= 0.8
        # a new stored copy of query 0 (all components): found first, at distance 0
        for c in rows:
            _fill(idx, c, queries[0][c][None], ["/synthetic/copy.off"])
        hits = idx.query_descriptor(queries[0], "fused", top=3)
        assert hits[0].path == "/synthetic/copy.off" and hits[0].distance < 1e-9
        assert idx.vector_set("pcavox", lower_bound=True).n == 241


def test_rows_of_and_the_hash_sample():
    X = _clustered(500, 8, seed=2)
    names = [f"/s/{k:03d}.off" for k in range(500)]
    meta = {"index_id": "x", "descriptor": "evd", "params": "{}", "version": 1, "metric": "chi2",
            "shape": [8]}
    vs = VectorSet.build(meta, names, X)
    rows = vs.rows_of(["/s/007.off", "/nowhere.off", "/s/499.off"])
    assert rows[1] == -1 and vs.path(rows[0]) == "/s/007.off" and vs.path(rows[2]) == "/s/499.off"
    assert np.array_equal(np.asarray(vs.X)[rows[0]], X[7])
    sample = vs.sample_rows(50)
    assert len(set(sample.tolist())) == 50
    # the smallest path hashes: independent of insertion order and list grouping
    expected = sorted(np.argsort(path_hashes(names), kind="stable")[:50].tolist())
    assert sorted(int(names.index(vs.path(r))) for r in sample) == expected
    assert len(vs.sample_rows(10_000)) == 500


def test_fused_candidates_never_return_a_shape_whose_row_vanished(tmp_path, monkeypatch):
    """A pcavox row deleted between the sidecar read and the row read (another writer) is
    skipped, not an error."""
    import geoshape.retrieval.index as index_module

    rows = _fused_rows(120, seed=3)
    names = [f"/synthetic/{k:03d}.off" for k in range(120)]
    q = {c: X[5] for c, X in rows.items()}
    with ShapeIndex(tmp_path / "i.db", search="brute") as idx:
        for c, X in rows.items():
            _fill(idx, c, X, names)
        monkeypatch.setattr(index_module, "FUSED_SCAN_MAX", 0)
        monkeypatch.setattr(index_module, "FUSED_SAMPLE", 16)
        first = idx.query_descriptor(q, "fused", top=5)
        assert first[0].path == names[5]
        real = ShapeIndex._stored_rows

        def lose_one(self, descriptor, pkey, paths):
            return {p: r for p, r in real(self, descriptor, pkey, paths).items() if p != names[5]}

        monkeypatch.setattr(ShapeIndex, "_stored_rows", lose_one)
        idx._cache.clear()  # the sample's rows are read again too
        hits = idx.query_descriptor(q, "fused", top=5)
    assert names[5] not in [h.path for h in hits] and len(hits) == 5


def test_fused_branch_and_bound_reads_what_reading_everything_would_rank(tmp_path, monkeypatch):
    """Branch and bound over pcavox reads gives the same list as reading every candidate's
    pcavox row (same weights), with a small sample; deleted files are skipped and the list
    stays full."""
    import geoshape.retrieval.index as index_module

    rows = _fused_rows(300, seed=5)
    folder = tmp_path / "m"
    folder.mkdir()
    names = [str(folder / f"s{k:03d}.off") for k in range(300)]
    for p in names:
        open(p, "w").close()
    rng = np.random.default_rng(2)
    queries = [{c: X[i] * np.exp(0.01 * rng.standard_normal(X.shape[1])) if c != "pcavox" else X[i]
                for c, X in rows.items()} for i in (3, 77, 150, 299)]
    monkeypatch.setattr(index_module, "FUSED_SCAN_MAX", 0)
    monkeypatch.setattr(index_module, "FUSED_SAMPLE", 32)
    with ShapeIndex(tmp_path / "i.db", search="brute") as idx:
        for c, X in rows.items():
            _fill(idx, c, X, names)
        bb = [idx.query_descriptor(q, "fused", top=10) for q in queries]
        monkeypatch.setattr(index_module, "FUSED_LB_SEED", 10_000)  # read every candidate at once
        every = [idx.query_descriptor(q, "fused", top=10) for q in queries]
        for a, b in zip(bb, every, strict=True):
            assert [h.path for h in a] == [h.path for h in b]
            assert np.allclose([h.distance for h in a], [h.distance for h in b], rtol=1e-12)
        monkeypatch.setattr(index_module, "FUSED_LB_SEED", 8)
        gone = {h.path for h in bb[0][:3]}
        for p in gone:
            (folder / p.rsplit("/", 1)[1]).unlink()
        hits = idx.query_descriptor(queries[0], "fused", top=10, skip_missing=True)
    assert len(hits) == 10 and not gone & {h.path for h in hits}
    assert [h.path for h in hits][:7] == [h.path for h in bb[0]][3:10]
