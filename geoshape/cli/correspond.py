"""``geoshape correspond`` and ``geoshape correspond-batch`` (used by external evaluation).

``correspond SRC TGT -o MAP.txt``: one line per source vertex, the 0-based index of its
target vertex. ``correspond-batch DIR --out-dir OUT``: for every pair of ``DIR/pairs.csv``,
``OUT/<source_stem>__<target_stem>.txt`` in the same format plus ``OUT/timings.json``.
Every file is written atomically; a pair that fails is reported and the others are still
written (exit code 1).
"""

from __future__ import annotations

import argparse
import sys

from geoshape.cli._common import SEED, WORKERS
from geoshape.io.outputs import declare_outputs


def _add_method(p) -> None:
    p.add_argument("--method", default="geoshape",
                   help="geoshape (default), jz, shapiro-brady, improved-sb, rigid-icp, shape-context-3d")
    p.add_argument("--seed", type=SEED, default=0, help="seed of samplings (default 0)")


def register(subparsers) -> None:
    p = subparsers.add_parser("correspond", help="dense vertex correspondence between two meshes",
                              description="Map every vertex of SRC to a vertex of TGT.")
    p.add_argument("source", metavar="SRC")
    p.add_argument("target", metavar="TGT")
    p.add_argument("-o", "--out", required=True, metavar="MAP.txt",
                   help="output: one 0-based target vertex id per source vertex, one per line")
    _add_method(p)
    p.add_argument("--plot", metavar="FIG.png", help="picture: source coloured through the map, target")
    p.add_argument("--ply", metavar="COLORED.ply", help="source mesh coloured through the map")
    p.add_argument("--html", metavar="VIEW.html",
                   help="offline interactive viewer (one file): both meshes, linked camera, colours "
                   "through the map, click a vertex to mark its image")
    p.add_argument("--json", action="store_true", help="print timings, cost and alternatives as JSON")
    p.set_defaults(handler=run_single)
    declare_outputs(p, out="text", plot="picture", ply="mesh", html="html")

    b = subparsers.add_parser("correspond-batch", help="correspondences for every pair of a pairs.csv",
                              description="For every pair in DIR/pairs.csv write "
                              "OUT/<source_stem>__<target_stem>.txt and OUT/timings.json.")
    b.add_argument("dir", metavar="DIR")
    b.add_argument("--pairs", default="pairs.csv", help="pairs file relative to DIR (default pairs.csv)")
    b.add_argument("--out-dir", required=True, metavar="OUT")
    _add_method(b)
    b.add_argument("--backend", default=None, help="serial, processes (default) or dask")
    b.add_argument("--jobs", type=WORKERS, default=None, help="worker processes (default: all cores)")
    b.add_argument("--scheduler", default=None, help="Dask scheduler address tcp://host:port")
    b.set_defaults(handler=run_batch)
    declare_outputs(b, all_or_nothing=False, out_dir="folder")


def run_single(args: argparse.Namespace) -> int:
    from geoshape.cli._common import print_json
    from geoshape.correspondence.map_io import write_map
    from geoshape.correspondence.mesh_matching import correspond
    from geoshape.io.mesh_io import load_mesh, save_mesh

    V1, F1 = load_mesh(args.source)
    V2, F2 = load_mesh(args.target)
    result = correspond(V1, F1, V2, F2, method=args.method, seed=args.seed,
                        names=(args.source, args.target))
    write_map(args.out, result.p2p_12)
    if args.plot:
        from geoshape.plot.correspondence import plot_correspondence

        plot_correspondence(args.plot, V1, F1, V2, F2, result.p2p_12, title=f"{args.method}")
    if args.ply:
        from geoshape.plot.correspondence import transferred_colors

        save_mesh(args.ply, V1, F1, colors=transferred_colors(V2, result.p2p_12)[0])
    if args.html:
        from geoshape.io.datasets import mesh_stem
        from geoshape.viewer.html import correspondence_html, write_html

        write_html(args.html, correspondence_html(
            V1, F1, V2, F2, result.p2p_12, names=(mesh_stem(args.source), mesh_stem(args.target)),
            subtitle=f"method {result.method}, cost {result.cost:.4g}, {result.timings['total']:.2f} s"))
    summary = {"source": args.source, "target": args.target, "method": result.method,
               "n_source": len(V1), "n_target": len(V2), "cost": result.cost,
               "seconds": result.timings.get("total"), "timings": result.timings,
               "alternatives": result.alternatives}
    if args.json:
        print_json(summary)
    else:
        print(f"{args.out}: {len(V1)} source vertices mapped to {args.target} "
              f"({result.method}, {result.timings['total']:.2f} s)")
    return 0


def run_batch(args: argparse.Namespace) -> int:
    from geoshape.correspondence.batch import correspond_batch

    report = correspond_batch(args.dir, args.out_dir, pairs_file=args.pairs, method=args.method,
                              seed=args.seed, backend=args.backend, n_jobs=args.jobs,
                              scheduler=args.scheduler)
    for failure in report["failed"]:
        print(f"geoshape correspond-batch: pair {failure['source']} -> {failure['target']} failed: "
              f"{failure['error']}", file=sys.stderr)
    print(f"{report['written']} maps written to {args.out_dir}, {len(report['failed'])} failed; "
          f"timings in {report['timings_file']}")
    return 1 if report["failed"] else 0
