"""``geoshape bench correspondence --suite generalization``: every dev set of issue #14, one table.

The sets: the shared ``tosca_r5k`` (``pairs_subset.csv``), ``scape`` and ``tosca_hires``; and,
generated reproducibly into ``--dev-dir`` (reused when their ``generator.json`` records the same
parameters), remeshed SCAPE and remeshed TOSCA r5k (``gen remesh-set``, 30 pairs, 5000 vertices,
seed 0; remeshed SCAPE scored on its snapped feature points, ``pairs_features.csv``, like SCAPE)
the non-isometric family (``gen nonisometric``, 30 pairs, seed 0) and its remeshed copy
(``nonisometric_r5k``: both meshes of every pair remeshed on their own, so the two characters
share no connectivity, as the unseen non-isometric pairs do not), and ape-like against
human-like bipeds (``nonisometric_ape``: ``gen nonisometric --families biped=ape-like:human-like``,
30 pairs, seed 0) with its remeshed copy (``nonisometric_ape_r5k``). Every pair is run and
scored by :func:`geoshape.bench.correspondence.evaluate_pairs` (the bench's one per-pair
evaluation); this module adds only the orchestration, the per-set metrics and the tables.

Per set and method: pairs; mean direct and symmetry-aware error (÷ √area, mean over pairs of
the per-pair mean); median pair error (direct); share of landmarks within 0.025 and 0.05
(direct); failures — pairs whose mean direct error exceeds 0.1, plus pairs on which the method
raised; flips — failures whose symmetry-aware error is under half the direct one (a
left/right swap, not a lost map); median seconds per pair. ``--sensitivity`` reruns the
``geoshape`` method with each numeric default of
:class:`~geoshape.correspondence.pipeline.GeoshapeOptions` (``SENSITIVITY_FIELDS``) ×0.5 and ×2
and reports the mean direct error per set; ``--seeds N`` adds N rows of the default with other
sampling seeds and their range per set, the noise those rows are read against (``--fields none``:
only those). ``--decision-weights`` runs the method once per pair,
keeps every refined candidate with its errors, and re-takes the decision with each exponent of
:func:`~geoshape.correspondence.pipeline.decision_score` halved, doubled and left out.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

SECTION = "correspondence-generalization"
SENSITIVITY_SECTION = "correspondence-sensitivity"
DECISION_WEIGHTS_SECTION = "correspondence-decision-weights"
FAILURE_ERROR = 0.1
"""A pair whose mean direct error (÷ √area) exceeds this is a failure."""
FLIP_RATIO = 0.5
"""A failure whose symmetry-aware error is under this × its direct error is a flip."""
SUITE_THRESHOLDS = (0.025, 0.05)
DEV_PAIRS, DEV_SEED, DEV_VERTICES = 30, 0, 5000
SENSITIVITY_FIELDS = (
    "n_keep", "n_refine", "distinct_spacing", "icp_iterations", "n_controls", "lb_k", "screen_k",
    "screen_samples", "zoomout_samples", "descriptor_k", "distortion_samples", "distortion_power",
    "repair_landmarks", "final_k", "final_vertices_per_eigenpair", "final_step", "soft_temperature",
    "soft_rings", "rigidity_patch",
)
"""Numeric defaults varied by ``--sensitivity``. Left out: ``k`` (the exhaustive order search
grows as k!·2^k, ×2 is intractable), ``zoomout_start`` / ``zoomout_step`` (the schedule between
fixed end sizes), ``n_samples`` (None: the embedding's own default) and ``seed``."""
SENSITIVITY_FACTORS = (0.5, 2.0)


@dataclass(frozen=True)
class DevSet:
    """One set of the suite: a shared dataset folder, or a generated one."""

    name: str
    pairs_file: str
    dataset: str | None = None
    """Folder name under the data root (shared sets)."""
    generator: str | None = None
    """``"remesh"`` or ``"nonisometric"`` (generated sets)."""
    params: dict = field(default_factory=dict)
    """Generator keyword arguments, as recorded in ``generator.json``."""


def _remeshed(dataset: str, **extra) -> dict:
    """Generator parameters of a dev set remeshed from ``dataset`` (``gen remesh-set``)."""
    return {"dataset": dataset, **extra, "pairs": DEV_PAIRS, "vertices": DEV_VERTICES, "seed": DEV_SEED,
            "iterations": 6}


def _nonisometric(**extra) -> dict:
    """Generator parameters of a non-isometric dev set (``gen nonisometric``)."""
    return {"pairs": DEV_PAIRS, "seed": DEV_SEED, "target_vertices": DEV_VERTICES, "templates": 3,
            "resolution": 128, "variation": 0.1, "jitter": 0.04, "amount": 1.0, **extra}


DEV_SETS = (
    DevSet("tosca_r5k", "pairs_subset.csv", dataset="tosca_r5k"),
    DevSet("scape", "pairs.csv", dataset="scape"),
    DevSet("tosca_hires", "pairs.csv", dataset="tosca_hires"),
    DevSet("scape_r5k", "pairs_features.csv", generator="remesh", params=_remeshed("scape")),
    DevSet("tosca_r5k_r5k", "pairs.csv", generator="remesh",
           params=_remeshed("tosca_r5k", pairs_file="pairs_subset.csv")),
    DevSet("nonisometric", "pairs.csv", generator="nonisometric", params=_nonisometric()),
    # the non-isometric family with both meshes of each pair remeshed on their own: no shared
    # connectivity, as between two characters modelled apart
    DevSet("nonisometric_r5k", "pairs.csv", generator="remesh", params=_remeshed("nonisometric")),
    # gorilla-like against human-like bodies (the held-out non-isometric benchmark's kind of
    # pair), as generated and with both meshes remeshed on their own
    DevSet("nonisometric_ape", "pairs.csv", generator="nonisometric",
           params=_nonisometric(classes=["biped"], paired_families={"biped": ["ape-like", "human-like"]})),
    DevSet("nonisometric_ape_r5k", "pairs.csv", generator="remesh", params=_remeshed("nonisometric_ape")),
)


def default_dev_dir() -> Path:
    """``$XDG_CACHE_HOME/geoshape/dev-sets`` (or ``~/.cache/…``); a temp folder if not writable."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "geoshape" / "dev-sets"
    try:
        base.mkdir(parents=True, exist_ok=True)
        return base
    except OSError:
        return Path(tempfile.gettempdir()) / "geoshape-dev-sets"


def _matches(folder: Path, params: dict) -> bool:
    """Whether ``folder/generator.json`` records every one of ``params``."""
    try:
        recorded = json.loads((folder / "generator.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return all(recorded.get(k) == v for k, v in params.items())


def prepare_set(spec: DevSet, dev_dir: Path, log=print) -> Path:
    """The folder of ``spec``: the shared dataset, or the generated set (made if missing or stale)."""
    if spec.dataset is not None:
        from geoshape.io.datasets import data_root

        return data_root() / spec.dataset
    folder = dev_dir / spec.name
    if _matches(folder, spec.params):
        return folder
    log(f"generating {spec.name} into {folder} ({spec.params})")
    p = dict(spec.params)
    if spec.generator == "remesh":
        from geoshape_datasets_gen.remesh import write_remeshed_set

        source = p.pop("dataset")
        generated = {s.name: s for s in DEV_SETS if s.generator}
        if source in generated:  # a remeshed copy of another generated set: that one first
            source = prepare_set(generated[source], dev_dir, log)
        write_remeshed_set(source, folder, n_pairs=p.pop("pairs"), n_vertices=p.pop("vertices"),
                           **p)
    else:
        from geoshape_datasets_gen.nonisometric import write_nonisometric_set

        write_nonisometric_set(folder, n_pairs=p.pop("pairs"), **p)
    return folder


def set_metrics(results, has_sym: bool = True) -> dict:
    """Suite metrics of one method's :class:`PairResult` list on one set (see the module doc)."""
    ok = [r for r in results if r.error is None]
    crashed = len(results) - len(ok)
    out = {"pairs": len(results), "mean": float("nan"), "mean_sym": float("nan"), "median_pair": float("nan"),
           "failures": crashed, "flips": 0, "median_s": float("nan"), "crashed": crashed}
    for t in SUITE_THRESHOLDS:
        out[f"within_{t}"] = float("nan")
    if not ok:
        return out
    direct = np.array([r.mean for r in ok])
    sym = np.array([r.mean_sym for r in ok])
    fail = direct > FAILURE_ERROR
    errors = np.concatenate([r.errors for r in ok])
    out.update(mean=float(direct.mean()), mean_sym=float(sym.mean()) if has_sym else float("nan"),
               median_pair=float(np.median(direct)), failures=int(fail.sum()) + crashed,
               flips=int((fail & (sym < FLIP_RATIO * direct)).sum()) if has_sym else 0,
               median_s=float(np.median([r.seconds for r in ok])))
    for t in SUITE_THRESHOLDS:
        out[f"within_{t}"] = float(100 * np.mean(errors <= t))
    return out


def _fmt(x, pct: bool = False):
    if isinstance(x, float):
        if np.isnan(x):
            return "—"
        return f"{x:.1f}" if pct else x
    return x


def suite_table(rows: list[tuple[str, str, dict]]) -> str:
    """Markdown table: one row per (set, method, :func:`set_metrics`)."""
    from geoshape.bench.results import markdown_table

    header = ["set", "method", "pairs", "mean error", "mean error (sym-aware)", "median pair error"]
    header += [f"≤ {t} (%)" for t in SUITE_THRESHOLDS]
    header += [f"failures (> {FAILURE_ERROR})", "flips", "median s/pair"]
    body = []
    for name, method, m in rows:
        body.append([name, method, m["pairs"], _fmt(m["mean"]), _fmt(m["mean_sym"]), _fmt(m["median_pair"])]
                    + [_fmt(m[f"within_{t}"], pct=True) for t in SUITE_THRESHOLDS]
                    + [m["failures"], m["flips"], _fmt(m["median_s"])])
    return markdown_table(header, body)


def _named(flag: str, kind: str, label: str, names: str, valid: list[str]) -> list[str]:
    """The names of the comma-separated ``names``, each checked against ``valid`` (the error lists
    them); ``flag``, ``kind`` (what none was named) and ``label`` (what one is) word the
    messages. Shared by ``--sets`` and ``--fields``."""
    from geoshape._options import check_choice
    from geoshape.errors import InvalidOptionError

    wanted = [n.strip() for n in names.split(",") if n.strip()]
    if not wanted:
        raise InvalidOptionError(f"{flag} {names!r} names no {kind}; valid: {', '.join(valid)}")
    for name in wanted:
        check_choice(label, name, valid)
    return wanted


def sensitivity_fields(names: str | None) -> tuple[str, ...]:
    """The options named in the comma-separated ``names`` (all of ``SENSITIVITY_FIELDS`` when None),
    in table order; a name outside the table raises :class:`~geoshape.errors.InvalidOptionError`."""
    from geoshape.errors import InvalidOptionError

    if not names:
        return SENSITIVITY_FIELDS
    if names.strip().lower() == "none":  # only the seed rows of --seeds
        return ()
    wanted = _named("--fields", "option", "sensitivity field", names, list(SENSITIVITY_FIELDS) + ["none"])
    if "none" in wanted:
        raise InvalidOptionError(f"--fields none stands alone (only the --seeds rows), got {names!r}")
    return tuple(n for n in SENSITIVITY_FIELDS if n in wanted)


def sensitivity_variants(factors=SENSITIVITY_FACTORS, fields=SENSITIVITY_FIELDS) -> list[tuple[str, dict]]:
    """(label, geoshape options) for every one of ``fields`` × every factor."""
    from geoshape.correspondence.pipeline import GeoshapeOptions

    defaults = GeoshapeOptions()
    out = []
    for name in fields:
        value = getattr(defaults, name)
        for f in factors:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                continue
            new = value * f if isinstance(value, float) else max(int(round(value * f)), 1)
            GeoshapeOptions(**{name: new})  # checked now, not after an hour
            out.append((f"{name} {value} → {new} (×{f:g})", {name: new}))
    return out


def seed_variants(draws: int, base: int = 0) -> list[tuple[str, dict]]:
    """(label, geoshape options) with the method's sampling seed changed from ``base`` (the
    seed of the table's default row) to each of the ``draws`` smallest other seeds ≥ 0: another
    draw of every farthest-point start and random sample, every constant kept. The method's own
    sampling noise, against which a constant's ×0.5 / ×2 row can be read.

    >>> [o for _, o in seed_variants(2, base=1)]
    [{'seed': 0}, {'seed': 2}]
    """
    seeds = [s for s in range(draws + 1) if s != base][:draws]
    return [(f"seed {base} → {s} (another draw of every sampling)", {"seed": s}) for s in seeds]


def seed_range_row(means: list[list[float]], draws: int) -> list[str]:
    """The sensitivity table's last row: per set, the lowest and highest mean of the default
    row (``means[0]``) and the ``draws`` seed rows (the last ``draws`` rows of ``means``: per
    row, the mean direct error of each set, NaN where none ran), and the largest move of a draw
    from the default in per cent. A draw that raised on every pair (NaN) is left out of its
    set's range; a default that did leaves no move to report ("—")."""
    rows = np.asarray([means[0]] + means[len(means) - draws:], dtype=np.float64)
    cells = []
    for col in rows.T:
        base, others = col[0], col[1:][np.isfinite(col[1:])]
        if not np.isfinite(base) or not len(others):
            cells.append("—")
            continue
        move = np.max(np.abs(others / base - 1)) if base > 0 else float("nan")
        low, high = min(base, others.min()), max(base, others.max())
        cells.append(f"{low:.4g}–{high:.4g} (±{100 * move:.0f} %)")
    return [f"sampling noise: the default and {draws} other seeds, lowest–highest (largest move)"] + cells


def selected_sets(names: str | None) -> list[DevSet]:
    """The dev sets named in the comma-separated ``names`` (all when None), in suite order;
    an unknown name raises :class:`~geoshape.errors.InvalidOptionError` listing the valid ones."""
    if not names:
        return list(DEV_SETS)
    wanted = _named("--sets", "dev set", "dev set", names, [s.name for s in DEV_SETS])
    return [s for s in DEV_SETS if s.name in wanted]


def prepared_sets(args: argparse.Namespace, log) -> list[tuple[DevSet, Path]]:
    """``(spec, folder)`` of every dev set ``args.sets`` selects, generated into ``args.dev_dir``
    where missing (:func:`prepare_set`); names and ``args.fields`` are checked first."""
    specs = selected_sets(getattr(args, "sets", None))
    sensitivity_fields(getattr(args, "fields", None))  # a bad --fields fails before any generation
    dev_dir = Path(args.dev_dir) if args.dev_dir else default_dev_dir()
    return [(spec, prepare_set(spec, dev_dir, log)) for spec in specs]


def run_suite(args: argparse.Namespace) -> int:
    """The suite table (every dev set, the geoshape method and its peer), or with
    ``--sensitivity`` the sensitivity table instead (geoshape only, its own section)."""
    from geoshape.bench.correspondence import peer_methods

    log = lambda text: print(text, flush=True)  # noqa: E731
    sets = prepared_sets(args, log)
    if args.sensitivity:
        return _run_sensitivity(args, sets, log, sensitivity_fields(getattr(args, "fields", None)))
    if getattr(args, "decision_weights", False):
        return _run_decision_weights(args, sets, log)
    methods = peer_methods([m for m in (args.methods or "geoshape").split(",") if m], args.peer)
    return _run_table(args, sets, methods, log)


def _spread_note(limit) -> str:
    return f" (--limit: {limit} evenly spaced rows of each pairs file)" if limit else ""


def _set_list(sets) -> str:
    return ", ".join(f"{s.name} ({s.pairs_file})" for s, _ in sets)


def _sets_flag(args, sets) -> str:
    """`` --sets A,B`` as typed (empty when every set was run by default)."""
    return f" --sets {','.join(s.name for s, _ in sets)}" if getattr(args, "sets", None) else ""


def _limit_and_section_flags(args) -> str:
    """``--limit`` as typed, and ``--section`` when given (so the command rewrites the same section)."""
    section = f" --section {args.section}" if getattr(args, "section", None) else ""
    return (f" --limit {args.limit}" if args.limit else "") + section


def _mean_failures(mean: float, failures: int) -> str:
    """A sensitivity cell: ``"mean (failures)"``, the mean to 4 significant digits (— when none ran)."""
    return f"{mean:.4g} ({failures})" if np.isfinite(mean) else f"— ({failures})"


def _write(args, section: str, text: str) -> None:
    from geoshape.bench.results import update_results_section

    print(text)
    if not args.no_results:
        update_results_section(args.section or section, text)


def _run_table(args, sets, methods, log) -> int:
    from geoshape.bench.correspondence import env_prefix, evaluate_pairs, process_note
    from geoshape.bench.experiments._common import machine_note

    rows = []
    for spec, folder in sets:
        log(f"== {spec.name} ({folder}/{spec.pairs_file})")
        results, has_sym = evaluate_pairs(folder, spec.pairs_file, methods, limit=args.limit,
                                          landmarks=args.landmarks, seed=args.seed, spread=True,
                                          log=log)
        for m in methods:
            rows.append((spec.name, m, set_metrics([r for r in results if r.method == m], has_sym)))
    only, limit = _sets_flag(args, sets), _limit_and_section_flags(args)
    # the command as typed: pyFM is the default peer, not a method name
    given = f" --methods {args.methods}" if getattr(args, "methods", None) else ""
    peer = "" if getattr(args, "peer", "pyfm") == "pyfm" else f" --peer {args.peer}"
    cmd = (f"{env_prefix()}geoshape bench correspondence --suite generalization{only}{limit}{given}{peer} "
           f"--landmarks {args.landmarks}")
    text = (f"### 3D correspondence — generalization suite (issue #14)\n\nCommand: `{cmd}`. "
            f"Sets: {_set_list(sets)}{_spread_note(args.limit)}; "
            f"the generated ones ({DEV_PAIRS} pairs, {DEV_VERTICES} vertices, seed {DEV_SEED}) as in "
            f"docs/datasets.md \"Dev sets\". Errors: geodesic distance / √area on the target, mean over "
            f"pairs of the per-pair mean, direct and symmetry-aware (— where the set has no symmetric "
            f"ground truth; SCAPE and remeshed SCAPE are scored on their 36 feature points); median pair "
            f"error: median of the per-pair direct means; ≤ t: share of all landmarks (direct); failures: "
            f"pairs with mean direct error > {FAILURE_ERROR} (or an exception); flips: failures whose "
            f"symmetry-aware error is under {FLIP_RATIO:g} × the direct one. Times: end to end per pair; "
            f"{process_note()} ({machine_note()}).\n\n{suite_table(rows)}\n")
    _write(args, SECTION, text)
    return 0


def _run_sensitivity(args, sets, log, fields=SENSITIVITY_FIELDS) -> int:
    """Mean direct error (and failures) per set of the geoshape default and of each
    :func:`sensitivity_variants` of ``fields`` on the same ``--limit`` pairs per set;
    O(variants × sets × limit) pipeline runs."""
    from geoshape.bench.correspondence import evaluate_pairs
    from geoshape.bench.experiments._common import machine_note
    from geoshape.bench.results import markdown_table

    header = ["geoshape option"] + [s.name for s, _ in sets]
    only = _sets_flag(args, sets)
    if getattr(args, "fields", None):
        only += f" --fields {','.join(fields) or 'none'}"
    draws = getattr(args, "seeds", 0) or 0
    if draws:
        only += f" --seeds {draws}"
    body, means = [], []
    rows = [("default", {})] + sensitivity_variants(fields=fields) + seed_variants(draws, base=args.seed)
    for label, options in rows:
        log(f"== sensitivity: {label}")
        row, set_means = [label], []
        for spec, folder in sets:
            results, has_sym = evaluate_pairs(folder, spec.pairs_file, ["geoshape"], limit=args.limit,
                                              landmarks=args.landmarks, seed=args.seed, options=options,
                                              spread=True, log=log)
            m = set_metrics(results, has_sym)
            row.append(_mean_failures(m["mean"], m["failures"]))
            set_means.append(m["mean"])
        body.append(row)
        means.append(set_means)
    if draws:
        body.append(seed_range_row(means, draws))
    limit = _limit_and_section_flags(args)
    text = (f"### 3D correspondence — sensitivity of the geoshape defaults (issue #14)\n\n"
            f"Command: `geoshape bench correspondence --suite generalization --sensitivity{only}{limit} "
            f"--landmarks {args.landmarks}`. Sets: {_set_list(sets)}{_spread_note(args.limit)}. Mean direct "
            f"error per set (as in the generalization suite; in brackets the failures, pairs above "
            f"{FAILURE_ERROR}) of the geoshape method with one default changed ×0.5 and ×2 (counts "
            f"rounded, at least 1)"
            + (f"; then the default with the sampling seed changed (every constant kept), and the range "
               f"of the default and those {draws} draws: the noise a constant's row can be read against"
               if draws else "")
            + f" ({machine_note()}).\n\n"
            + markdown_table(header, body) + "\n")
    _write(args, SENSITIVITY_SECTION, text)
    return 0


def decision_weight_variants(factors=SENSITIVITY_FACTORS) -> list[tuple[str, tuple[float, ...]]]:
    """``(label, exponents)``: the exponents of :func:`~geoshape.correspondence.pipeline.decision_score`
    (``DECISION_FACTORS``: distortion, energy, curvature disagreement, orientation share) as
    they are, then each one ×``factors`` and left out (exponent 0), the others kept."""
    from geoshape.correspondence.pipeline import DECISION_EXPONENTS, DECISION_FACTORS

    out = [("default " + str(tuple(float(x) for x in DECISION_EXPONENTS)), tuple(DECISION_EXPONENTS))]
    for i, name in enumerate(DECISION_FACTORS):
        for f in (*factors, 0.0):
            e = list(DECISION_EXPONENTS)
            e[i] = DECISION_EXPONENTS[i] * f
            label = f"{name} left out (exponent 0)" if f == 0 else f"{name} exponent ×{f:g} ({e[i]:g})"
            out.append((label, tuple(e)))
    return out


def decided_index(pool, exponents) -> int:
    """Position in ``pool.candidates`` (a non-empty
    :class:`~geoshape.bench.correspondence.CandidatePool`) of the candidate
    :func:`~geoshape.correspondence.pipeline.decide` takes with ``exponents``. O(candidates)."""
    from geoshape.correspondence.pipeline import decide

    chosen = decide(pool.candidates, exponents=exponents)
    return next(i for i, c in enumerate(pool.candidates) if c is chosen)


def redecided_errors(pools, exponents) -> np.ndarray:
    """Per pool, the refined-map error of the candidate at :func:`decided_index` (NaN where the
    method raised)."""
    return np.array([p.errors[decided_index(p, exponents)] if p.candidates else np.nan for p in pools])


def weights_cell(errors: np.ndarray) -> str:
    """``"mean (failures)"`` of per-pair errors: the mean over pairs that ran, failures counting
    pairs above ``FAILURE_ERROR`` and pairs on which the method raised (NaN)."""
    ran = errors[np.isfinite(errors)]
    failures = int((ran > FAILURE_ERROR).sum()) + int(len(errors) - len(ran))
    return _mean_failures(float(ran.mean()) if len(ran) else float("nan"), failures)


def _run_decision_weights(args, sets, log) -> int:
    """``--decision-weights``: one pipeline run per pair keeps every refined candidate and its
    errors; the decision is then re-taken with each :func:`decision_weight_variants` (no re-run),
    and the mean direct error of the chosen refined maps and the failures are reported per set,
    with the best map in each pool as the ceiling. O(pairs × pipeline)."""
    from geoshape.bench.correspondence import candidate_pools, limited_pairs
    from geoshape.bench.experiments._common import machine_note
    from geoshape.bench.results import markdown_table
    from geoshape.correspondence.pipeline import DECISION_EXPONENTS
    from geoshape.io.datasets import read_pairs

    pools = {}
    for spec, folder in sets:
        log(f"== {spec.name} ({folder}/{spec.pairs_file})")
        pairs = limited_pairs(read_pairs(folder, spec.pairs_file), args.limit, spread=True)
        pools[spec.name] = []
        for i, pool in enumerate(candidate_pools(folder, pairs, landmarks=args.landmarks, seed=args.seed)):
            pools[spec.name].append(pool)
            log(f"[{i + 1}/{len(pairs)}] {pool.name}: {len(pool.candidates)} candidates, chosen "
                f"{pool.errors[pool.chosen_index]:.4f}, best {min(pool.errors):.4f}")
    # the default exponents must retake the pipeline's own decision on every pair
    ran = [p for ps in pools.values() for p in ps if p.candidates]
    agree = sum(decided_index(p, DECISION_EXPONENTS) == p.chosen_index for p in ran)
    crashed = sum(len(ps) for ps in pools.values()) - len(ran)
    body = [[label] + [weights_cell(redecided_errors(pools[s.name], e)) for s, _ in sets]
            for label, e in decision_weight_variants()]
    body.append(["best candidate in the pool (ceiling)"]
                + [weights_cell(np.array([min(p.errors) if p.candidates else np.nan for p in pools[s.name]]))
                   for s, _ in sets])
    factors = ", ".join(f"×{f:g}" for f in SENSITIVITY_FACTORS)
    exps = ", ".join(f"{e:g}" for e in DECISION_EXPONENTS)
    only, limit = _sets_flag(args, sets), _limit_and_section_flags(args)
    text = (f"### 3D correspondence — weights of the decision objective (issue #14)\n\n"
            f"Command: `geoshape bench correspondence --suite generalization --decision-weights{only}{limit} "
            f"--landmarks {args.landmarks}`. Sets: {_set_list(sets)}{_spread_note(args.limit)}. One run of "
            f"the geoshape method per pair keeps every refined candidate; the decision (wanted orientation "
            f"first, then the lowest distortion^a × energy^b × curvature disagreement^h ÷ orientation "
            f"share^c; default (a, b, h, c) = ({exps})) is re-taken with each exponent {factors} and 0, "
            f"the others at their default. Cells: "
            f"mean direct error of the chosen *refined* map (before the full-resolution stage; the suite "
            f"scores the final maps) and, in brackets, failures (pairs above {FAILURE_ERROR}, and pairs on "
            f"which the method raised: {crashed}). The default row retakes the pipeline's own choice on "
            f"{agree} of {len(ran)} pairs ({machine_note()}).\n\n"
            + markdown_table(["decision exponents", *[s.name for s, _ in sets]], body) + "\n")
    _write(args, DECISION_WEIGHTS_SECTION, text)
    return 0
