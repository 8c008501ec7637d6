"""``geoshape index add|query|prune|info DB …``: a persistent, resumable index of shape descriptors.

``add`` describes mesh files (or folders of them) on the parallel runner and commits each
batch in one SQLite transaction; unchanged files (same path, content hash, descriptor and
parameters) are skipped, so an interrupted run resumes where it stopped. A file that cannot
be read or described is named on stderr and skipped; the exit code is then 1.
``query`` ranks the stored shapes against a mesh — by default by the fused descriptor
(``fused``: the stored evd_heat, shapedna, lfd and wks, late-fused as ``geoshape
retrieval3d`` does; ``add`` stores those by default) — optionally re-ranking by CCD, or by
diffusion over the stored k-nearest-neighbour graph (``--rerank lcdp``). Vector descriptors
are searched through a memory-mapped sidecar (``DB.ann/``): exactly by brute force, or
through an IVF above 8 million stored values (``--search``).
"""

from __future__ import annotations

from geoshape.cli._common import POSITIVE_INT, SEED, WORKERS
from geoshape.io.outputs import declare_outputs


def register(subparsers) -> None:
    from geoshape.cli.retrieval3d import FUSED_SCORES
    from geoshape.retrieval.fusion import FUSED_WEIGHTS
    from geoshape.retrieval.index import DEFAULT_INDEX_DESCRIPTORS, DEFAULT_QUERY_METHOD

    weights = ", ".join(f"{n} {w:g}" for n, w in FUSED_WEIGHTS.items() if w > 0)
    p = subparsers.add_parser(
        "index",
        help="persistent index of shape descriptors (SQLite): add meshes, query a mesh",
        description="A resumable SQLite index of 3D shape descriptors. 'add' computes and "
        "stores descriptors (unchanged files skipped), 'query' ranks stored shapes against "
        "a mesh (files deleted since are never returned), 'prune' deletes the rows of missing "
        "files, 'info' lists what is stored.",
    )
    sub = p.add_subparsers(dest="index_command", metavar="ACTION")

    a = sub.add_parser("add", help="describe mesh files / folders and store the descriptors",
                       description="Describe meshes and store the descriptors in DB (created if "
                       "missing). Each batch is committed in one transaction; re-running skips "
                       "files already stored with the same content hash and parameters.")
    a.add_argument("db", metavar="DB", help="index file (SQLite)")
    a.add_argument("inputs", metavar="MESH_OR_DIR", nargs="+", help="mesh files or folders")
    a.add_argument("--descriptor", action="extend", nargs="+", metavar="NAME", default=None,
                   help="descriptors to store (repeatable; 'fused' stands for its components; default: "
                   f"{' '.join(DEFAULT_INDEX_DESCRIPTORS)}, the components of the fused default that "
                   "'query' ranks by)")
    a.add_argument("--affinity", default=None, metavar="KIND",
                   help="geodesic (default), euclidean or combined, for spectral descriptors")
    a.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address (tcp://host:port); default: local processes")
    a.add_argument("--backend", default=None, help="processes (default), serial, dask")
    a.add_argument("--jobs", "--n-jobs", dest="n_jobs", type=WORKERS, default=None,
                   help="worker processes (default: all cores)")
    a.add_argument("--batch-size", type=POSITIVE_INT, default=None, metavar="N",
                   help="files per committed batch (default 4 x workers)")
    a.add_argument("--seed", type=SEED, default=0)
    a.add_argument("--json", action="store_true", help="print the summary as JSON")
    a.set_defaults(handler=run_add)

    q = sub.add_parser("query", help="rank the stored shapes against a mesh",
                       description="Compute the query mesh's descriptor with the stored "
                       "parameters and list the closest stored shapes.")
    q.add_argument("db", metavar="DB")
    q.add_argument("mesh", metavar="MESH")
    q.add_argument("--top", type=POSITIVE_INT, default=10, help="number of results (default 10)")
    q.add_argument("--descriptor", default=DEFAULT_QUERY_METHOD, metavar="NAME",
                   help=f"ranking descriptor, or 'fused' (default {DEFAULT_QUERY_METHOD}: the late fusion "
                   f"of the stored {', '.join(DEFAULT_INDEX_DESCRIPTORS)} with the cross-validated "
                   f"weights {weights}, as 'geoshape retrieval3d' by default). " + FUSED_SCORES)
    q.add_argument("--rerank", default=None, metavar="NAME",
                   help="re-rank the shortlist by a second stored descriptor (ccd), or by a diffusion "
                   "method (lcdp) over the stored k-nearest-neighbour graph (built on first use, then "
                   "kept up to date by add and prune)")
    q.add_argument("--rerank-k", type=POSITIVE_INT, default=None, metavar="K",
                   help="shortlist size for re-ranking (default max(top, 20))")
    q.add_argument("--search", default="auto", metavar="MODE",
                   help="auto (default: exact brute force over the sidecar, IVF above 8 million stored "
                   "values), brute (always exact), ivf (approximate), memory (no sidecar)")
    q.add_argument("--nprobe", type=POSITIVE_INT, default=None, metavar="N",
                   help="IVF lists scanned (default max(8, lists / 32))")
    q.add_argument("--affinity", default=None, metavar="KIND")
    q.add_argument("--seed", type=SEED, default=0)
    q.add_argument("--json", action="store_true", help="print the results as JSON")
    q.add_argument("--plot-strip", metavar="strip.png", default=None,
                   help="also draw the query and its results in one row")
    q.add_argument("--html", metavar="VIEW.html", default=None,
                   help="offline interactive viewer (one file): the query and its results side by "
                   "side, linked camera, names and distances")
    q.set_defaults(handler=run_query)
    declare_outputs(q, plot_strip="picture", html="html")

    r = sub.add_parser("prune", help="delete the rows of files that no longer exist")
    r.add_argument("db", metavar="DB")
    r.set_defaults(handler=run_prune)

    i = sub.add_parser("info", help="list the stored descriptor sets")
    i.add_argument("db", metavar="DB")
    i.add_argument("--json", action="store_true")
    i.set_defaults(handler=run_info)
    p.set_defaults(handler=lambda args: _usage(p))


def _usage(parser) -> int:
    parser.print_help()
    return 2


def _open(path, must_exist: bool, **options):
    from pathlib import Path

    from geoshape.errors import DatasetError
    from geoshape.retrieval.index import ShapeIndex

    if must_exist and not Path(path).is_file():
        raise DatasetError(f"{path}: no such index")
    return ShapeIndex(path, **options)


def run_add(args) -> int:
    import sys

    from geoshape._options import check_choice
    from geoshape.cli._common import print_json
    from geoshape.parallel import BACKENDS
    from geoshape.retrieval.descriptors import FUSIONS, get_descriptor, method_descriptors
    from geoshape.retrieval.index import DEFAULT_INDEX_DESCRIPTORS

    names = args.descriptor or list(DEFAULT_INDEX_DESCRIPTORS)
    names = list(dict.fromkeys(x for nm in names
                               for x in (method_descriptors(nm) if nm in FUSIONS else (nm,))))
    for nm in names:
        get_descriptor(nm)
    if args.backend is not None:
        check_choice("backend", args.backend, BACKENDS)

    def progress(done, total):
        print(f"  {done}/{total} files described and committed", file=sys.stderr, flush=True)

    with _open(args.db, must_exist=False) as idx:
        rep = idx.add(args.inputs, names, affinity=args.affinity, seed=args.seed,
                      backend=args.backend, n_jobs=args.n_jobs, scheduler=args.scheduler,
                      batch_size=args.batch_size, progress=progress if args.verbose else None)
        total = idx.count()
        if total == 0 and not rep.claimed_elsewhere:  # a failed first add leaves no file
            idx._discard_if_new_and_empty()
    for path, msg in rep.failed:
        print(f"geoshape index add: skipped {msg if path in msg else f'{path}: {msg}'}",
              file=sys.stderr)
    busy = f", {rep.claimed_elsewhere} being added by another process" if rep.claimed_elsewhere else ""
    summary = {"db": str(args.db), "descriptors": names, "added": rep.added,
               "claimed_elsewhere": rep.claimed_elsewhere,
               "skipped_unchanged": rep.skipped, "failed": [p for p, _ in rep.failed],
               "batches": rep.batches, "rows_in_index": total, "seconds": rep.seconds}
    if args.json:
        print_json(summary)
    else:
        print(f"{rep.added} descriptors added, {rep.skipped} unchanged{busy}, {len(rep.failed)} files "
          f"failed, {rep.batches} batches, {rep.seconds:.1f} s; {total} rows in {args.db}")
    return 1 if rep.failed else 0


def run_query(args) -> int:
    from pathlib import Path

    from geoshape._options import check_choice
    from geoshape.cli._common import print_json
    from geoshape.io.mesh_io import load_mesh
    from geoshape.retrieval.index import SEARCH_MODES, check_query_method, check_rerank

    check_query_method(args.descriptor)
    if args.rerank:
        check_rerank(args.rerank)
    check_choice("search", args.search, SEARCH_MODES)
    with _open(args.db, must_exist=True, search=args.search, nprobe=args.nprobe) as idx:
        V, F = load_mesh(args.mesh)
        hits, timing = idx.query_mesh(V, F, args.descriptor, top=args.top, affinity=args.affinity,
                                      seed=args.seed, rerank=args.rerank, rerank_k=args.rerank_k)
    if args.plot_strip:
        from geoshape.io.datasets import mesh_stem
        from geoshape.plot.retrieval import plot_query_strip

        plot_query_strip((V, F), [load_mesh(h.path) for h in hits], args.plot_strip,
                         query_title=mesh_stem(args.mesh),
                         titles=[f"{mesh_stem(h.path)}\n{h.distance:.3g}" for h in hits])
    if args.html:
        from geoshape.io.datasets import mesh_stem
        from geoshape.viewer.html import query_html, write_html

        rerank = f", re-ranked by {args.rerank}" if args.rerank else ""
        write_html(args.html, query_html(
            (V, F), [load_mesh(h.path) for h in hits], query_name=mesh_stem(args.mesh),
            names=[mesh_stem(h.path) for h in hits], scores=[h.distance for h in hits],
            subtitle=f"{args.descriptor} distances{rerank}, index {Path(args.db).name}"))
    if args.json:
        print_json({"query": str(Path(args.mesh)), "descriptor": args.descriptor,
                    "rerank": args.rerank, **timing,
                    "results": [{"rank": h.rank, "path": h.path, "distance": h.distance,
                                 **({"first_distance": h.first_distance} if args.rerank else {})}
                                for h in hits]})
        return 0
    for h in hits:
        extra = f"  ({args.descriptor} {h.first_distance:.6g})" if h.first_distance is not None else ""
        print(f"{h.rank:3d}  {h.distance:.6g}  {h.path}{extra}")
    print(f"query descriptor {timing['seconds_descriptor']:.3f} s, search "
          f"{1000 * timing['seconds_search']:.1f} ms")
    return 0


def run_prune(args) -> int:
    with _open(args.db, must_exist=True) as idx:
        gone = idx.prune()
    for path in gone:
        print(f"removed {path}")
    print(f"{len(gone)} missing files removed from {args.db}")
    return 0


def run_info(args) -> int:
    from geoshape.cli._common import print_json

    with _open(args.db, must_exist=True) as idx:
        rows = idx.summary()
    if args.json:
        print_json(rows)
        return 0
    for r in rows:
        print(f"{r['descriptor']:10s} {r['rows']:7d} rows  {r['params']}")
    return 0
