"""``geoshape bench correspondence DIR``: geodesic error and time of every method, with pyFM.

For each pair of ``DIR/pairs.csv`` (or ``--pairs``) and each method: the map is computed
end to end (meshes loaded, every per-mesh precomputation included — nothing is cached
across pairs, so times are honest per-pair times), then scored by the geodesic error on
the target divided by √area (:mod:`geoshape.metrics.correspondence`), direct and
symmetry-aware. Landmark ground truth (``.vts``) is subsampled to ``--landmarks`` seeded
landmarks per pair; identity ground truth uses the same number of random vertices.
SCAPE (identity ids) has no mirrored map of all vertices: its symmetry-aware score uses
the 36 SCB feature points (``Corrs/1.pid``) with their left/right pairs (``1.sym.info``),
as in Kim et al.'s benchmark; other identity sets report direct errors only.

The off-the-shelf peer is pyFM (``pip install pyfmaps``, never a dependency of geoshape),
run with its README's recommended settings: WKS descriptors, K = 30, orientation term
on, ZoomOut refinement nit = 16, step = 5.

``--suite generalization`` runs every dev set of issue #14 into one table instead
(:mod:`geoshape.bench.correspondence_suite`), through the same :func:`evaluate_pairs`.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HELP = "3D correspondence: geodesic errors and times of every method (and pyFM) on a pairs set"
DEFAULT_METHODS = "geoshape,jz,improved-sb,shapiro-brady,rigid-icp,shape-context-3d"
THRESHOLDS = (0.025, 0.05, 0.1, 0.25)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dir", metavar="DIR", nargs="?", default=None,
                   help="dataset folder holding pairs.csv and the meshes (not with --suite)")
    p.add_argument("--pairs", default="pairs.csv", help="pairs file (relative to DIR), default pairs.csv")
    p.add_argument("--limit", type=int, default=None, help="only the first N pairs")
    p.add_argument("--methods", default=None,
                   help=f"comma-separated (default {DEFAULT_METHODS}; with --suite: geoshape)")
    p.add_argument("--peer", choices=("pyfm", "none"), default="pyfm", help="off-the-shelf peer to run too")
    p.add_argument("--landmarks", type=int, default=1000, help="landmarks evaluated per pair (seeded subset)")
    p.add_argument("--section", default=None, help="RESULTS.md section name (default from DIR and pairs)")
    p.add_argument("--plot", default=None,
                   help="cumulative-error plot (default docs/img/correspondence_<set>.png)")
    p.add_argument("--no-results", action="store_true", help="print only; do not write docs/RESULTS.md")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--suite", choices=("generalization",), default=None,
                   help="run every dev set of issue #14 (original, remeshed, non-isometric) into one table")
    p.add_argument("--dev-dir", default=None,
                   help="with --suite: folder of the generated dev sets, reused when their generator "
                   "parameters match (default $XDG_CACHE_HOME/geoshape/dev-sets or ~/.cache/…)")
    p.add_argument("--sets", default=None,
                   help="with --suite: comma-separated dev sets (default: all, names as in the table); "
                   "the RESULTS section then holds only these (--section to write another)")
    p.add_argument("--sensitivity", action="store_true",
                   help="with --suite: instead of the suite table, the mean error of each numeric default of "
                   "the geoshape method ×0.5 and ×2 (its own RESULTS section; long: use --limit)")
    p.add_argument("--candidates", default=None, metavar="NAMES",
                   help="instead of a table: for the pairs whose 'source -> target' name contains one of "
                   "these comma-separated strings, every refined candidate of the geoshape method with its "
                   "decision scores and its errors (print only)")
    p.add_argument("--decision-weights", action="store_true",
                   help="with --suite: instead of the suite table, the mean error and failures per set when "
                   "the decision objective's exponents (distortion, energy, curvature disagreement, "
                   "orientation share) are halved, doubled or set to 0, re-deciding on each pair's "
                   "candidates (its own RESULTS section)")
    p.add_argument("--fields", default=None,
                   help="with --sensitivity: comma-separated geoshape options to vary (default: every "
                   "numeric default of the sensitivity table; none: only the --seeds rows)")
    p.add_argument("--seeds", type=int, default=0, metavar="N",
                   help="with --sensitivity: also N rows of the default with N other sampling seeds, and "
                   "their range per set: the method's own sampling noise (default 0)")


#: the most ``--seeds`` rows a sensitivity table takes (each is a full run of every set)
MAX_SEED_DRAWS = 10


def run_pyfm(V1, F1, V2, F2) -> np.ndarray:
    """p2p_12 (source → target) from pyFM's recommended pipeline."""
    from pyFM.functional import FunctionalMapping
    from pyFM.mesh import TriMesh

    target = TriMesh(V2, F2, area_normalize=True, center=True)
    source = TriMesh(V1, F1, area_normalize=True, center=True)
    model = FunctionalMapping(target, source)  # p2p_21 of (target, source) maps source → target
    model.preprocess(descr_type="WKS", subsample_step=2, verbose=False)
    model.fit(K=30, w_descr=1e0, w_lap=1e-1, w_dcomm=1e0, w_orient=1e0, verbose=False)
    fm = model.zoomout_refine(nit=16, step=5, verbose=False)
    return np.asarray(model.get_p2p(fm, n_jobs=1), dtype=np.int64)


def _landmark_sets(pair, n_vertices_1, n_vertices_2, n_landmarks, seed, feature_points):
    """(source ids, target ids, target mirrored ids or None) to evaluate."""
    rng = np.random.default_rng(seed)
    if pair.identity:
        if feature_points is not None:
            ids, sym = feature_points
            return ids, ids, sym
        n = min(n_vertices_1, n_vertices_2)
        ids = np.sort(rng.choice(n, min(n_landmarks, n), replace=False))
        return ids, ids, None
    k = len(pair.source_landmarks)
    sel = np.sort(rng.choice(k, min(n_landmarks, k), replace=False))
    sym = None if pair.target_symmetric_landmarks is None else pair.target_symmetric_landmarks[sel]
    return pair.source_landmarks[sel], pair.target_landmarks[sel], sym


def process_note() -> str:
    """How the timed methods used the cores, for a RESULTS header: the geoshape method runs
    independent stages of a pair beside each other (:func:`geoshape.parallel.beside`) unless
    ``GEOSHAPE_STAGE_PROCESSES=0`` or the machine cannot; every other method, and pyFM, in one
    process; every one with one BLAS thread."""
    from geoshape.parallel import can_run_beside

    if can_run_beside():
        return ("geoshape runs independent stages of a pair on a second core (geoshape.parallel.beside), "
                "every other method and the peer in one process; one BLAS thread each")
    return ("every method in one process (GEOSHAPE_STAGE_PROCESSES=0, or no forking here: "
            "geoshape.parallel.can_run_beside), one BLAS thread")


def env_prefix() -> str:
    """``GEOSHAPE_STAGE_PROCESSES=0 `` when that switch is set, for the command a RESULTS header shows."""
    from geoshape.parallel import STAGE_PROCESSES_ENV

    return f"{STAGE_PROCESSES_ENV}=0 " if os.environ.get(STAGE_PROCESSES_ENV, "1") == "0" else ""


def run(args: argparse.Namespace) -> int:
    from geoshape.parallel import blas_threads

    # one BLAS thread: on shared cores threaded BLAS is many times slower; same for every method
    with blas_threads(1, openmp=True):
        return _run(args)


@dataclass
class PairResult:
    """One method on one pair: per-landmark errors ÷ √area (direct, symmetry-aware) and time."""

    method: str
    pair: str
    errors: np.ndarray | None = None
    errors_sym: np.ndarray | None = None
    """Symmetry-aware errors; the direct ones when the pair has no symmetric ground truth."""
    seconds: float = float("nan")
    error: str | None = None
    """Message when the method raised (no errors then)."""

    @property
    def mean(self) -> float:
        return float(self.errors.mean()) if self.errors is not None else float("nan")

    @property
    def mean_sym(self) -> float:
        return float(self.errors_sym.mean()) if self.errors_sym is not None else float("nan")


def peer_methods(methods: list[str], peer: str) -> list[str]:
    """``methods`` (checked) plus ``"pyfm"`` when the peer is asked for and installed."""
    from geoshape._options import check_choice
    from geoshape.correspondence.mesh_matching import CORRESPONDENCE_METHODS

    methods = list(methods)
    for m in methods:
        check_choice("correspondence method", m, CORRESPONDENCE_METHODS)
    if peer == "pyfm":
        try:
            import pyFM  # noqa: F401
        except ImportError:
            print("pyFM is not installed (pip install pyfmaps); running without the peer")
        else:
            methods.append("pyfm")
    return methods


@dataclass
class LoadedPair:
    """One row of a pairs file, loaded: meshes, evaluation landmarks, and a geodesic-error evaluator."""

    index: int
    name: str
    V1: np.ndarray
    F1: np.ndarray
    V2: np.ndarray
    F2: np.ndarray
    src: np.ndarray
    tgt: np.ndarray
    sym: np.ndarray | None
    evaluator: object


def loaded_pairs(folder: Path, pairs, *, landmarks: int, seed: int, feature_points):
    """Yield a :class:`LoadedPair` for each of ``pairs`` (rows of ``read_pairs``; a None row is
    skipped and keeps its position), landmarks drawn with seed ``seed + position``; evaluators kept
    for the last 4 targets (pairs files repeat targets)."""
    from geoshape.io.mesh_io import load_mesh
    from geoshape.metrics.correspondence import GeodesicErrorEvaluator

    evaluators: dict = {}
    for pi, pair in enumerate(pairs):
        if pair is None:
            continue
        V1, F1 = load_mesh(pair.source)
        V2, F2 = load_mesh(pair.target)
        src, tgt, sym = _landmark_sets(pair, len(V1), len(V2), landmarks, seed + pi, feature_points)
        ev = evaluators.get(str(pair.target))
        if ev is None:  # built only for a target not seen among the last 4
            ev = evaluators[str(pair.target)] = GeodesicErrorEvaluator(V2, F2)
            if len(evaluators) > 4:
                evaluators.pop(next(iter(evaluators)))
        yield LoadedPair(pi, f"{pair.source.name} -> {pair.target.name}", V1, F1, V2, F2, src, tgt, sym, ev)


def limited_pairs(pairs: list, limit: int | None, *, spread: bool = False) -> list:
    """The first ``limit`` of ``pairs`` (all when None), or with ``spread`` ``limit`` evenly
    spaced ones (every class of a file sorted by class kept)."""
    if spread and limit is not None and limit < len(pairs):
        rows = np.unique(np.linspace(0, len(pairs) - 1, max(limit, 1)).round().astype(int))
        pairs = [pairs[i] for i in rows]
    return pairs[:limit]


def evaluate_pairs(folder, pairs_file: str, methods: list[str], *, limit: int | None = None,
                   landmarks: int = 1000, seed: int = 0, options: dict | None = None, spread: bool = False,
                   log=print) -> tuple[list[PairResult], bool]:
    """Run every method on the first ``limit`` pairs of ``folder/pairs_file`` and score it.

    With ``spread`` the ``limit`` pairs are evenly spaced rows instead (every class of a
    file sorted by class kept).
    Returns the results (pair by pair, methods in turn) and whether the set has a
    symmetric ground truth. ``options`` go to the ``geoshape`` method only. ``seed`` picks the
    landmarks and seeds every method's sampling, unless ``options`` names the method's own
    ``seed`` (the ``--seeds`` rows of the sensitivity table).
    """
    from geoshape.correspondence.mesh_matching import correspond
    from geoshape.errors import GeoshapeError
    from geoshape.io.datasets import read_pairs, scape_feature_points
    from geoshape.metrics.correspondence import geodesic_errors

    folder = Path(folder)
    pairs = limited_pairs(read_pairs(folder, pairs_file), limit, spread=spread)
    feature_points = scape_feature_points(folder)
    results: list[PairResult] = []
    for lp in loaded_pairs(folder, pairs, landmarks=landmarks, seed=seed, feature_points=feature_points):
        V1, F1, V2, F2, name = lp.V1, lp.F1, lp.V2, lp.F2, lp.name
        line = [f"[{lp.index + 1}/{len(pairs)}] {name}:"]
        for m in methods:
            t = time.perf_counter()
            try:
                if m == "pyfm":
                    p2p = run_pyfm(V1, F1, V2, F2)
                else:
                    extra = options if (options and m == "geoshape") else {}
                    kw = {"seed": seed, **extra}  # an option's own seed (a --seeds row) wins
                    p2p = correspond(V1, F1, V2, F2, method=m, **kw).p2p_12
            except GeoshapeError as exc:
                results.append(PairResult(m, name, error=str(exc)))
                line.append(f"{m} FAILED ({exc})")
                continue
            seconds = time.perf_counter() - t
            r = geodesic_errors(V2, F2, p2p[lp.src], lp.tgt, lp.sym, evaluator=lp.evaluator)
            results.append(PairResult(m, name, r["errors"],
                                      r["errors_sym_aware"] if lp.sym is not None else r["errors"], seconds))
            sym_mean = r.get("mean_sym_aware", float("nan"))
            line.append(f"{m} {r['mean']:.4f}/{sym_mean:.4f} {seconds:.1f}s")
        log(" ".join(line))
    has_sym = any(p.target_symmetric_landmarks is not None for p in pairs) or feature_points is not None
    return results, has_sym


@dataclass
class CandidatePool:
    """One pair's refined candidates (``Correspondence.details["candidates"]``) with the mean
    direct and symmetry-aware errors of each refined map at the evaluation landmarks, and the
    errors of the pipeline's final map."""

    name: str
    candidates: list
    errors: list[float]
    errors_sym: list[float]
    chosen_index: int = -1
    final_error: float = float("nan")
    final_error_sym: float = float("nan")
    error: str | None = None
    """The message of the :class:`~geoshape.errors.GeoshapeError` the method raised (no candidates)."""


def candidate_pools(folder, pairs, *, landmarks: int = 1000, seed: int = 0, options: dict | None = None):
    """Yield a :class:`CandidatePool` for each of ``pairs`` (rows of ``read_pairs``; a None row is
    skipped and keeps its position, so landmarks are drawn as the suite draws them). Errors of
    refined maps are taken before the full-resolution stage; on large meshes, where refined maps
    live on samples, each landmark reads the image of its nearest refinement sample. A pair on
    which the method raises a :class:`~geoshape.errors.GeoshapeError` yields a pool with no
    candidates and the message in ``error``. ``seed`` as in :func:`evaluate_pairs`.
    O(pipeline + candidates × landmarks) per pair."""
    from geoshape.correspondence.mesh_matching import correspond
    from geoshape.errors import GeoshapeError
    from geoshape.geometry.knn import nearest
    from geoshape.io.datasets import scape_feature_points
    from geoshape.metrics.correspondence import geodesic_errors

    folder = Path(folder)
    for lp in loaded_pairs(folder, pairs, landmarks=landmarks, seed=seed,
                           feature_points=scape_feature_points(folder)):
        V1, V2, F2, ev = lp.V1, lp.V2, lp.F2, lp.evaluator
        try:
            kw = {"seed": seed, **(options or {})}  # an option's own seed wins, as in evaluate_pairs
            result = correspond(V1, lp.F1, V2, F2, method="geoshape", **kw)
        except GeoshapeError as exc:
            yield CandidatePool(lp.name, [], [], [], error=str(exc))
            continue
        final = geodesic_errors(V2, F2, result.p2p_12[lp.src], lp.tgt, lp.sym, evaluator=ev)
        on_rows = result.details["candidate_rows"]
        at = lp.src if on_rows is None else nearest(V1[on_rows], V1[lp.src])[1]
        errors = [geodesic_errors(V2, F2, c.refined_map[at], lp.tgt, lp.sym, evaluator=ev)
                  for c in result.details["candidates"]]
        yield CandidatePool(lp.name, result.details["candidates"], [float(e["mean"]) for e in errors],
                            [float(e.get("mean_sym_aware", float("nan"))) for e in errors],
                            result.details["chosen_index"], float(final["mean"]),
                            float(final.get("mean_sym_aware", float("nan"))))


def candidate_report(folder, pairs_file: str, names: list[str], *, landmarks: int = 1000, seed: int = 0,
                     options: dict | None = None, log=print) -> list[dict]:
    """Why the geoshape method chose what it chose: for every pair of ``folder/pairs_file`` whose
    ``"source -> target"`` name contains one of ``names``, one row per refined candidate
    (:func:`candidate_pools`) with its decision factors and errors. Logged as a table per pair;
    returned as dicts."""
    from geoshape.correspondence.pipeline import decision_score
    from geoshape.io.datasets import read_pairs

    named = [p if any(n in f"{p.source.name} -> {p.target.name}" for n in names) else None
             for p in read_pairs(Path(folder), pairs_file)]
    rows = []
    for pool in candidate_pools(folder, named, landmarks=landmarks, seed=seed, options=options):
        if pool.error is not None:
            log(f"== {pool.name}: failed: {pool.error}")
            continue
        log(f"== {pool.name}: final map {pool.final_error:.4f} direct, "
            f"{pool.final_error_sym:.4f} symmetry-aware")
        log("  chosen | source | error | error (sym-aware) | distortion | energy | curvature | "
            "orientation | wanted | decision score | rigidity")
        for i, c in enumerate(pool.candidates):
            row = {"pair": pool.name, "source": c.source, "error": pool.errors[i],
                   "error_sym": pool.errors_sym[i], "distortion": c.distortion,
                   "energy": c.refined_energy, "curvature": c.curvature_disagreement,
                   "orientation": c.refined_orientation,
                   "wanted": not c.unwanted, "decision_score": decision_score(c),
                   "rigidity": c.rigidity, "chosen": i == pool.chosen_index}
            rows.append(row)
            mark = "*" if row["chosen"] else " "
            log(f"  {mark} | {c.source} | {row['error']:.4f} | {row['error_sym']:.4f} | {c.distortion:.4f} | "
                f"{c.refined_energy:.4f} | {c.curvature_disagreement:.4f} | {c.refined_orientation:+.3f} | "
                f"{'yes' if row['wanted'] else 'no'} | {row['decision_score']:.6f} | "
                f"{'—' if c.rigidity is None else f'{c.rigidity:.4f}'}")
    return rows


def _run(args: argparse.Namespace) -> int:
    from geoshape.errors import InvalidOptionError

    flags = (("--sensitivity", "sensitivity"), ("--decision-weights", "decision_weights"))
    suite_only = [flag for flag, attr in flags if getattr(args, attr, False)]
    if suite_only and not args.suite:
        raise InvalidOptionError(f"{suite_only[0]} needs --suite generalization")
    seeds = getattr(args, "seeds", 0) or 0
    if not 0 <= seeds <= MAX_SEED_DRAWS:
        raise InvalidOptionError(f"--seeds must be a count from 0 to {MAX_SEED_DRAWS}, got {seeds}")
    if seeds and not getattr(args, "sensitivity", False):
        raise InvalidOptionError("--seeds adds rows to the sensitivity table: it needs --sensitivity")
    if (getattr(args, "fields", None) or "").strip().lower() == "none" and not seeds:
        raise InvalidOptionError("--fields none leaves only the default row: give --seeds N too")
    reports = suite_only + ["--candidates"] * bool(getattr(args, "candidates", None))
    if len(reports) > 1:
        raise InvalidOptionError(f"{' and '.join(reports)} each make a different report: give one")
    if getattr(args, "candidates", None):
        return _run_candidates(args)
    if args.suite:
        from geoshape.bench.correspondence_suite import run_suite

        return run_suite(args)
    folder = _dataset_dir(args)
    from geoshape.bench.experiments._common import machine_note
    from geoshape.bench.results import markdown_table, update_results_section
    from geoshape.io.datasets import scape_feature_points
    from geoshape.plot.correspondence import plot_error_curves

    args.methods = args.methods or DEFAULT_METHODS
    methods = peer_methods([m for m in args.methods.split(",") if m], args.peer)
    results, has_sym = evaluate_pairs(folder, args.pairs, methods, limit=args.limit,
                                      landmarks=args.landmarks, seed=args.seed,
                                      log=lambda text: print(text, flush=True))
    feature_points = scape_feature_points(folder)
    ok = [r for r in results if r.error is None]
    errs = {m: [r.errors for r in ok if r.method == m] for m in methods}
    errs_sym = {m: [r.errors_sym for r in ok if r.method == m] for m in methods}
    times = {m: [r.seconds for r in ok if r.method == m] for m in methods}
    failures = {m: sum(r.error is not None and r.method == m for r in results) for m in methods}
    header = ["method", "mean error", "mean error (sym-aware)"]
    header += [f"≤ {t} (%)" for t in THRESHOLDS] + ["median s/pair", "pairs", "failed"]
    rows = []
    for m in methods:
        if not errs[m]:
            rows.append([m] + ["—"] * (len(header) - 3) + [0, failures[m]])
            continue
        e = np.concatenate(errs[m])
        per_pair = [x.mean() for x in errs[m]]
        per_pair_sym = [x.mean() for x in errs_sym[m]]
        es = np.concatenate(errs_sym[m])
        row = [m, float(np.mean(per_pair)), float(np.mean(per_pair_sym)) if has_sym else "—"]
        row += [f"{100 * np.mean(e <= t):.1f}" + (f" ({100 * np.mean(es <= t):.1f})" if has_sym else "")
                for t in THRESHOLDS]
        row += [float(np.median(times[m])), len(errs[m]), failures[m]]
        rows.append(row)
    table = markdown_table(header, rows)
    ratio = ""
    if "pyfm" in methods and errs.get("geoshape") and errs["pyfm"]:
        g_err = np.mean([x.mean() for x in errs["geoshape"]])
        p_err = np.mean([x.mean() for x in errs["pyfm"]])
        g_t, p_t = np.median(times["geoshape"]), np.median(times["pyfm"])
        ratio = (f"\ngeoshape / pyFM: mean direct error ratio {g_err / p_err:.3f}, "
                 f"median time ratio {g_t / p_t:.3f}\n")
    set_name = f"{folder.name}/{args.pairs}" + (f" (first {args.limit})" if args.limit else "")
    cmd = (f"geoshape bench correspondence {args.dir} --pairs {args.pairs}"
           + (f" --limit {args.limit}" if args.limit else "")
           + f" --methods {args.methods} --peer {args.peer} --landmarks {args.landmarks}")
    sym_note = ("symmetry-aware on the 36 SCB feature points" if feature_points is not None
                else "symmetry-aware: per pair the better of direct and mirrored ground truth")
    text = (f"### 3D correspondence — {set_name}\n\nCommand: `{cmd}`. Errors: geodesic distance / √area on "
            f"the target, mean over pairs of the per-pair mean ({sym_note}); ≤ t: share of landmarks "
            f"(direct, in parentheses symmetry-aware). Times: end to end per pair, {process_note()} "
            f"({machine_note()}; a method and its peer ran in turn on each pair, under the same load)."
            f"\n\n{table}\n{ratio}")
    print(text)
    plot = args.plot
    if plot is None and not args.no_results:
        plot = Path(__file__).resolve().parents[2] / "docs" / "img" / f"correspondence_{folder.name}.png"
    if plot:
        curves = {m: np.concatenate(errs[m]) for m in methods if errs[m]}
        plot_error_curves(curves, plot, title=f"Geodesic error — {folder.name}")
        text += f"\n![cumulative error](img/{Path(plot).name})\n"
    if not args.no_results:
        section = args.section or f"correspondence-{folder.name}-{Path(args.pairs).stem}"
        update_results_section(section, text)
    return 0


def _dataset_dir(args: argparse.Namespace) -> Path:
    """DIR of a run without ``--suite``; exits with a usage message when it is missing."""
    if args.dir is None:
        raise SystemExit("geoshape bench correspondence: DIR is required (or --suite generalization)")
    return Path(args.dir)


def _run_candidates(args: argparse.Namespace) -> int:
    """``--candidates``: :func:`candidate_report` on DIR, or with ``--suite`` on every selected dev set."""
    names = [n.strip() for n in args.candidates.split(",") if n.strip()]
    log = lambda text: print(text, flush=True)  # noqa: E731
    if args.suite:
        from geoshape.bench.correspondence_suite import prepared_sets

        targets = [(folder, spec.pairs_file) for spec, folder in prepared_sets(args, log)]
    else:
        targets = [(_dataset_dir(args), args.pairs)]
    found = 0
    for folder, pairs_file in targets:
        found += len(candidate_report(folder, pairs_file, names, landmarks=args.landmarks, seed=args.seed,
                                      log=log))
    if not found:
        from geoshape.errors import InvalidOptionError

        raise InvalidOptionError(f"--candidates {args.candidates!r}: no pair name contains any of {names}")
    return 0
