"""``geoshape bench index``: the shape index at scale — query time, recall, build, memory,
the k-nearest-neighbour graph, and ``index add`` throughput on a local Dask cluster.

Rows. For each size N (default 10^5 and 10^6) a fresh index receives N synthetic rows of
the real EVD length (the EVD of a generated mesh gives the length and the scale): N / 200
cluster centres log-normally scattered (σ = 0.5) around that descriptor, each row a centre
scattered by 5 %. They go in through :meth:`ShapeIndex.insert_rows` (the documented bulk
path, the one ``add`` uses), 50,000 rows a transaction.

Build. The first query of a set builds its sidecar from SQLite (read, embed, k-means lists,
write): timed, with the peak RSS of that process, in a fresh process.

Queries. 100 queries, each a stored row perturbed by 2 % log-normal noise, top 10, in a
fresh process per search mode, the sidecar files read once before (in the OS page cache, as
on a machine serving queries; the database is not read): ``brute`` (exact), ``ivf`` (nprobe default), and
``memory`` (the pre-sidecar path: every row loaded from SQLite, χ² to all; 10 queries).
``first`` is opening the index and the first query (sidecar mapped, version checked);
median and p95 are over the queries that follow. RSS growth is that process's resident
memory after the queries minus before opening (mapped sidecar pages included).
Recall@10 is against exact χ² over all rows computed here in float64 (independent code).
Then 1000 rows are inserted and the time to bring the sidecar up to date is measured.

Graph. For ``--graph-sizes`` rows (default 10^4 and 10^5): the exact k-nearest-neighbour
graph built from scratch (first ``--rerank lcdp``), brought up to date after 100 more rows,
and the time of a query without and with ``rerank="lcdp"``.

Dask. ``--dask-meshes`` tiny generated meshes (162-vertex spheres and capsules, stretched)
are added with the default descriptors (the fused method's five components) on a local Dask
cluster of ``--workers`` single-threaded workers: half of them first, then all (the first
half skipped as unchanged: the resume path). With the default 200 meshes, 10^4 is
extrapolated from the measured rate; ``--dask-meshes 10000`` runs it.

Fused. For ``--fused-sizes`` (default 10^5 and 10^6) a fresh index receives that many
synthetic shapes with all five components of the default (``_fused_chunk``: clustered rows
from a generated mesh's descriptors), its sidecars are built in a fresh process, and
``--queries`` default (fused) queries run in another, timed as above; recall@10 of the first
``--fused-recall-queries`` against the exact fused scan of every row.
"""

from __future__ import annotations

HELP = ("shape index at scale: top-10 query over 10^5/10^6 rows (exact, IVF), recall, build, memory, "
        "k-NN graph, Dask add")

SIZES = (100_000, 1_000_000)
GRAPH_SIZES = (10_000, 100_000)
CHUNK = 50_000


def add_arguments(parser) -> None:
    parser.add_argument("--sizes", type=int, nargs="*", default=list(SIZES),
                        help="numbers of stored rows (default 100000 1000000)")
    parser.add_argument("--queries", type=int, default=100, help="queries per size and mode (default 100)")
    parser.add_argument("--memory-queries", type=int, default=10,
                        help="queries of the in-memory baseline (default 10; 0 skips it)")
    parser.add_argument("--fused-sizes", type=int, nargs="*", default=list(SIZES),
                        help="stored shapes for the default (fused) query (default 100000 1000000; "
                             "none skips it)")
    parser.add_argument("--fused-independent-sizes", type=int, nargs="*", default=[SIZES[0]],
                        help="sizes also run with independently scattered components (default 100000)")
    parser.add_argument("--fused-recall-queries", type=int, default=16,
                        help="queries whose fused top 10 is checked against the exact scan (default 16)")
    parser.add_argument("--real", default=None, metavar="DIR",
                        help="also: a mesh folder with labels.csv (e.g. from 'geoshape gen mixed3d'), "
                             "indexed with the default descriptors; every stored shape queried by the "
                             "exact fused scan and by the large-index candidate path scaled down to "
                             "the collection (section index-fused-real)")
    parser.add_argument("--graph-sizes", type=int, nargs="*", default=list(GRAPH_SIZES),
                        help="rows for the k-NN graph timings (default 10000 100000)")
    parser.add_argument("--dask-meshes", type=int, default=200,
                        help="tiny meshes added on a local Dask cluster (default 200; 0 skips it)")
    parser.add_argument("--workers", type=int, default=2, help="Dask workers (default 2)")
    parser.add_argument("--work-dir", default=None,
                        help="folder for the databases (default: a temporary one)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-write", action="store_true", help="print only, do not update RESULTS.md")


def _rss_mb() -> tuple[float, float]:
    """(VmRSS, VmHWM) of this process in MB (Linux)."""
    vals = {}
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(("VmRSS:", "VmHWM:")):
                    vals[line.split(":")[0]] = float(line.split()[1]) / 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    return vals.get("VmRSS", float("nan")), vals.get("VmHWM", float("nan"))


def _worker(spec_path: str) -> None:
    """Run one measured action in this (fresh) process; write a JSON result."""
    import json
    import time

    import numpy as np
    import scipy.sparse  # noqa: F401  (imports are not what "first query" measures)

    import geoshape.retrieval.ann  # noqa: F401
    import geoshape.retrieval.descriptors  # noqa: F401
    from geoshape.retrieval.index import ShapeIndex

    spec = json.loads(open(spec_path).read())
    rss0, _ = _rss_mb()
    out = {}
    t0 = time.perf_counter()
    if spec["action"] == "build":
        with ShapeIndex(spec["db"]) as idx:
            vs = idx.vector_set(spec["descriptor"])
            out.update(seconds=time.perf_counter() - t0, nlist=vs.nlist, n=vs.n, d=vs.d)
    elif spec["action"] == "build-fused":
        with ShapeIndex(spec["db"]) as idx:
            sets = [idx.vector_set(c) or idx.vector_set(c, lower_bound=True) for c in spec["components"]]
            out.update(seconds=time.perf_counter() - t0, n=max(vs.n for vs in sets if vs is not None))
    else:
        if spec["descriptor"] == "fused":
            with np.load(spec["queries"]) as z:
                parts = {c: z[c] for c in z.files}
            Q = [{c: v[i] for c, v in parts.items()} for i in range(len(next(iter(parts.values()))))]
        else:
            Q = np.load(spec["queries"])
        times, found = [], []
        with ShapeIndex(spec["db"], search=spec["mode"]) as idx:
            for q in Q:
                t = time.perf_counter()
                hits = idx.query_descriptor(q, spec["descriptor"], top=spec["top"])
                times.append(time.perf_counter() - t)
                found.append([h.path for h in hits])
        out.update(first=time.perf_counter() - t0 - sum(times[1:]), times=times[1:], found=found)
    rss1, hwm = _rss_mb()
    out.update(rss_growth=rss1 - rss0, hwm=hwm)
    with open(spec["out"], "w") as fh:
        json.dump(out, fh)


def _cache_sidecars(db) -> None:
    """Read the sidecar files of ``db`` once, so that they are in the OS page cache as on a
    machine that serves queries (the database itself is not read)."""
    from pathlib import Path

    for f in sorted(Path(str(db) + ".ann").glob("*.vec")):
        with open(f, "rb") as fh:
            while fh.read(1 << 24):
                pass


def _in_fresh_process(work, name: str, spec: dict) -> dict:
    import json
    import subprocess
    import sys

    spec = {**spec, "out": str(work / f"{name}.out.json")}
    path = work / f"{name}.spec.json"
    path.write_text(json.dumps(spec))
    subprocess.run([sys.executable, "-c", "import sys; from geoshape.bench.index import _worker; "
                    "_worker(sys.argv[1])", str(path)], check=True)
    return json.loads((work / f"{name}.out.json").read_text())


def _template(seed: int):
    """The EVD of a generated mesh (length and scale of the synthetic rows)."""
    import trimesh

    from geoshape.retrieval.descriptors import compute_descriptor

    m = trimesh.creation.icosphere(3)
    return compute_descriptor(m.vertices * [1.0, 1.4, 0.8], m.faces, "evd", seed=seed).ravel()


def _rows(template, n: int, seed: int):
    import numpy as np

    rng = np.random.default_rng(seed)
    clusters = max(10, n // 200)
    centres = np.abs(template) * np.exp(0.5 * rng.standard_normal((clusters, len(template))))
    return centres[rng.integers(0, clusters, n)] * np.exp(0.05 * rng.standard_normal((n, len(template))))


def _names(start: int, stop: int) -> list[str]:
    return [f"/synthetic/{k:08d}.off" for k in range(start, stop)]


def _fill(idx, pkey, X, start: int = 0) -> float:
    import time

    t0 = time.perf_counter()
    for s in range(0, len(X), CHUNK):
        names = _names(start + s, start + min(len(X), s + CHUNK))
        idx.insert_rows((p, "evd", pkey, "0" * 64, x, 0.0)
                        for p, x in zip(names, X[s : s + CHUNK], strict=True))
    return time.perf_counter() - t0


def _write_meshes(folder, n: int, seed: int, start: int = 0) -> None:
    import numpy as np
    import trimesh

    from geoshape.io.mesh_io import save_mesh

    rng = np.random.default_rng(seed + start)
    folder.mkdir(parents=True, exist_ok=True)
    for k in range(start, start + n):
        m = trimesh.creation.icosphere(2) if k % 2 == 0 else trimesh.creation.capsule(1.0, 0.4)
        save_mesh(folder / f"shape{k:05d}.off", np.asarray(m.vertices) * rng.uniform(0.5, 2.0, size=3),
                  np.asarray(m.faces))


def run(args) -> int:
    import shutil
    import tempfile
    import time
    from pathlib import Path

    import numpy as np

    from geoshape.bench.results import markdown_table, update_results_section
    from geoshape.retrieval.ann import GRAPH_K
    from geoshape.retrieval.descriptors import descriptor_distances, descriptor_params, params_key
    from geoshape.retrieval.index import IVF_MIN_VALUES, ShapeIndex

    own = args.work_dir is None
    work = Path(tempfile.mkdtemp(prefix="geoshape-bench-index-") if own else args.work_dir)
    work.mkdir(parents=True, exist_ok=True)
    pkey = params_key(descriptor_params("evd"))
    template = _template(args.seed)
    d = len(template)
    rng = np.random.default_rng(args.seed + 1)
    search_rows, build_rows, graph_rows, dask_rows = [], [], [], []
    fused_rows, fused_build = [], []
    try:
        if args.real:
            text = _fused_real(work, args.real)
            print(text)
            if not args.no_write:
                print(f"wrote {update_results_section('index-fused-real', text)}")
        if args.fused_sizes:
            fused_rows, fused_build = _fused_scale(work, args)
        for n in args.sizes:
            db = work / f"rows{n}.db"
            for p in work.glob(f"rows{n}.db*"):
                shutil.rmtree(p) if p.is_dir() else p.unlink()
            X = _rows(template, n, args.seed + n)
            with ShapeIndex(db) as idx:
                t_insert = _fill(idx, pkey, X)
            print(f"{n} rows inserted in {t_insert:.1f} s", flush=True)
            built = _in_fresh_process(work, f"build{n}",
                                      {"action": "build", "db": str(db), "descriptor": "evd"})
            sidecar_mb = sum(f.stat().st_size for f in Path(str(db) + ".ann").glob("*.vec")) / 2**20
            print(f"  sidecar built in {built['seconds']:.1f} s, {sidecar_mb:.0f} MB", flush=True)
            picks = rng.choice(n, args.queries, replace=False)
            Q = X[picks] * np.exp(0.02 * rng.standard_normal((args.queries, d)))
            np.save(work / "queries.npy", Q)
            truth = []
            for s in range(0, len(Q), 10):  # exact chi2 in float64, paths in index order = row order
                D = descriptor_distances("evd", Q[s : s + 10], X)
                truth += [{f"/synthetic/{k:08d}.off" for k in np.argsort(row, kind="stable")[:10]}
                          for row in D]
            for mode in ("brute", "ivf", "memory"):
                count = args.memory_queries if mode == "memory" else args.queries
                if count <= 0:
                    continue
                np.save(work / "queries.npy", Q[:count])
                _cache_sidecars(db)
                res = _in_fresh_process(work, f"q{n}{mode}", {
                    "action": "query", "db": str(db), "descriptor": "evd", "mode": mode,
                    "queries": str(work / "queries.npy"), "top": 10})
                times = 1000 * np.asarray(res["times"])
                recall = float(np.mean([len(set(f) & t) / 10
                                        for f, t in zip(res["found"], truth, strict=False)]))
                search_rows.append([n, mode, 1000 * res["first"], float(np.median(times)),
                                    float(np.percentile(times, 95)), round(recall, 4),
                                    round(res["rss_growth"])])
                print(f"  {mode}: median {np.median(times):.2f} ms, p95 {np.percentile(times, 95):.2f} ms, "
                      f"recall@10 {recall:.4f}, first {1000 * res['first']:.0f} ms", flush=True)
            with ShapeIndex(db) as idx:
                idx.vector_set("evd")
                X_new = _rows(template, 1000, args.seed + 7)
                _fill(idx, pkey, X_new, start=n)
                t0 = time.perf_counter()
                vs = idx.vector_set("evd")
                t_incr = time.perf_counter() - t0
                assert vs.n == n + 1000
            build_rows.append([n, d, round(t_insert, 1), round(n / t_insert), round(built["seconds"], 1),
                               round(built["hwm"]), round(sidecar_mb), built["nlist"], round(t_incr, 2),
                               "ivf" if n * d > IVF_MIN_VALUES else "brute"])
            del X
            for p in work.glob(f"rows{n}.db*"):
                shutil.rmtree(p) if p.is_dir() else p.unlink()
        for n in args.graph_sizes:
            db = work / f"graph{n}.db"
            X = _rows(template, n + 100, args.seed + 3)
            with ShapeIndex(db, search="brute") as idx:
                _fill(idx, pkey, X[:n])
                idx.vector_set("evd")
                t0 = time.perf_counter()
                idx.vector_set("evd", graph=True)
                t_graph = time.perf_counter() - t0
                _fill(idx, pkey, X[n:], start=n)
                t0 = time.perf_counter()
                idx.vector_set("evd")
                t_upd = time.perf_counter() - t0
                times = []
                for q in X[rng.choice(n, 21, replace=False)] * 1.01:
                    t = time.perf_counter()
                    idx.query_descriptor(q, "evd", top=10, rerank="lcdp")
                    times.append(time.perf_counter() - t)
                plain = []
                for q in X[rng.choice(n, 21, replace=False)] * 1.01:
                    t = time.perf_counter()
                    idx.query_descriptor(q, "evd", top=10)
                    plain.append(time.perf_counter() - t)
            graph_rows.append([n, GRAPH_K, round(t_graph, 1), round(t_upd, 2),
                               round(1000 * float(np.median(plain[1:])), 2),
                               round(1000 * float(np.median(times[1:])), 2)])
            print(f"graph {n}: build {t_graph:.1f} s, +100 rows {t_upd:.2f} s, lcdp query "
                  f"{1000 * np.median(times[1:]):.1f} ms", flush=True)
            for p in work.glob(f"graph{n}.db*"):
                shutil.rmtree(p) if p.is_dir() else p.unlink()
        if args.dask_meshes > 0:
            dask_rows = _dask_add(work, args)
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)

    md = [
        "Command: `geoshape bench index --fused-sizes --fused-independent-sizes` (synthetic EVD rows, "
        "see `geoshape/bench/index.py`; the fused default at scale is section `index-fused`). "
        f"Descriptor length d = {d}; top 10; exact = χ² over all rows in float64.",
        "",
        "**Top-10 query** (one fresh process per row, the sidecar files read once before it as a "
        "serving machine keeps them in the page cache, the database not; `first` = open the index "
        "+ first query; median / p95 over the rest):",
        "",
        markdown_table(["rows", "search", "first ms", "median ms", "p95 ms", "recall@10", "RSS growth MB"],
                       search_rows),
        "",
        "**Build and memory** (`auto` = the mode `search=\"auto\"` picks; `incremental` = sidecar "
        "brought up to date after 1000 more rows):",
        "",
        markdown_table(["rows", "d", "insert s", "rows/s", "sidecar build s", "build peak RSS MB",
                        "sidecar MB", "IVF lists", "incremental s", "auto"], build_rows),
    ]
    if fused_rows:
        from geoshape.retrieval.index import FUSED_CANDIDATES, FUSED_SAMPLE, FUSED_SCAN_MAX

        sizes = " ".join(map(str, args.fused_sizes))
        indep = " ".join(map(str, args.fused_independent_sizes))
        fused_md = [
            f"Command: `geoshape bench index --fused-sizes {sizes} --fused-independent-sizes {indep} "
            "--sizes --graph-sizes --dask-meshes 0` (the fused part of `geoshape bench index`; "
            f"{args.queries} queries, recall of the first {args.fused_recall_queries}).", "",
            "**The default query (`fused`) at scale** (synthetic rows of all five components, "
            f"see `_fused_chunk`; above {FUSED_SCAN_MAX} shapes a query scores the {FUSED_CANDIDATES} "
            "nearest of each sidecar component + a sample of "
            f"{FUSED_SAMPLE} shapes for the medians, pcavox rows read by primary key where branch "
            "and bound needs them; "
            "recall@10 against the exact fused scan of all rows, `fuse_distances` on full "
            "distance rows; one fresh process, sidecars read once before it, the database not; "
            "`search=\"auto\"`):", "",
            markdown_table(["rows", "scatter", "first ms", "median ms", "p95 ms", "recall@10",
                            "RSS growth MB"], fused_rows),
            "", markdown_table(["rows", "scatter", "descriptors", "insert s", "database MB",
                                "sidecars build s", "build peak RSS MB", "sidecars MB"], fused_build)]
        fused_text = "\n".join(fused_md)
        print(fused_text)
        if not args.no_write:
            print(f"wrote {update_results_section('index-fused', fused_text)}")
    if graph_rows:
        md += ["", f"**k-nearest-neighbour graph** (K = {GRAPH_K}, exact; built on the first "
               "`--rerank lcdp`: all pairs up to 20,000 rows, pruned by IVF lists above; then kept "
               "up to date: `+100 rows`; `query` = top 10 without / with re-ranking):", "",
               markdown_table(["rows", "K", "graph build s", "+100 rows s", "query ms", "query + lcdp ms"],
                              graph_rows)]
    if dask_rows:
        md += ["", "**`index add` on a local Dask cluster** (tiny meshes; 10^4 meshes extrapolated "
               "from the measured rate at the same mesh size, not run):", "",
               markdown_table(["run", "meshes", "workers", "added", "skipped", "seconds", "meshes/s",
                               "10^4 meshes (extrapolated)"], dask_rows)]
    text = "\n".join(md)
    if not (search_rows or graph_rows or dask_rows):
        return 0  # only --real / the fused part ran: their own sections are written
    print(text)
    if not args.no_write:
        print(f"wrote {update_results_section('index', text)}")
    return 0


def _dask_add(work, args) -> list[list]:
    """Add throughput on a local Dask cluster: half the meshes, then all (resume)."""
    import logging
    import time

    try:
        from distributed import Client, LocalCluster
    except ImportError:
        print("Dask part skipped: pip install 'geoshape[dask]'")
        return []
    from geoshape.retrieval.index import DEFAULT_INDEX_DESCRIPTORS, ShapeIndex

    logging.getLogger("distributed").setLevel(logging.WARNING)
    half = args.dask_meshes // 2
    _write_meshes(work / "meshes" / "a", half, args.seed)
    _write_meshes(work / "meshes" / "b", args.dask_meshes - half, args.seed, start=half)
    db = work / "dask.db"
    out = []
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.WARNING) as cluster, \
            Client(cluster) as client:
        for label, inputs in (("first half", [work / "meshes" / "a"]),
                              ("all (resume)", [work / "meshes" / "a", work / "meshes" / "b"])):
            with ShapeIndex(db) as idx:
                t0 = time.perf_counter()
                rep = idx.add(inputs, backend="dask", scheduler=client)  # the default descriptors
                sec = time.perf_counter() - t0
            files = sum(1 for folder in inputs for _ in folder.glob("*.off"))
            per_mesh = len(DEFAULT_INDEX_DESCRIPTORS)
            rate = rep.added / per_mesh / sec
            hours = 10_000 / rate / 3600 if rate > 0 else float("nan")
            out.append([label, files, args.workers, rep.added // per_mesh, rep.skipped // per_mesh,
                        round(sec, 1), round(rate, 2), f"{hours:.1f} h"])
            print(f"dask {label}: {rep.added} rows added, {rep.skipped} skipped in {sec:.1f} s", flush=True)
    return out


# ---------------------------------------------------------------------------------------
# The fused default at scale
# ---------------------------------------------------------------------------------------

#: rows generated (and inserted) at a time
FUSED_CHUNK = 10_000
#: shape parameters shared by a synthetic row's descriptors (see :func:`_fused_chunk`)
FUSED_LATENT = 8
#: Gaussian blur (cells) of a synthetic pcavox grid's scatter. Real shapes differ by parts, so
#: nearby grids differ smoothly, and how smoothly decides how tight pcavox's lower bound is
#: (so how many pcavox rows a large-index query reads). Calibrated on that statistic: the
#: bound over the exact distance for each shape's 10 nearest is 0.84 (median) on mixed3d;
#: synthetic grids give 0.52 with unblurred scatter at the descriptor's own 0.7-cell blur,
#: 0.70 at 1, 0.82 at 1.5, 0.85 at 2 — 1.5 is the closest without exceeding the real value.
FUSED_PCAVOX_SMOOTHING = 1.5
#: fraction of synthetic clusters whose two largest principal spreads are near-equal
#: (pcavox then also tries the swaps of those axes, as for roundish real objects)
FUSED_DEGENERATE = 0.25


def _fused_templates(seed: int) -> dict:
    """The fused method's component descriptors of a generated mesh (lengths and scales)."""
    import numpy as np
    import trimesh

    from geoshape.retrieval.descriptors import FUSIONS, compute_descriptor_set

    names = [c for c, w in FUSIONS["fused"].items() if w > 0]
    m = trimesh.creation.icosphere(3)
    desc, _ = compute_descriptor_set(m.vertices * [1.0, 1.6, 0.7], m.faces, names, seed=seed)
    return {c: np.ravel(desc[c]) for c in names}


def _fused_centres(templates: dict, clusters: int, seed: int) -> dict:
    """Cluster centres per component: the template scattered log-normally (σ = 0.5); pcavox
    grids renormalised, spreads the template's or, for :data:`FUSED_DEGENERATE` of the
    clusters, ``(1, 0.9, 0.5)``."""
    import numpy as np

    rng = np.random.default_rng([seed, clusters])
    out = {}
    for c, t in templates.items():
        C = t * np.exp(0.5 * rng.standard_normal((clusters, len(t))))
        if c == "pcavox":
            G = C[:, :-3]
            G /= np.linalg.norm(G, axis=1, keepdims=True)
            C[:, -3:] = t[-3:]
            C[rng.random(clusters) < FUSED_DEGENERATE, -3:] = (1.0, 0.9, 0.5)
        out[c] = C
    return out


def _fused_chunk(centres: dict, n: int, start: int, stop: int, seed: int, shared: bool = True) -> dict:
    """Rows ``start:stop`` of the synthetic collection of ``n`` rows (the same every call):
    each a cluster centre scattered by 5 % log-normally (pcavox grids renormalised, spreads
    kept; their scatter blurred by :data:`FUSED_PCAVOX_SMOOTHING` cells and rescaled to the
    same spread). ``shared``: one
    shape's descriptors vary together — the scatter of every component is a fixed random
    linear image (per component) of the row's own :data:`FUSED_LATENT` shape parameters, plus
    1 % independent noise; otherwise each component is scattered independently (its near
    neighbours unrelated to the others')."""
    import numpy as np
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng([seed, n, start])
    clusters = len(next(iter(centres.values())))
    which = rng.integers(0, clusters, stop - start)
    z = rng.standard_normal((stop - start, FUSED_LATENT))
    out = {}
    for j, (c, C) in enumerate(centres.items()):
        if shared:
            A = np.random.default_rng([seed, 99, j]).standard_normal((FUSED_LATENT, C.shape[1]))
            noise = 0.05 * (z @ A) / np.sqrt(FUSED_LATENT)
            noise += 0.01 * rng.standard_normal(noise.shape)
        else:
            noise = 0.05 * rng.standard_normal((stop - start, C.shape[1]))
        if c == "pcavox":  # shapes vary by parts, so grids vary smoothly: blurred scatter
            R = round((C.shape[1] - 3) ** (1 / 3))
            s = FUSED_PCAVOX_SMOOTHING
            field = gaussian_filter(noise[:, :-3].reshape(-1, R, R, R), (0, s, s, s))
            field *= noise[:, :-3].std(axis=1, keepdims=True)[:, :, None, None] / \
                np.maximum(field.reshape(len(field), -1).std(axis=1), 1e-12)[:, None, None, None]
            noise[:, :-3] = field.reshape(len(field), -1)
        X = C[which] * np.exp(noise)
        if c == "pcavox":
            X[:, -3:] = C[which, -3:]
            X[:, :-3] /= np.linalg.norm(X[:, :-3], axis=1, keepdims=True)
        out[c] = X
    return out


def _fused_truth(centres: dict, n: int, seed: int, queries: dict, *, top: int = 10,
                 shared: bool = True) -> list[set]:
    """Exact fused top-``top`` of each query over all ``n`` rows: every component's distances
    to every row (chunks regenerated), fused by ``fuse_distances`` (the definition)."""
    import numpy as np

    from geoshape.retrieval.descriptors import FUSIONS, descriptor_distances
    from geoshape.retrieval.fusion import fuse_distances

    weights = {c: w for c, w in FUSIONS["fused"].items() if w > 0}
    nq = len(next(iter(queries.values())))
    mats = {c: np.empty((nq, n)) for c in weights}
    for s in range(0, n, FUSED_CHUNK):
        chunk = _fused_chunk(centres, n, s, min(n, s + FUSED_CHUNK), seed, shared)
        for c in weights:
            for a in range(0, nq, 8):  # pcavox: at most 8 queries a product
                mats[c][a : a + 8, s : s + len(chunk[c])] = descriptor_distances(c, queries[c][a : a + 8],
                                                                                 chunk[c])
    D = fuse_distances(mats, weights, all_pairs=False)
    return [{_names(int(k), int(k) + 1)[0] for k in np.argsort(row, kind="stable")[:top]} for row in D]


def _fused_scale(work, args) -> tuple[list, list]:
    """The default (fused) query over ``args.fused_sizes`` synthetic rows: fill, sidecar
    build, query times in a fresh process, recall@10 against the exact fused scan."""
    import shutil
    import time
    from pathlib import Path

    import numpy as np

    from geoshape.retrieval.descriptors import descriptor_params, params_key

    templates = _fused_templates(args.seed)
    pkeys = {c: params_key(descriptor_params(c)) for c in templates}
    query_rows, build_rows = [], []
    rng = np.random.default_rng(args.seed + 11)
    runs = [(n, True) for n in args.fused_sizes] + [(n, False) for n in args.fused_independent_sizes]
    for n, shared in runs:
        db = work / f"fused{n}.db"
        for p in work.glob(f"fused{n}.db*"):
            shutil.rmtree(p) if p.is_dir() else p.unlink()
        centres = _fused_centres(templates, max(10, n // 200), args.seed)
        picks = np.sort(rng.choice(n, args.queries, replace=False))
        picked = {c: [] for c in templates}
        t0 = time.perf_counter()
        from geoshape.retrieval.index import ShapeIndex

        with ShapeIndex(db) as idx:
            for s in range(0, n, FUSED_CHUNK):
                stop = min(n, s + FUSED_CHUNK)
                chunk = _fused_chunk(centres, n, s, stop, args.seed, shared)
                names = _names(s, stop)
                idx.insert_rows((p, c, pkeys[c], "0" * 64, x, 0.0)
                                for c in templates for p, x in zip(names, chunk[c], strict=True))
                mine = picks[(picks >= s) & (picks < stop)] - s
                for c in templates:
                    picked[c].append(chunk[c][mine])
                if (s // FUSED_CHUNK) % 10 == 9:
                    print(f"  {stop} / {n} rows inserted ({time.perf_counter() - t0:.0f} s)", flush=True)
        t_insert = time.perf_counter() - t0
        db_mb = sum(f.stat().st_size for f in work.glob(f"fused{n}.db*") if f.is_file()) / 2**20
        print(f"fused: {n} rows x {len(templates)} descriptors inserted in {t_insert:.0f} s, "
              f"{db_mb:.0f} MB", flush=True)
        queries = {}
        for c, parts in picked.items():
            Q = np.concatenate(parts)
            noise = np.exp(0.02 * rng.standard_normal(Q.shape))
            if c == "pcavox":
                noise[:, -3:] = 1.0
            Q = Q * noise
            if c == "pcavox":
                Q[:, :-3] /= np.linalg.norm(Q[:, :-3], axis=1, keepdims=True)
            queries[c] = Q
        np.savez(work / "fused_queries.npz", **queries)
        built = _in_fresh_process(work, f"fbuild{n}", {"action": "build-fused", "db": str(db),
                                                        "components": list(templates)})
        sidecar_mb = sum(f.stat().st_size for f in Path(str(db) + ".ann").glob("*.vec")) / 2**20
        print(f"  sidecars built in {built['seconds']:.1f} s, {sidecar_mb:.0f} MB", flush=True)
        _cache_sidecars(db)
        res = _in_fresh_process(work, f"fq{n}", {"action": "query", "db": str(db), "descriptor": "fused",
                                                 "mode": "auto", "queries": str(work / "fused_queries.npz"),
                                                 "top": 10})
        times = 1000 * np.asarray(res["times"])
        t0 = time.perf_counter()
        m = min(args.fused_recall_queries, args.queries)
        truth = _fused_truth(centres, n, args.seed, {c: Q[:m] for c, Q in queries.items()}, shared=shared)
        t_truth = time.perf_counter() - t0
        recall = float(np.mean([len(set(f) & t) / 10 for f, t in zip(res["found"][:m], truth, strict=True)]))
        scatter = "shared" if shared else "independent"
        query_rows.append([n, scatter, round(1000 * res["first"]), round(float(np.median(times)), 2),
                           round(float(np.percentile(times, 95)), 2), f"{recall:.3f} ({m} queries)",
                           round(res["rss_growth"])])
        build_rows.append([n, scatter, len(templates), round(t_insert), round(db_mb),
                           round(built["seconds"], 1), round(built["hwm"]), round(sidecar_mb)])
        print(f"  fused query: median {np.median(times):.1f} ms, p95 {np.percentile(times, 95):.1f} ms, "
              f"recall@10 {recall:.3f} (exact scan {t_truth:.0f} s)", flush=True)
        for p in work.glob(f"fused{n}.db*"):
            shutil.rmtree(p) if p.is_dir() else p.unlink()
    return query_rows, build_rows


#: the candidate path scaled down to a collection of a few hundred shapes (``--real``)
REAL_CANDIDATES, REAL_SAMPLE = 16, 64


def _fused_real(work, folder) -> str:
    """Section ``index-fused-real``: the large-index candidate path on a real collection.

    The folder's meshes are indexed with the default descriptors; each stored shape is the
    query (its stored descriptors) of the exact fused scan and of the candidate path forced
    (``FUSED_SCAN_MAX`` 0) with :data:`REAL_CANDIDATES` per component and a
    :data:`REAL_SAMPLE`-shape sample — about the share of a 240-shape collection that 32 and
    256 are of a few thousand. Reported: recall@10 of the candidate path against the scan,
    and NN / first tier of both (first tier from the returned lists, which hold the largest
    class)."""
    import shutil
    import time
    from collections import Counter
    from pathlib import Path

    import numpy as np

    import geoshape.retrieval.index as index_module
    from geoshape.io.datasets import read_labels
    from geoshape.retrieval.descriptors import FUSIONS, descriptor_params
    from geoshape.retrieval.index import ShapeIndex

    items = read_labels(folder)
    label = {str(Path(it.path).resolve()): it.label for it in items}
    size = Counter(label.values())
    db = Path(work) / "real.db"
    for p in Path(work).glob("real.db*"):
        shutil.rmtree(p) if p.is_dir() else p.unlink()
    comps = [c for c, w in FUSIONS["fused"].items() if w > 0]
    t0 = time.perf_counter()
    with ShapeIndex(db, search="brute") as idx:
        idx.add([it.path for it in items])
        stored = {c: dict(zip(*idx.load(c, descriptor_params(c)), strict=True)) for c in comps}
        paths = [p for p in stored[comps[0]] if p in label]
        want = max(10, max(size.values()) - 1)
        saved = (index_module.FUSED_SCAN_MAX, index_module.FUSED_CANDIDATES, index_module.FUSED_SAMPLE)
        results = {}
        try:
            for name, patch in (("exact scan", saved),
                                ("candidate path", (0, REAL_CANDIDATES, REAL_SAMPLE))):
                (index_module.FUSED_SCAN_MAX, index_module.FUSED_CANDIDATES,
                 index_module.FUSED_SAMPLE) = patch
                idx._cache.clear()
                t = time.perf_counter()
                results[name] = []
                for p in paths:
                    hits = idx.query_descriptor({c: stored[c][p] for c in comps}, "fused", top=want + 1)
                    results[name].append([h.path for h in hits if h.path != p][:want])
                results[name + " s"] = (time.perf_counter() - t) / len(paths)
        finally:
            (index_module.FUSED_SCAN_MAX, index_module.FUSED_CANDIDATES, index_module.FUSED_SAMPLE) = saved
    rows = []
    for name in ("exact scan", "candidate path"):
        lists = results[name]
        nn = np.mean([label[r[0]] == label[p] for p, r in zip(paths, lists, strict=True)])
        ft = np.mean([sum(label[x] == label[p] for x in r[: size[label[p]] - 1]) / (size[label[p]] - 1)
                      for p, r in zip(paths, lists, strict=True)])
        rec = np.mean([len(set(a[:10]) & set(b[:10])) / 10
                       for a, b in zip(results["exact scan"], lists, strict=True)])
        rows.append([name, len(paths), f"{nn:.3f}", f"{ft:.3f}", f"{rec:.3f}",
                     f"{1000 * results[name + ' s']:.1f}"])
    from geoshape.bench.results import markdown_table

    return "\n".join([
        f"Command: `geoshape bench index --real DIR --sizes --fused-sizes --fused-independent-sizes "
        f"--graph-sizes --dask-meshes 0` with DIR = `{Path(folder).name}` ({len(paths)} meshes, "
        f"{len(size)} classes; indexed with the default descriptors in {time.perf_counter() - t0:.0f} s "
        "including the queries). Each stored shape queries the index by its own stored "
        "descriptors (itself left out of its list): the exact fused scan, and the candidate path "
        f"of large indexes forced and scaled down ({REAL_CANDIDATES} candidates per component, a "
        f"{REAL_SAMPLE}-shape sample). Recall@10 = share of the scan's top 10 in the candidate "
        "path's; NN / FT from the returned lists.",
        "",
        markdown_table(["query", "queries", "NN", "FT", "recall@10 vs scan", "ms / query"], rows),
    ])
