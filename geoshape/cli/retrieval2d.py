"""``geoshape retrieval2d DIR --matrix OUT.npy``: all-pairs 2D shape retrieval on a folder."""

from __future__ import annotations

from geoshape.cli._common import CONTOUR_POINTS, N_POINTS_HELP, WORKERS
from geoshape.io.outputs import declare_outputs


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "retrieval2d",
        help="all-pairs dissimilarity matrix and retrieval scores of a folder of silhouettes",
        description="DIR holds silhouette images and labels.csv (columns file,label). Writes the "
        "N x N dissimilarity matrix in labels.csv row order (--matrix), the retrieval metrics "
        "(top-1..10 counts, bull's-eye, mAP, seconds) as JSON (--json), and a picture of the "
        "matrix (--plot). Every image is read first: a missing or unreadable file stops the "
        "command with its name and nothing is written. Outputs are written atomically at the end.",
    )
    p.add_argument("folder", metavar="DIR",
                   help="folder with images (each at most 50,000,000 pixels) and labels.csv")
    p.add_argument("--method", default="default",
                   help="default (both orientations: a shape and its mirror image match), "
                   "default_nomirror (direct orientation only), gsc, shape_context, idsc, "
                   "curvature_map")
    p.add_argument("--rerank", default=None, metavar="NAME",
                   help="re-rank the matrix over the whole collection (unsupervised): lcdp "
                   "(locally constrained diffusion); default none")
    p.add_argument("--matrix", required=True,
                   help="output .npy of the N x N matrix (re-ranked with --rerank)")
    p.add_argument("--json", help="output JSON with the metrics and timing")
    p.add_argument("--plot", help="output picture of the matrix")
    p.add_argument("--n-points", type=CONTOUR_POINTS, default=None,
                   help=N_POINTS_HELP)
    p.add_argument("--backend", default=None, help="processes (default), serial, dask")
    p.add_argument("--n-jobs", type=WORKERS, default=None, help="workers (default: all cores)")
    p.set_defaults(handler=run)
    declare_outputs(p, matrix="npy", json="text", plot="picture")


def run(args) -> int:
    import json

    from geoshape.cli._common import to_jsonable
    from geoshape.contour.methods import method_spec
    from geoshape.contour.retrieval import retrieval_on_folder
    from geoshape.io.atomic import save_npy_atomic, write_text_atomic

    method_spec(args.method)
    if args.rerank is not None:
        from geoshape.retrieval.rerank import check_rerank_method

        check_rerank_method(args.rerank)
    if args.backend is not None:
        from geoshape._options import check_choice
        from geoshape.parallel import BACKENDS

        check_choice("backend", args.backend, BACKENDS)
    result = retrieval_on_folder(args.folder, args.method, n_points=args.n_points,
                                 backend=args.backend, n_jobs=args.n_jobs)
    if args.rerank is not None:
        from geoshape.retrieval.rerank import rerank_and_score

        result.update(rerank_and_score(result["D"], result["labels"], args.rerank))
    metrics = result["metrics"]
    summary = {
        "method": args.method,
        "rerank": args.rerank,
        "seconds_rerank": result.get("seconds_rerank"),
        "n": len(result["files"]),
        "files": result["files"],
        "labels": result["labels"],
        "seconds": result["seconds"],
        "seconds_descriptors": result["seconds_descriptors"],
        "seconds_matching": result["seconds_matching"],
        "top_k_counts": metrics.get("top_k_counts"),
        "top_k_total": metrics.get("top_k_total"),
        "bulls_eye": metrics.get("bulls_eye"),
        "map": metrics.get("map"),
        "metrics": metrics,
    }
    # Everything computed; now write all outputs (each atomically).
    save_npy_atomic(args.matrix, result["D"])
    if args.json:
        write_text_atomic(args.json, json.dumps(to_jsonable(summary), indent=2) + "\n")
    if args.plot:
        from geoshape.plot.contours import plot_distance_matrix

        plot_distance_matrix(result["D"], args.plot, labels=result["labels"],
                             title=f"{args.method} ({summary['n']} shapes)")
    shown = args.method + (f", re-ranked by {args.rerank}" if args.rerank else "")
    print(f"{summary['n']} shapes, method {shown}, {result['seconds']:.1f} s")
    if metrics:
        counts = metrics["top_k_counts"]
        print(f"top-1..{len(counts)}: {counts} total {metrics['top_k_total']}/{metrics['top_k_max']}")
        print(f"bull's-eye {metrics['bulls_eye']:.2f} %, mAP {metrics['map']:.4f}")
    print(f"matrix: {args.matrix}")
    return 0
