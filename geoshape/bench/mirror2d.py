"""``geoshape bench mirror2d``: the default 2D method with and without mirror images, on every
dev collection, and the setting chosen by a rule stated before measuring.

A silhouette and its reflection are the same shape for retrieval. With ``mirror`` the
distance of a pair is the better of the matchings against the shape and against its mirror
image (:func:`geoshape.contour.methods.pair_costs`); the cyclic DP's ``n_starts`` counts per
orientation (the best ``2·n_starts`` starts, ranked over both orientations together), so the
settings measured are

- ``off``: the direct orientation only, 4 starts (the default before 2026-12-01);
- ``on-2``: both orientations, ``n_starts=2``: 4 starts in all (the DP work of ``off``);
- ``on``: both orientations, ``n_starts=4``: 8 starts in all (the default of 2026-12-01);
- ``on-16``: both orientations, ``n_starts=16``: 32 starts in all (the default's count since 2026-12-05,
  chosen with ``--methods``: "2D default method: cross-validated choice").

Collections: ``kimia99``, ``tari1000``, ``generated`` (seeded silhouette generator,
6 classes × 12) and ``<set>-<kind>`` = ``geoshape gen perturb2d <set> --kind <kind> --seed 0``
(folders and matrices cached in ``--matrix-dir``, as ``geoshape bench rerank`` does). The
descriptors are computed once per collection (the mirror images' once more, timed apart);
each setting's all-pairs matrix is timed on its own.

Rule (fixed before the run): a setting whose total matrix CPU time (user + system seconds, the
workers' included: the work done, less sensitive than wall time to other jobs on the
machine; wall time if any matrix was cached before CPU seconds were recorded, or matrices were
computed with different worker counts, and the section says which; the first matrix timed in a
process follows an untimed warm-up, so none pays for loading the compiled kernels) exceeds
twice that of ``off`` is not eligible; among the others, the one with the best *worst-case*
bull's-eye over the collections wins (so no collection decides alone); ties within 0.05 points
go to the higher mean mAP, then to the cheaper setting.

With ``--methods M1,M2,…`` registered methods are compared instead (each as registered, mirror
included), under the same rule with ``M1`` as the time reference; the table goes into its own
section (``default2d``) of docs/RESULTS.md. This is how candidates for ``default`` (for example
``default_hf``: the default plus height functions) are cross-validated.
"""

from __future__ import annotations

from typing import NamedTuple

from geoshape.bench.method_variants import effective_spec, matrix_cache_name, parse_variant, variant_tracing

HELP = "default 2D method with and without mirror images on every dev collection; rule-based choice"

DEFAULT_SETS = (
    "kimia99,tari1000,generated,kimia99-mirror,kimia99-noise,kimia99-notch,kimia99-erode,"
    "tari1000-mirror,tari1000-noise"
)
#: name -> (mirror, n_starts per orientation)
SETTINGS = {"off": (False, 4), "on-2": (True, 2), "on": (True, 4), "on-16": (True, 16)}
#: Candidates for ``default`` compared with ``--methods`` (the first is the time reference).
DEFAULT_CANDIDATES = "default_2026_11,default_hf"
#: A setting may cost at most this many times the matrix CPU time of the reference (wall time if
#: any matrix was cached before CPU seconds were recorded).
MAX_TIME_RATIO = 2.0
#: Worst-case bull's-eye values closer than this (points) are a tie.
TIE_POINTS = 0.05


def add_arguments(parser) -> None:
    parser.add_argument("--matrix-dir", required=True,
                        help="folder for derived collections and cached matrices (+ their times)")
    parser.add_argument("--sets", default=DEFAULT_SETS,
                        help="comma-separated set names, or NAME=FOLDER for a folder with labels.csv "
                        f"(default {DEFAULT_SETS})")
    parser.add_argument("--settings", default=",".join(SETTINGS),
                        help=f"comma-separated settings among: {', '.join(SETTINGS)} (default: all)")
    parser.add_argument("--methods", default=None,
                        help="compare these registered methods instead of mirror settings; the "
                        "first is the time reference of the rule (e.g. "
                        f"{DEFAULT_CANDIDATES})")
    parser.add_argument("--section", default=None,
                        help="docs/RESULTS.md section to write with --methods (default default2d, "
                        "the cross-validated choice; another name keeps that table and adds one)")
    parser.add_argument("--n-jobs", type=int, default=None, help="workers (default: all cores)")
    parser.add_argument("--no-write", action="store_true", help="print only")


def _slug(setting: str) -> str:
    return "mirror-" + setting


def choose(summary: dict, reference: str = "off") -> str:
    """The setting the rule picks from ``{setting: (worst bull's-eye, mean mAP, matrix cost)}``
    (the cost in CPU seconds where measured, else wall seconds).

    ``reference`` (default ``off``) must be present: it is the time reference.

    >>> choose({"off": (90.0, 0.9, 10.0), "on": (95.0, 0.91, 15.0), "slow": (99.0, 0.99, 30.0)})
    'on'
    >>> choose({"off": (95.0, 0.92, 10.0), "on": (95.02, 0.91, 15.0)})
    'off'
    """
    limit = MAX_TIME_RATIO * summary[reference][2]
    eligible = {s: v for s, v in summary.items() if v[2] <= limit}
    top = max(v[0] for v in eligible.values())
    tied = {s: v for s, v in eligible.items() if v[0] >= top - TIE_POINTS}
    return min(tied, key=lambda s: (-tied[s][1], tied[s][2]))


class _Score(NamedTuple):
    """One matrix's scores on its collection and its times (``matrix_cpu_s``: None if cached
    before CPU seconds were recorded)."""

    top_k: int
    top_k_max: int
    bulls_eye: float
    map: float
    descriptors_s: float
    matrix_s: float
    matrix_cpu_s: float | None


#: Whether this process has run the untimed warm-up of :func:`_timed_matrix`.
_WARMED_UP = False


def _timed_matrix(sigs, method: str, n_jobs, **options):
    """``(D, info)``: the all-pairs matrix of ``sigs`` for ``method`` with ``options``, and its
    wall and CPU seconds (user + system, the pool's workers included), the worker count and the
    load average after it. The first call in a process runs the same computation on a few
    shapes first, untimed, so that no timed matrix pays for compiling or loading the kernels."""
    import os
    import time

    from geoshape.bench.timing import cpu_seconds
    from geoshape.contour.retrieval import shape_distance_matrix

    global _WARMED_UP
    if not _WARMED_UP:
        shape_distance_matrix(None, method, signatures=sigs[:8], n_jobs=n_jobs, **options)
        _WARMED_UP = True
    t0, cpu0 = time.perf_counter(), cpu_seconds()
    D = shape_distance_matrix(None, method, signatures=sigs, n_jobs=n_jobs, **options)
    info = {"matrix_s": time.perf_counter() - t0, "matrix_cpu_s": cpu_seconds() - cpu0,
            "workers": n_jobs or os.cpu_count(), "load": os.getloadavg()[0]}
    return D, info


def _collection(name: str, folder, work, settings: list[str], n_jobs) -> dict:
    """Per setting: the matrix, its time, and the descriptors' time (cached in ``work``)."""
    import dataclasses
    import json
    import time

    import numpy as np

    from geoshape.contour.methods import contour_tracing
    from geoshape.contour.retrieval import contour_signatures, load_contours
    from geoshape.geometry.contour import mirror_contour
    from geoshape.io.atomic import save_npy_atomic, write_text_atomic
    from geoshape.io.datasets import read_labels

    items = read_labels(folder)
    out, sigs, desc = {}, None, {}
    for setting in settings:
        # keyed by what default computes (descriptors and tracing), like matrix_cache_name
        path = work / f"{matrix_cache_name(name, 'default')}-{_slug(setting)}.npy"
        meta = path.with_suffix(".json")
        if path.is_file() and meta.is_file():
            out[setting] = (np.load(path), json.loads(meta.read_text()))
            continue
        if sigs is None:
            contours = load_contours([it.path for it in items], **contour_tracing("default"))
            t0 = time.perf_counter()
            direct = contour_signatures(contours, "default", mirror=False, n_jobs=n_jobs)
            t1 = time.perf_counter()
            mirrored = contour_signatures([mirror_contour(P) for P in contours], "default",
                                          mirror=False, n_jobs=n_jobs)
            t2 = time.perf_counter()
            # the mirror image's direct descriptors are the mirror variant (height functions too)
            sigs = [dataclasses.replace(a, X_mirror=b.X, H_mirror=b.H)
                    for a, b in zip(direct, mirrored, strict=True)]
            desc = {"direct": t1 - t0, "mirror": t2 - t1}
        mirror, n_starts = SETTINGS[setting]
        print(f"[{name}] mirror {setting} …", flush=True)
        D, info = _timed_matrix(sigs, "default", n_jobs, mirror=mirror, n_starts=n_starts)
        info["descriptors_s"] = desc["direct"] + (desc["mirror"] if mirror else 0.0)
        save_npy_atomic(path, D)
        write_text_atomic(meta, json.dumps(info) + "\n")
        out[setting] = (D, info)
    return out


def _method_collection(name: str, folder, work, methods: list[str], n_jobs) -> dict:
    """Per registered method: the matrix, its time and the descriptors' time (cached)."""
    import json
    import time

    import numpy as np

    from geoshape.contour.retrieval import contour_signatures, load_contours
    from geoshape.io.atomic import save_npy_atomic, write_text_atomic
    from geoshape.io.datasets import read_labels

    out, contours = {}, {}
    for method in methods:
        base, n_points, overrides = parse_variant(method)
        tracing = variant_tracing(base, n_points, overrides)
        path = work / f"{matrix_cache_name(name, method)}.npy"
        meta = path.with_suffix(".json")
        if path.is_file() and meta.is_file():
            out[method] = (np.load(path), json.loads(meta.read_text()))
            continue
        key = tuple(tracing.values())
        if key not in contours:
            contours[key] = load_contours([it.path for it in read_labels(folder)], **tracing)
        print(f"[{name}] {method} …", flush=True)
        t0 = time.perf_counter()
        sigs = contour_signatures(contours[key], base, n_jobs=n_jobs, **overrides)
        descriptors_s = time.perf_counter() - t0
        D, info = _timed_matrix(sigs, base, n_jobs, **overrides)
        info["descriptors_s"] = descriptors_s
        save_npy_atomic(path, D)
        write_text_atomic(meta, json.dumps(info) + "\n")
        out[method] = (D, info)
    return out


def run(args) -> int:
    import os
    import platform
    import time
    from pathlib import Path

    import numpy as np

    from geoshape._options import check_choice
    from geoshape.bench.rerank import _folder
    from geoshape.bench.results import markdown_table, update_results_section, workers_note
    from geoshape.bench.retrieval2d import points_note
    from geoshape.contour.methods import CONTOUR_METHODS
    from geoshape.io.datasets import read_labels
    from geoshape.metrics.retrieval import retrieval_metrics

    if args.methods:
        settings = [m.strip() for m in args.methods.split(",") if m.strip()]
        for m in settings:
            check_choice("method", parse_variant(m)[0], CONTOUR_METHODS)
        reference = settings[0]
    else:
        settings = [s.strip() for s in args.settings.split(",") if s.strip()]
        for s in settings:
            check_choice("setting", s, SETTINGS)
        if "off" not in settings:
            settings.insert(0, "off")  # the time reference of the rule
        reference = "off"
    work = Path(args.matrix_dir)
    work.mkdir(parents=True, exist_ok=True)
    scores: dict[tuple[str, str], _Score] = {}  # (collection, setting) -> its scores and times
    workers_seen: set = set()
    names, loads = [], []
    for item in args.sets.split(","):
        name, _, spec = item.strip().partition("=")
        folder = _folder(name, spec, work)
        labels = [it.label for it in read_labels(folder)]
        names.append((name, len(labels)))
        per = (_method_collection(name, folder, work, settings, args.n_jobs) if args.methods
               else _collection(name, folder, work, settings, args.n_jobs))
        for setting, (D, info) in per.items():
            m = retrieval_metrics(D, labels)
            scores[name, setting] = _Score(m["top_k_total"], m["top_k_max"], m["bulls_eye"], m["map"],
                                           info["descriptors_s"], info["matrix_s"],
                                           info.get("matrix_cpu_s"))
            loads.append(info.get("load", float("nan")))
            cpu = info.get("matrix_cpu_s")
            print(f"  {name} {setting}: top-10 {m['top_k_total']}/{m['top_k_max']}, bull's-eye "
                  f"{m['bulls_eye']:.2f} %, mAP {m['map']:.4f}, matrix {info['matrix_s']:.1f} s"
                  + ("" if cpu is None else f" ({cpu:.1f} CPU s)"), flush=True)
            workers_seen.add(info.get("workers"))

    col = "method" if args.methods else "mirror"
    rows = []
    for name, n in names:
        base = name.rpartition("-")[0]
        for setting in settings:
            sc = scores[name, setting]
            row = [name, n, setting, f"{sc.top_k}/{sc.top_k_max}", f"{sc.bulls_eye:.2f}",
                   f"{sc.map:.4f}", f"{sc.descriptors_s:.1f}", f"{sc.matrix_s:.1f}"]
            if args.methods:  # bull's-eye points below the clean collection's
                clean = scores.get((base, setting))
                row.insert(5, f"{sc.bulls_eye - clean.bulls_eye:+.2f}" if clean else "")
            rows.append(row)
    header = [col, "top-10 total", "bull's-eye %", "mAP", "descriptors s", "all-pairs matrix s"]
    if args.methods:
        header.insert(3, "BE − clean")
    table = markdown_table(["collection", "N", *header], rows)
    # Mean rank over collections (1 = best bull's-eye; ties share the mean rank).
    ranks = {s: [] for s in settings}
    for name, _ in names:
        be = np.array([scores[name, s].bulls_eye for s in settings])
        for s, b in zip(settings, be, strict=True):
            ranks[s].append(1.0 + (be > b + 1e-9).sum() + 0.5 * ((np.abs(be - b) <= 1e-9).sum() - 1))
    # The budget counts CPU seconds (the work, whatever shares the machine) when every matrix
    # has them and all were computed with one worker count (each pool's start-up is counted);
    # matrices cached before they were recorded have wall seconds only.
    counts = workers_seen - {None}
    on_cpu = all(v.matrix_cpu_s is not None for v in scores.values()) and len(counts) <= 1
    wall = {s: sum(scores[name, s].matrix_s for name, _ in names) for s in settings}
    cpu = {s: sum(scores[name, s].matrix_cpu_s for name, _ in names) for s in settings} if on_cpu else None
    summary = {}
    for s in settings:
        vals = [scores[name, s] for name, _ in names]
        summary[s] = (min(v.bulls_eye for v in vals), float(np.mean([v.map for v in vals])),
                      (cpu or wall)[s])
    chosen = choose(summary, reference)
    ref_cost = summary[reference][2]
    worst = {s: min(names, key=lambda nn, s=s: scores[nn[0], s].bulls_eye)[0] for s in settings}
    sum_rows = [[s, f"{summary[s][0]:.2f} ({worst[s]})",
                 f"{np.mean([scores[n, s].bulls_eye for n, _ in names]):.2f}", f"{summary[s][1]:.5f}",
                 f"{np.mean(ranks[s]):.2f}", f"{wall[s]:.1f}", f"{cpu[s]:.1f}" if cpu else "—",
                 f"{summary[s][2] / ref_cost:.2f}", "**chosen**" if s == chosen else ""]
                for s in settings]
    sum_table = markdown_table([col, "worst bull's-eye % (collection)", "mean bull's-eye %",
                                "mean mAP", "mean rank", "matrix s, all collections",
                                "matrix CPU s, all collections",
                                f"× {reference} ({'CPU' if cpu else 'wall'})", "rule"], sum_rows)
    budget = ("CPU time (user + system, workers included)" if cpu else
              "wall time (cached matrices without CPU seconds)" if len(counts) <= 1 else
              f"wall time (cached matrices computed with {sorted(counts)} workers)")
    workers = args.n_jobs or os.cpu_count()
    if args.methods:
        text = _methods_section(args, settings, reference, chosen, workers, loads, table,
                                sum_table, budget)
        print(text)
        if not args.no_write:
            update_results_section(args.section or "default2d", text)
        return 0
    spec = CONTOUR_METHODS["default"]
    library = next((s for s, v in SETTINGS.items()
                    if v == (spec["mirror"], spec["matcher_options"]["n_starts"])), "other")
    text = (
        "## 2D mirror-aware matching (default method)\n\n"
        f"Command: `geoshape bench mirror2d --matrix-dir DIR --sets {args.sets} --settings "
        f"{','.join(settings)}` ({time.strftime('%Y-%m-%d')}, {points_note(None, 'default')}, processes, "
        f"{workers_note(workers)}, {platform.machine()}; shared with other jobs, 1-min load average "
        f"{min(loads):.1f}–{max(loads):.1f} after each matrix, so wall times are upper bounds). "
        "`generated` is the seeded silhouette generator (6 classes × 12); `SET-KIND` is "
        "`geoshape gen perturb2d SET --kind KIND --seed 0` "
        "(`mirror`: every other shape flipped left-right). Settings: `off` matches the direct "
        "orientation only (4 cyclic-DP starts: the default before 2026-12-01); `on` also the "
        "mirror image, 4 starts per orientation (the best 8, ranked over both orientations "
        "together); `on-2` 2 per orientation (4 in all: the DP work of `off`, plus one more "
        "cost-matrix product and start ranking); `on-16` 16 per orientation (32 in all). "
        "'descriptors s' includes the mirror images' descriptors "
        "when on; 'all-pairs matrix s' is the matching alone.\n\n"
        f"Rule, fixed before the run: a setting whose matrix {budget} summed over the collections is "
        f"above {MAX_TIME_RATIO:g} × that of `off` is not eligible; of the others the best "
        f"*worst-case* bull's-eye over the collections wins (ties within {TIE_POINTS} points: "
        "higher mean mAP, then cheaper). Mean rank is shown for reference (1 = best bull's-eye on "
        f"a collection). Chosen: `{chosen}`; library default of `default`: `{library}` "
        "(`mirror=False` in the Python API turns it off; `--method default_nomirror` on the "
        "command line).\n\n" + table + "\n\n" + sum_table
    )
    print(text)
    if not args.no_write:
        update_results_section("mirror2d", text)
    return 0


def _methods_section(args, methods, reference, chosen, workers, loads, table, sum_table, budget) -> str:
    import platform
    import time

    from geoshape.bench.results import workers_note
    from geoshape.contour.methods import CONTOUR_METHODS, contour_tracing
    from geoshape.geometry.contour import N_POINTS

    def spec(m):
        return CONTOUR_METHODS[parse_variant(m)[0]]

    def described(key, value):
        if key == "parts":
            return f", weights {', '.join(f'{p[0]} {p[1]:g}' for p in value)} instead"
        if key == "heights":
            return (f", heights term weight {value['weight']:g}, skip cost {value['skip_cost']:g}, "
                    f"{value['descriptor']['n_groups']} runs, every {value['step']} points"
                    f"{' of every sampling phase' if value.get('all_phases') else ''}, "
                    f"{value['n_starts']} starts per orientation instead")
        if key == "spread_power":
            return f", main term divided by the pair's mean descriptor spread to the power {value:g}"
        if key == "region":
            return (f", region term weight {value['weight']:g}, Zernike orders up to {value['order']}, "
                    f"disc of {value['radius']:g} equal-area radii instead")
        return f", {key} {value:g} instead"

    def extra(m):
        _, n, over = parse_variant(m)
        return f", {n} contour points" + "".join(described(k, v) for k, v in over.items())

    what = "\n".join(f"- `{m}`: {spec(m)['summary']}{extra(m)}" for m in methods)
    default = effective_spec("default")
    same = [m for m in methods if effective_spec(m) == default]
    section = args.section or "default2d"
    title = "" if section == "default2d" else f" ({section})"
    option = "" if section == "default2d" else f" --section {section}"
    return (
        f"## 2D default method: cross-validated choice{title}\n\n"
        f"Command: `geoshape bench mirror2d --matrix-dir DIR --sets {args.sets} --methods "
        f"{','.join(methods)}{option}` ({time.strftime('%Y-%m-%d')}, processes, "
        f"{workers_note(workers)}, {platform.machine()}; shared with other jobs, 1-min load average "
        f"{min(loads):.1f}–{max(loads):.1f} after each matrix, so wall times are upper bounds; "
        "`METHOD@N`: the method on N contour points instead of its own ("
        f"{contour_tracing('default')['n_points']} for default, "
        f"{contour_tracing('default_128pt')['n_points']} for default_128pt, "
        f"{N_POINTS} for most others); "
        "`+skipX`: DP skip cost X; "
        "`+startsK`: K cyclic-DP starts per orientation; `+wNAME=X`: weight X of descriptor part "
        "NAME; `+partsX`: the contour tracer joins components of ≥ X × the largest one's area; "
        "`+smoothX`: it smooths the boundary by a Gaussian of X × the perimeter; `+spreadX`: the "
        "main term divided by the pair's mean descriptor spread to the power X; `+hweight=X`, "
        "`+hskip=X`, `+hgroups=K`, `+hstep=K`, `+hstarts=K`: that setting of the method's "
        "height-functions term; `+rweight=X`, `+rorder=K`, `+rradius=X`: that setting of its "
        "region term). "
        "Collections as in the mirror-aware section above. 'BE − clean': bull's-eye points "
        "relative to the unperturbed collection (the target is within 1.5 points).\n\n"
        f"Candidates:\n\n{what}\n\n"
        f"Rule, fixed before the run: a method whose matrix {budget} summed over the collections is "
        f"above {MAX_TIME_RATIO:g} × that of `{reference}` is not eligible; of the others the best "
        f"*worst-case* bull's-eye over the collections wins (ties within {TIE_POINTS} points: "
        f"higher mean mAP, then cheaper). Chosen: `{chosen}`; `default` is currently the same "
        f"as: {', '.join(f'`{m}`' for m in same) or 'none of these'}.\n\n"
        + table + "\n\n" + sum_table
    )
