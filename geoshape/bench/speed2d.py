"""``geoshape bench speed2d``: wall time of the default 2D all-pairs matrix at 1000 and 1400 shapes.

The collection is Tari-1000 followed by perturbed copies of randomly chosen Tari-1000 shapes
(``geoshape gen perturb2d`` kinds in turn: mirror, noise, notch, erode; seeded), so the first
1000 shapes are Tari-1000 itself. For each size: descriptors (all shapes, processes on all
cores), the all-pairs matrix of the ``default`` method (processes; ``--search``, by default
the library's ``auto``: coarse-to-fine at these sizes), and re-ranking (``lcdp``, one process),
each timed by the wall clock. Image reading and perturbing are not timed. With ``--reference``
(an exact Tari-1000 matrix of the same method) the 1000-shape matrix is compared with it:
retrieval scores of both, plain and re-ranked, and how many of each query's exact first ranks
the coarse-to-fine search matched exactly.
"""

from __future__ import annotations

HELP = "2D all-pairs speed: default method on Tari-1000 and a 1400-shape extension"

TARGET_SECONDS = 240.0


def add_arguments(parser) -> None:
    parser.add_argument("--sizes", default="1000,1400", help="collection sizes (default 1000,1400)")
    parser.add_argument("--n-points", type=int, default=None,
                        help="contour points (default: the default method's own tracing)")
    parser.add_argument("--n-jobs", type=int, default=None, help="workers (default: all cores)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the perturbed copies (default 0)")
    parser.add_argument("--reference", default=None,
                        help="a saved Tari-1000 default matrix (.npy) the 1000-shape matrix is "
                        "compared with (identical / largest difference)")
    parser.add_argument("--search", default="auto", choices=("auto", "exact", "coarse_to_fine"),
                        help="all-pairs search of shape_distance_matrix (default auto)")
    parser.add_argument("--no-write", action="store_true", help="print only")


def extended_collection(n_total: int, n_points: int | None, seed: int):
    """Tari-1000 contours and labels, then ``n_total − 1000`` perturbed copies (seeded), traced
    as the default method's (``n_points`` overrides its point count)."""
    import numpy as np
    from geoshape_datasets_gen.perturb2d import PERTURBATIONS, perturb_mask

    from geoshape.contour.methods import DEFAULT_METHOD, contour_tracing
    from geoshape.geometry.contour import extract_contour
    from geoshape.io.datasets import dataset_dir, read_labels
    from geoshape.io.silhouette import load_silhouette

    tracing = contour_tracing(DEFAULT_METHOD, n_points)
    items = read_labels(dataset_dir("tari1000"))
    contours = [extract_contour(load_silhouette(it.path), name=str(it.path), **tracing) for it in items]
    labels = [it.label for it in items]
    rng = np.random.default_rng(seed)
    n_extra = max(0, n_total - len(items))
    for t, src in enumerate(rng.choice(len(items), size=n_extra, replace=n_extra > len(items))):
        kind = PERTURBATIONS[t % len(PERTURBATIONS)]
        mask = perturb_mask(load_silhouette(items[src].path), kind, rng, index=t, parity=0)
        contours.append(extract_contour(mask, name=f"{items[src].path} ({kind})", **tracing))
        labels.append(labels[src])
    return contours[:n_total], labels[:n_total]


def _scores(D, R, labels) -> str:
    from geoshape.metrics.retrieval import retrieval_metrics

    m, r = retrieval_metrics(D, labels), retrieval_metrics(R, labels)
    return (f"bull's-eye {m['bulls_eye']:.2f} %, top-10 total {m['top_k_total']}/{m['top_k_max']}, "
            f"mAP {m['map']:.4f}; re-ranked {r['bulls_eye']:.2f} %, {r['top_k_total']}, {r['map']:.4f}")


def _compare(ref, D, labels, path) -> str:
    """How the matrix compares with an exact reference matrix of the same shapes."""
    import os

    import numpy as np

    from geoshape.metrics.retrieval import rank_recall
    from geoshape.retrieval.rerank import rerank

    name = os.path.basename(path)
    if ref.shape != D.shape:
        return f"The reference matrix `{name}` has shape {ref.shape}, not {D.shape}: not compared."
    if np.array_equal(ref, D):
        return f"Against the exact reference matrix `{name}`: identical."
    n = len(D)
    exact = ref == D
    off = ~np.eye(n, dtype=bool)
    parts = [f"Against the exact reference matrix `{name}` ({_scores(ref, rerank(ref), labels)}): "
             f"{(exact & off).sum() / off.sum():.1%} of the off-diagonal entries are the exact "
             f"distances (the rest rank after them); share of each query's exact first t ranks "
             f"that are exact here (mean / worst query):"]
    for t, kept in rank_recall(ref, exact).items():
        parts.append(f"t = {t}: {kept.mean():.4f} / {kept.min():.2f};")
    return " ".join(parts)[:-1] + "."


def run(args) -> int:
    import os
    import platform
    import time

    import numpy as np

    from geoshape.bench.results import markdown_table, update_results_section
    from geoshape.bench.retrieval2d import points_note
    from geoshape.bench.timing import cpu_seconds
    from geoshape.contour.retrieval import (
        COARSE_STARTS,
        REFINE_K,
        contour_signatures,
        shape_distance_matrix,
    )
    from geoshape.retrieval.rerank import rerank

    sizes = sorted({int(s) for s in args.sizes.split(",") if s.strip()})
    contours, labels = extended_collection(max(sizes), args.n_points, args.seed)
    workers = args.n_jobs or os.cpu_count()
    shape_distance_matrix(contours[:20], n_jobs=args.n_jobs)  # load the compiled kernels
    rows, notes = [], []
    for n in sizes:
        print(f"[speed2d] {n} shapes …", flush=True)
        cpu0 = cpu_seconds()
        t0 = time.perf_counter()
        sigs = contour_signatures(contours[:n], n_jobs=args.n_jobs)
        t1, cpu1 = time.perf_counter(), cpu_seconds()
        D = shape_distance_matrix(None, signatures=sigs, n_jobs=args.n_jobs, search=args.search)
        t2, cpu2 = time.perf_counter(), cpu_seconds()
        R = rerank(D)
        t3 = time.perf_counter()
        cpu = cpu_seconds() - cpu0
        pairs = n * (n - 1) // 2
        total = t3 - t0
        rows.append([n, f"{pairs:,}", f"{t1 - t0:.1f}", f"{t2 - t1:.1f}",
                     f"{(t2 - t1) / pairs * 1e6:.0f}", f"{(t2 - t1) * workers / pairs * 1e6:.0f}",
                     f"{t3 - t2:.2f}", f"{total:.1f}", "yes" if total <= TARGET_SECONDS else "no",
                     f"{cpu:.0f}", f"{cpu / workers:.0f}", f"{cpu1 - cpu0:.0f}", f"{cpu2 - cpu1:.0f}",
                     f"{os.getloadavg()[0]:.1f}"])
        print("  " + " | ".join(str(x) for x in rows[-1]), flush=True)
        if n == 1000:
            notes.append(f"The 1000-shape matrix is Tari-1000's: {_scores(D, R, labels[:n])}.")
            if args.reference:
                notes.append(_compare(np.load(args.reference), D, labels[:n], args.reference))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    table = markdown_table(["shapes", "pairs", "descriptors s", "all-pairs matrix s",
                            "µs / pair (wall)", "µs / pair / worker", "re-ranking s", "total s",
                            f"total ≤ {TARGET_SECONDS:.0f} s", "CPU s", "CPU s / workers",
                            "descriptors CPU s", "matrix CPU s", "load"], rows)
    text = (
        "## 2D all-pairs speed (default method)\n\n"
        f"Command: `geoshape bench speed2d --sizes {','.join(map(str, sizes))}"
        f"{'' if args.search == 'auto' else ' --search ' + args.search}"
        f"{' --reference ' + os.path.basename(args.reference) if args.reference else ''}` "
        f"({time.strftime('%Y-%m-%d')}, {points_note(args.n_points, 'default')}, processes, {workers} "
        f"workers, {platform.machine()}; 2 cores shared with other jobs, 1-min load average "
        f"{load:.1f} at the end ('load': after each size), so the times are upper bounds). "
        "Collection: Tari-1000, then "
        "perturbed copies (mirror, noise, notch, erode in turn; seed "
        f"{args.seed}) of randomly chosen Tari-1000 shapes. 'total' = descriptors + matrix + "
        "re-ranking (lcdp), image reading excluded. 'CPU s' is the user + system time of the "
        "parent and its worker processes over the same span; divided by the workers it is the "
        "wall time the run would take with its cores to itself. The matcher (cyclic DP with its start "
        "ranking, abandoning starts that cannot beat the best) and the visibility test of the inner "
        "distance run as compiled loops (numba) that give the NumPy implementation's results to the bit. "
        f"All-pairs search: `{args.search}`"
        + (f" ({'above ' + str(4 * REFINE_K) + ' shapes, ' if args.search == 'auto' else ''}"
           "coarse-to-fine: a first pass on every 2nd contour "
           f"point in single precision with {COARSE_STARTS} DP starts per orientation for all pairs, "
           f"then each query's {REFINE_K} nearest by it "
           "matched exactly, the other entries placed after them; "
           "`geoshape.contour.retrieval`)" if args.search != "exact" else " (every pair exactly)")
        + ".\n\n" + table + ("\n\n" + " ".join(notes) if notes else "") + "\n"
    )
    print(text)
    if not args.no_write:
        update_results_section("speed2d", text)
        print("updated section speed2d of docs/RESULTS.md")
    return 0
