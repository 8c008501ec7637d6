"""``geoshape bench coarse2d``: how many DP starts the first pass of the coarse-to-fine search needs.

The coarse-to-fine all-pairs search (:mod:`geoshape.contour.retrieval`) ranks every pair by a
cheap first pass, then matches each query's ``refine_k`` nearest exactly. Its only error is a
shape the exact distance would rank among a query's first ranks that the first pass leaves
out of them, so a first-pass setting is judged by that *recall*: the share of each query's
exact first ``t`` ranks (self excluded) inside its refined set, for ``t`` = 10, 20 and 40 (40
is the bull's-eye depth of Tari-1000's 20-shape classes).

For each collection (default: Tari-1000 and its mirrored and noisy copies, the ones above
the ``auto`` threshold of 600 shapes), the exact matrix of the default method is computed once
(and saved in ``--matrix-dir`` under a digest of the method's spec), then the first pass is
run with each start count and its refined set compared with the exact ranks. The refined
entries of the search are the exact distances to the bit (tests), so the matrix the search
would return is formed from the exact one without matching again; its bull's-eye is reported.

Rule (the one the refine count was chosen by, docs/RESULTS.md "2D coarse-to-fine all-pairs"):
the fewest starts per orientation whose mean recall of the first 40 ranks is ≥ 0.995 on every
collection at the library's ``refine_k``.
"""

from __future__ import annotations

HELP = "first pass of the 2D coarse-to-fine search: recall of the exact first ranks by DP start count"

DEFAULT_SETS = "tari1000,tari1000-mirror,tari1000-noise"
#: Mean recall of the first 40 exact ranks a setting must keep on every collection.
MIN_RECALL_40 = 0.995


def add_arguments(parser) -> None:
    parser.add_argument("--matrix-dir", required=True,
                        help="folder for the exact matrices and the perturbed collections (reused)")
    parser.add_argument("--sets", default=DEFAULT_SETS, help=f"collections (default {DEFAULT_SETS})")
    parser.add_argument("--starts", default="16,8,4,2",
                        help="first-pass DP starts per orientation to compare (default 16,8,4,2)")
    parser.add_argument("--refine-k", default=None,
                        help="refined shapes per query (comma-separated; default the library's)")
    parser.add_argument("--n-jobs", type=int, default=None, help="workers (default: all cores)")
    parser.add_argument("--no-write", action="store_true", help="print only")


#: Depths of the exact ranking whose recall is reported (40: Tari-1000's bull's-eye depth).
DEPTHS = (10, 20, 40)


def run(args) -> int:
    import os
    import time
    from pathlib import Path

    import numpy as np

    from geoshape.bench.method_variants import matrix_cache_name
    from geoshape.bench.rerank import _folder
    from geoshape.bench.results import markdown_table, update_results_section
    from geoshape.contour.methods import DEFAULT_METHOD, contour_tracing, method_spec
    from geoshape.contour.retrieval import (
        REFINE_K,
        contour_signatures,
        first_pass_matrix,
        load_contours,
        nearest_mask,
        refined_matrix,
        shape_distance_matrix,
    )
    from geoshape.errors import InvalidOptionError
    from geoshape.io.atomic import save_npy_atomic
    from geoshape.io.datasets import read_labels
    from geoshape.metrics.retrieval import rank_recall, retrieval_metrics

    try:
        starts = sorted({int(s) for s in args.starts.split(",") if s.strip()}, reverse=True)
        ks = sorted({int(k) for k in args.refine_k.split(",")}) if args.refine_k else [REFINE_K]
    except ValueError as err:
        raise InvalidOptionError(f"--starts and --refine-k take comma-separated integers ({err})") from None
    if not starts or min(starts) < 1 or min(ks) < 1:
        raise InvalidOptionError("--starts and --refine-k must be integers ≥ 1")
    work = Path(args.matrix_dir)
    work.mkdir(parents=True, exist_ok=True)
    spec = method_spec(DEFAULT_METHOD)
    rows, worst40 = [], {}
    for name in [s.strip() for s in args.sets.split(",") if s.strip()]:
        folder = _folder(name, "", work)
        items = read_labels(folder)
        labels = [it.label for it in items]
        contours = load_contours([it.path for it in items], **contour_tracing(DEFAULT_METHOD))
        sigs = contour_signatures(contours, spec=spec, n_jobs=args.n_jobs)
        cached = work / f"{matrix_cache_name(name, DEFAULT_METHOD)}_exact.npy"
        if cached.is_file():
            exact = np.load(cached)
        else:
            print(f"[{name}] exact all pairs ({len(sigs)} shapes) …", flush=True)
            exact = shape_distance_matrix(None, signatures=sigs, search="exact", n_jobs=args.n_jobs)
            save_npy_atomic(cached, exact)
        be_exact = retrieval_metrics(exact, labels)["bulls_eye"]
        for n_starts in starts:
            print(f"[{name}] first pass, {n_starts} starts per orientation …", flush=True)
            t0 = time.perf_counter()
            coarse = first_pass_matrix(sigs, spec["matcher_options"]["skip_cost"], n_starts,
                                       spread_power=spec.get("spread_power", 0.0), n_jobs=args.n_jobs)
            seconds = time.perf_counter() - t0
            for k in ks:
                refine = nearest_mask(coarse, k)
                kept = rank_recall(exact, refine, DEPTHS)
                cells = [f"{r.mean():.4f} / {r.min():.2f} / {(r < 1).sum()}" for r in kept.values()]
                if k == REFINE_K:
                    worst40[n_starts] = min(worst40.get(n_starts, 1.0), float(kept[40].mean()))
                m = retrieval_metrics(refined_matrix(exact, coarse, refine), labels)
                rows.append([name, len(sigs), n_starts, k, f"{seconds:.1f}",
                             f"{refine[~np.eye(len(refine), dtype=bool)].mean():.1%}", *cells,
                             f"{m['bulls_eye']:.2f} ({be_exact:.2f})", f"{m['map']:.4f}"])
                print("  " + " | ".join(map(str, rows[-1])), flush=True)
    eligible = [s for s in starts if worst40.get(s, 0.0) >= MIN_RECALL_40]
    chosen = min(eligible) if eligible else max(starts)
    table = markdown_table(["collection", "N", "starts per orientation", "refine_k", "first pass s",
                            "entries refined", "t = 10", "t = 20", "t = 40",
                            "bull's-eye % (exact)", "mAP"], rows)
    text = (
        "## 2D coarse-to-fine all-pairs: DP starts of the first pass (coarse2d)\n\n"
        f"Command: `geoshape bench coarse2d --matrix-dir DIR --sets {args.sets} --starts "
        f"{','.join(map(str, starts))}"
        f"{' --refine-k ' + args.refine_k if args.refine_k else ''}` ({time.strftime('%Y-%m-%d')}, "
        f"default method, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f} at the end). Recall: share "
        "of each query's exact first t ranks (self excluded) inside its refined set — mean over "
        "queries / worst query / queries below 1. The bull's-eye is that of the matrix the search "
        "returns (its refined entries are the exact distances). 'first pass s': wall time of "
        "the first pass over all pairs.\n\n"
        f"Rule: the fewest starts whose mean recall of the first 40 ranks is ≥ {MIN_RECALL_40} on "
        f"every collection at refine_k = {REFINE_K}. Worst collection's mean per start count: "
        + ", ".join(f"{s}: {worst40[s]:.4f}" for s in starts if s in worst40)
        + f". **Chosen: {chosen}**"
        + ("" if eligible else " (none reaches the bar: the most starts tried)") + ".\n\n" + table + "\n"
    )
    print(text)
    if not args.no_write:
        update_results_section("coarse2d-starts", text)
        print("updated section coarse2d-starts of docs/RESULTS.md")
    return 0
