"""``geoshape retrieval3d DIR [--descriptor NAME] --matrix OUT.npy``: all-pairs 3D retrieval.

Contract (used by external evaluation; keep it stable): DIR holds meshes and
``labels.csv`` (``file,label``); without ``--descriptor`` the fused default
(:data:`geoshape.retrieval.descriptors.DEFAULT_RETRIEVAL_METHOD`, ``fused``) is used; the
N x N dissimilarity matrix is written in labels.csv row order; ``--json`` holds NN, FT, ST,
E, DCG, mAP and seconds. Every output is written
atomically after everything is computed; a mesh that cannot be read or described stops the
command with its name (exit 2) and nothing is written.
"""

from __future__ import annotations

from geoshape.cli._common import POSITIVE_INT, SEED, WORKERS
from geoshape.io.outputs import declare_outputs

#: the default's measured scores, quoted from docs/RESULTS.md (section "3D late fusion", row
#: "fusion, adaptive (library)", written by ``geoshape bench fusion``)
FUSED_SCORES = ("Measured (docs/RESULTS.md, section fusion): tosca_r5k NN 1.000 / FT 0.954, mixed3d "
                "NN 0.988 / FT 0.863 (seed 1: NN 0.983 / FT 0.843); about 0.8 s CPU per 5000-vertex mesh "
                "on one core.")


def register(subparsers) -> None:
    from geoshape.retrieval.descriptors import DEFAULT_RETRIEVAL_METHOD, MESH_DESCRIPTORS, RETRIEVAL_METHODS
    from geoshape.retrieval.fusion import FUSED_WEIGHTS

    weights = ", ".join(f"{n} {w:g}" for n, w in FUSED_WEIGHTS.items() if w > 0)
    listing = "; ".join(f"{n}: {s.summary}" for n, s in MESH_DESCRIPTORS.items())
    p = subparsers.add_parser(
        "retrieval3d",
        help="all-pairs dissimilarity matrix and retrieval scores of a folder of meshes",
        description="DIR holds meshes and labels.csv (columns file,label). Computes one "
        "descriptor per mesh (in parallel), the N x N dissimilarity matrix in labels.csv "
        "row order (--matrix), and NN, FT, ST, E, DCG, mAP and timings (--json). "
        f"Descriptors — {listing}; evd_ccd: EVD, then each query's top K re-ranked by CCD; "
        f"fused (the default): the {', '.join(n for n, w in FUSED_WEIGHTS.items() if w > 0)} "
        f"matrices fused query-adaptively (per query, each component weighted by how sharply it "
        f"separates the query's nearest items compared with its usual sharpness), weights {weights} "
        "(cross-validated over four collections by 'geoshape bench fusion'; the spectral components "
        "share one Laplace-Beltrami eigen-solve per mesh). " + FUSED_SCORES,
    )
    p.add_argument("folder", metavar="DIR", help="folder with meshes and labels.csv")
    p.add_argument("--descriptor", default=None, metavar="NAME",
                   help=f"one of {', '.join(RETRIEVAL_METHODS)} (default {DEFAULT_RETRIEVAL_METHOD}: "
                   "the cross-validated late fusion, see above)")
    p.add_argument("--affinity", default=None, metavar="KIND",
                   help="geodesic (default), euclidean or combined: distances of the spectral "
                   "embedding (evd, ccd, evd_ccd, *_emb only)")
    p.add_argument("--matrix", required=True, metavar="OUT.npy", help="output N x N matrix")
    p.add_argument("--json", metavar="OUT.json", help="output JSON with metrics and timing")
    p.add_argument("--plot-pr", metavar="pr.png", help="output precision-recall curve")
    p.add_argument("--plot-matrix", metavar="m.png", help="output similarity-matrix image")
    p.add_argument("--rerank-k", type=POSITIVE_INT, default=None, metavar="K",
                   help="evd_ccd: shortlist re-ranked by CCD (default 20)")
    p.add_argument("--rerank", default=None, metavar="NAME",
                   help="re-rank the matrix over the whole collection (unsupervised): lcdp "
                   "(locally constrained diffusion); default none")
    p.add_argument("--seed", type=SEED, default=0, help="seed of sampling (default 0)")
    p.add_argument("--backend", default=None, help="processes (default), serial, dask")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address (implies --backend dask)")
    p.add_argument("--jobs", "--n-jobs", dest="n_jobs", type=WORKERS, default=None,
                   help="workers (default: all cores)")
    p.set_defaults(handler=run)
    declare_outputs(p, matrix="npy", json="text", plot_pr="picture", plot_matrix="picture")


def run(args) -> int:
    import json

    from geoshape._options import check_choice
    from geoshape.cli._common import to_jsonable
    from geoshape.io.atomic import save_npy_atomic, write_text_atomic
    from geoshape.parallel import BACKENDS
    from geoshape.retrieval.descriptors import (
        DEFAULT_RETRIEVAL_METHOD,
        RERANKERS,
        RETRIEVAL_METHODS,
        descriptor_params,
        method_descriptors,
    )
    from geoshape.retrieval.meshes import DEFAULT_RERANK_K, retrieval3d_on_folder

    if args.descriptor is None:
        args.descriptor = DEFAULT_RETRIEVAL_METHOD
    check_choice("descriptor", args.descriptor, RETRIEVAL_METHODS)
    for nm in method_descriptors(args.descriptor):
        descriptor_params(nm, args.affinity, args.seed)
    if args.backend is not None:
        check_choice("backend", args.backend, BACKENDS)
    if args.rerank is not None:
        from geoshape.retrieval.rerank import check_rerank_method

        check_rerank_method(args.rerank)
    if args.rerank_k is not None and args.descriptor not in RERANKERS:
        from geoshape.errors import InvalidOptionError

        raise InvalidOptionError(f"--rerank-k applies to {', '.join(RERANKERS)} only")
    res = retrieval3d_on_folder(args.folder, args.descriptor, affinity=args.affinity,
                                seed=args.seed, rerank_k=args.rerank_k or DEFAULT_RERANK_K,
                                backend=args.backend, n_jobs=args.n_jobs,
                                scheduler=args.scheduler)
    if args.rerank is not None:
        from geoshape.retrieval.rerank import rerank_and_score

        res.update(rerank_and_score(res["D"], res["labels"], args.rerank))
    m = res["metrics"]
    keys = {"NN": "nearest_neighbor", "FT": "first_tier", "ST": "second_tier",
            "E": "e_measure", "DCG": "dcg", "mAP": "map"}
    summary = {
        "descriptor": args.descriptor,
        "affinity": args.affinity,
        "rerank": args.rerank,
        "seconds_rerank": res.get("seconds_rerank"),
        "n": len(res["files"]),
        "files": res["files"],
        "labels": res["labels"],
        **{k: m.get(v) for k, v in keys.items()},
        "seconds": res["seconds"],
        "seconds_descriptors": res["seconds_descriptors"],
        "seconds_matrix": res["seconds_matrix"],
        "seconds_per_mesh": res["seconds_per_mesh"],
        "metrics": m,
    }
    # Everything computed: now write (each output atomically).
    save_npy_atomic(args.matrix, res["D"])
    if args.json:
        write_text_atomic(args.json, json.dumps(to_jsonable(summary), indent=2) + "\n")
    name = args.descriptor + (f" ({args.affinity})" if args.affinity else "")
    name += f", re-ranked by {args.rerank}" if args.rerank else ""
    if args.plot_pr and m:
        from geoshape.plot.retrieval import plot_precision_recall

        plot_precision_recall({name: m}, args.plot_pr, title=f"{name}, {summary['n']} meshes")
    if args.plot_matrix:
        from geoshape.plot.retrieval import plot_similarity_matrix

        plot_similarity_matrix(res["D"], args.plot_matrix, labels=res["labels"],
                               title=f"{name} ({summary['n']} meshes)")
    print(f"{summary['n']} meshes, descriptor {name}, {res['seconds']:.1f} s")
    if m:
        print("NN {NN:.4f}  FT {FT:.4f}  ST {ST:.4f}  E {E:.4f}  DCG {DCG:.4f}  mAP {mAP:.4f}"
              .format(**{k: summary[k] for k in keys}))
    print(f"matrix: {args.matrix}")
    return 0
