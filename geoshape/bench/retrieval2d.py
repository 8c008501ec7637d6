"""Shared driver of the 2D retrieval benchmarks (``geoshape bench kimia99|tari1000``).

For each method of the registry: the all-pairs matrix on the data set with the default
backend (processes on all cores), its wall time (descriptors + matching; image reading
excluded), and the retrieval scores; one Markdown table into ``docs/RESULTS.md``.
"""

from __future__ import annotations

ALL_METHODS = ("default", "gsc", "shape_context", "idsc", "curvature_map")


def add_common_arguments(parser, default_methods=ALL_METHODS) -> None:
    parser.add_argument("--methods", default=",".join(default_methods),
                        help=f"comma-separated methods (default: {','.join(default_methods)})")
    from geoshape.cli._common import N_POINTS_HELP

    parser.add_argument("--n-points", type=int, default=None, help=N_POINTS_HELP)
    parser.add_argument("--backend", default=None, help="processes (default), serial, dask")
    parser.add_argument("--n-jobs", type=int, default=None, help="workers (default: all cores)")
    parser.add_argument("--matrix-dir", default=None,
                        help="also save each method's matrix as <dir>/<set>_<method>.npy (and what it was "
                             "computed with as <set>_<method>.spec)")
    parser.add_argument("--no-write", action="store_true",
                        help="print the table but do not update docs/RESULTS.md")


def matrix_spec(dataset: str, method: str, n_points: int | None = None) -> str:
    """What a saved ``<set>_<method>.npy`` was computed with: the set, the method and a digest of
    its registry entry and contour tracing (:func:`geoshape.bench.method_variants.matrix_cache_name`).
    :func:`save_matrix` writes it beside the matrix, so a reader tells a matrix of the method
    as it is now from one saved before its entry (e.g. ``default``) changed."""
    from geoshape.bench.method_variants import matrix_cache_name

    return matrix_cache_name(dataset, method if n_points is None else f"{method}@{n_points}")


def save_matrix(folder, dataset: str, method: str, D, *, n_points: int | None = None):
    """Save ``D`` as ``folder/<set>_<method>.npy`` and its :func:`matrix_spec` as ``….spec``
    (each written to a temporary file, then moved; the spec last, so an interrupted save reads
    as stale). Returns the matrix's path."""
    from pathlib import Path

    from geoshape.io.atomic import save_npy_atomic, write_text_atomic

    path = Path(folder) / f"{dataset}_{method}.npy"
    save_npy_atomic(path, D)
    write_text_atomic(path.with_suffix(".spec"), matrix_spec(dataset, method, n_points) + "\n")
    return path


def load_matrix(folder, dataset: str, method: str):
    """The matrix :func:`save_matrix` saved for ``method`` on ``dataset`` with its own tracing,
    or None when there is none or it was computed under another spec (a changed registry
    entry, another point count, or no spec file: saved by an older version)."""
    from pathlib import Path

    import numpy as np

    path = Path(folder) / f"{dataset}_{method}.npy"
    spec = path.with_suffix(".spec")
    if not (path.is_file() and spec.is_file()):
        return None
    if spec.read_text().strip() != matrix_spec(dataset, method):
        return None
    return np.load(path)


def points_note(n_points: int | None, method: str | None = None) -> str:
    """How a benchmark's contours were traced, for its command line's note."""
    from geoshape.contour.methods import DEFAULT_METHOD, contour_tracing
    from geoshape.geometry.contour import N_POINTS

    def traced(m: str) -> str:
        t = contour_tracing(m)
        return f"{t['n_points']} contour points smoothed by {t['smoothing']:g} x the perimeter"

    if n_points:
        return f"{n_points} contour points, each method's smoothing and part joining"
    if method:
        return f"{traced(method)} ({method}'s tracing)"
    return (f"each method's contour tracing ({DEFAULT_METHOD}: {traced(DEFAULT_METHOD)}; "
            f"most others: {N_POINTS})")


def run_benchmark(dataset: str, args, *, intro: str, primary: str) -> int:
    from pathlib import Path

    from geoshape._options import check_choice
    from geoshape.bench.results import update_results_section
    from geoshape.contour.methods import CONTOUR_METHODS
    from geoshape.contour.retrieval import retrieval_on_folder
    from geoshape.io.datasets import dataset_dir

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    for m in methods:
        check_choice("method", m, CONTOUR_METHODS)
    folder = dataset_dir(dataset)
    rows = []
    for m in methods:
        print(f"[{dataset}] {m} …", flush=True)
        res = retrieval_on_folder(folder, m, n_points=args.n_points, backend=args.backend,
                                  n_jobs=args.n_jobs)
        met = res["metrics"]
        counts = met["top_k_counts"]
        rows.append([m, CONTOUR_METHODS[m]["summary"], " ".join(str(c) for c in counts),
                     f"{met['top_k_total']}/{met['top_k_max']}", f"{met['bulls_eye']:.2f}",
                     f"{met['map']:.4f}", f"{res['seconds_descriptors']:.1f}",
                     f"{res['seconds']:.1f}"])
        print(f"  top-k {counts} total {met['top_k_total']}, bull's-eye {met['bulls_eye']:.2f} %, "
              f"mAP {met['map']:.4f}, {res['seconds']:.1f} s", flush=True)
        if args.matrix_dir:
            save_matrix(Path(args.matrix_dir), dataset, m, res["D"], n_points=args.n_points)
        # Write after every method, so a long run leaves its finished rows behind.
        md = _section(dataset, args, methods, rows, intro, primary)
        if not args.no_write:
            update_results_section(f"retrieval2d-{dataset}", md)
    print(md)
    if not args.no_write:
        print(f"updated section retrieval2d-{dataset} of docs/RESULTS.md")
    return 0


def _section(dataset, args, methods, rows, intro, primary) -> str:
    import os
    import platform
    import time

    from geoshape.bench.results import markdown_table, workers_note
    from geoshape.contour.retrieval import AUTO_COARSE_FACTOR, REFINE_K

    header = ["method", "what", "top-1..10 counts", "top-10 total", "bull's-eye %", "mAP",
              "descriptors s", "all-pairs s"]
    table = markdown_table(header, rows)
    workers = args.n_jobs or os.cpu_count()
    stamp = time.strftime("%Y-%m-%d")
    done = "" if len(rows) == len(methods) else f" (rows so far: {len(rows)} of {len(methods)})"
    jobs = f" --n-jobs {args.n_jobs}" if args.n_jobs else ""
    return (f"## 2D retrieval: {dataset}\n\n{intro}\n\n"
            f"Command: `geoshape bench {dataset} --methods {','.join(methods)}{jobs}`{done} "
            f"({stamp}, {points_note(args.n_points)}, backend {args.backend or 'processes'}, "
            f"{workers_note(workers)}, {platform.machine()}; 'all-pairs s' is the wall time of "
            f"descriptors + all-pairs matrix, measured on a machine shared with other jobs, "
            f"so an upper bound; all-pairs search `auto`: coarse-to-fine for the cyclic-DP methods "
            f"above {AUTO_COARSE_FACTOR * REFINE_K} shapes, see '2D coarse-to-fine all-pairs search'). "
            f"Primary score: {primary}.\n\n{table}\n")
