"""``geoshape bench fusion``: late fusion of 3D descriptors, fixed vs query-adaptive.

On ``tosca_r5k``, the generated articulated collection (as ``geoshape bench retrieval3d``
builds it) and two ``mixed3d`` collections (``geoshape_datasets_gen.mixed3d.write_collection``,
seeds 0 and 1, or ``--mixed DIR`` / ``--mixed-s1 DIR``), computes each component's all-pairs
matrix (cached as ``CACHE/<set>/<descriptor>.npz`` with keys ``D``, ``labels``, ``spm`` when
``--cache`` is given), then scores per collection: each single component, the fixed-weight
fusion, the uncalibrated adaptive rule of earlier versions (power 1, no reference gaps), the
library's calibrated query-adaptive fusion (:data:`geoshape.retrieval.fusion.FUSED_WEIGHTS`,
``FUSED_GAP_REFERENCE``, ``FUSED_POWER``), the leave-one-collection-out fusion (weights *and*
reference gaps chosen on the other collections, scored on this one) and the sensitivity of the
library setting (each weight ×0.5 / ×2, renormalised; k halved / doubled; power halved /
doubled) — NN, FT, ST, mAP, each without and with LCDP re-ranking. The library row is the
library's own ``fused`` method run on the collection (``retrieval3d_on_folder(DIR, "fused")``:
components computed together, one shared eigen-solve per mesh; cached as ``fused.npz`` with
its settings): its s / mesh is measured, and its matrix is checked against the fusion of the
cached component matrices. Writes section ``fusion`` of docs/RESULTS.md.
"""

from __future__ import annotations

HELP = "3D late fusion: single descriptors vs fixed / query-adaptive fusion, LOCO weights, sensitivity"

DEFAULT_SETS = "tosca_r5k,generated,mixed3d,mixed3d_s1"
DEFAULT_COMPONENTS = "evd_heat,shapedna,lfd,shd,wks,pcavox"
#: the row of the library's ``fused`` method
LIBRARY_ROW = "fusion, adaptive (library)"


def add_arguments(parser) -> None:
    parser.add_argument("--sets", default=DEFAULT_SETS,
                        help=f"comma-separated: tosca_r5k, generated, mixed3d (seed 0), mixed3d_s1 (seed 1) "
                        f"(default {DEFAULT_SETS})")
    parser.add_argument("--components", default=DEFAULT_COMPONENTS,
                        help=f"descriptors on the weight grid (default {DEFAULT_COMPONENTS})")
    parser.add_argument("--grid-step", type=float, default=0.125,
                        help="step of the weight grid (weights sum to 1; default 1/8)")
    parser.add_argument("--mixed", default=None, metavar="DIR",
                        help="existing mixed3d folder (default: generate one, seed 0, in a temp folder)")
    parser.add_argument("--mixed-s1", default=None, metavar="DIR",
                        help="existing mixed3d seed-1 folder (default: generate one in a temp folder)")
    parser.add_argument("--cache", default=None, metavar="DIR",
                        help="cache of component matrices, DIR/<set>/<descriptor>.npz (with --mixed M or "
                        "--mixed-s1 M, that set is cached under DIR/<name of M>/)")
    parser.add_argument("--n-jobs", type=int, default=None, help="workers (default: all cores)")
    parser.add_argument("--gen-poses", type=int, default=4, help="poses per generated instance")
    parser.add_argument("--gen-instances", type=int, default=2, help="instances per generated class")
    parser.add_argument("--timing-meshes", type=int, default=8, metavar="N",
                        help="tosca_r5k meshes (5000 vertices) timed one at a time on one core for the "
                        "library default's cost (default 8; 0: skip)")
    parser.add_argument("--no-write", action="store_true", help="print only")


def _cache_tag(set_name: str, args) -> str:
    from pathlib import Path

    if set_name == "mixed3d" and args.mixed:
        return Path(args.mixed).name
    if set_name == "mixed3d_s1" and args.mixed_s1:
        return Path(args.mixed_s1).name
    return set_name


def folder_flags(args) -> str:
    """The ``--mixed`` / ``--mixed-s1`` / ``--cache`` part of a bench command, folders as DIR."""
    flags = [("mixed", "--mixed"), ("mixed_s1", "--mixed-s1"), ("cache", "--cache")]
    return "".join(f" {flag} DIR" for name, flag in flags if getattr(args, name, None))


def _folder(set_name: str, tmp, args):
    from pathlib import Path

    from geoshape.io.datasets import dataset_dir

    if set_name == "generated":
        from geoshape.bench.retrieval3d import _generated

        return _generated(tmp, args)
    if set_name in ("mixed3d", "mixed3d_s1"):
        given = args.mixed if set_name == "mixed3d" else args.mixed_s1
        if given:
            return Path(given)
        from geoshape_datasets_gen.mixed3d import write_collection

        folder = tmp / set_name
        write_collection(folder, seed=0 if set_name == "mixed3d" else 1)
        return folder
    return dataset_dir(set_name)


def _component(set_name, comp, tmp, args, folders):
    """``(D, labels, seconds per mesh)`` of one component, from the cache or computed."""
    from pathlib import Path

    import numpy as np

    path = Path(args.cache) / _cache_tag(set_name, args) / f"{comp}.npz" if args.cache else None
    if path is not None and path.is_file():
        z = np.load(path)
        return z["D"], [str(x) for x in z["labels"]], float(z["spm"])
    from geoshape.retrieval.meshes import retrieval3d_on_folder

    if set_name not in folders:
        folders[set_name] = _folder(set_name, tmp, args)
    print(f"[{set_name}] {comp} …", flush=True)
    res = retrieval3d_on_folder(folders[set_name], comp, n_jobs=args.n_jobs, progress=False)
    D, labels, spm = res["D"], list(res["labels"]), float(res["seconds_per_mesh"][comp])
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, D=D, labels=np.array(labels), spm=spm)
    return D, labels, spm


def _library(set_name, tmp, args, folders):
    """``(D, labels, seconds per mesh)`` of the library's ``fused`` method (the default of
    ``geoshape retrieval3d``).

    The method computes its components together per mesh (one shared eigen-solve), takes each
    component's all-pairs matrix and fuses them; the cache keeps those component matrices
    (``fused_parts.npz``: ``D_<name>``, ``spm_<name>``, ``labels``), so a change of the fusion
    settings re-fuses them without recomputing descriptors (the fusion is exactly the method's
    last step, :func:`geoshape.retrieval.meshes.retrieval3d_matrix`)."""
    from pathlib import Path

    import numpy as np

    from geoshape.retrieval.descriptors import descriptor_distance_matrix, method_descriptors
    from geoshape.retrieval.fusion import FUSED_WEIGHTS, fuse_distances

    names = method_descriptors("fused")
    path = Path(args.cache) / _cache_tag(set_name, args) / "fused_parts.npz" if args.cache else None
    parts = None
    if path is not None and path.is_file():
        z = np.load(path)
        if all(f"D_{n}" in z.files for n in names):
            parts = ({n: z[f"D_{n}"] for n in names}, [str(x) for x in z["labels"]],
                     {n: float(z[f"spm_{n}"]) for n in names})
    if parts is None:
        from geoshape.retrieval.meshes import retrieval3d_on_folder

        if set_name not in folders:
            folders[set_name] = _folder(set_name, tmp, args)
        print(f"[{set_name}] fused (library) …", flush=True)
        res = retrieval3d_on_folder(folders[set_name], "fused", n_jobs=args.n_jobs, progress=False)
        parts = ({n: descriptor_distance_matrix(n, res["descriptors"][n]) for n in names},
                 list(res["labels"]), {n: float(res["seconds_per_mesh"][n]) for n in names})
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savez(path, labels=np.array(parts[1]), **{f"D_{n}": parts[0][n] for n in names},
                     **{f"spm_{n}": parts[2][n] for n in names})
    mats, labels, spm = parts
    D = fuse_distances(mats, {n: FUSED_WEIGHTS[n] for n in names})
    return D, labels, float(sum(spm.values()))


def _one_core_cost(n: int) -> dict:
    """The fused default's descriptor cost per tosca_r5k mesh on one core: components computed
    together (one shared eigen-solve) and, for comparison, each computed alone; CPU time of
    this process (single-thread BLAS, so it is one core's work whatever else runs) and wall."""
    import time

    from geoshape.io.datasets import dataset_dir, read_labels
    from geoshape.io.mesh_io import load_mesh
    from geoshape.parallel import single_thread_blas
    from geoshape.retrieval.descriptors import compute_descriptor, compute_descriptor_set, method_descriptors

    items = read_labels(dataset_dir("tosca_r5k"))
    items = items[:: max(1, len(items) // n)][:n]
    names = method_descriptors("fused")
    tot = {"shared": [0.0, 0.0], "separate": [0.0, 0.0]}
    nv = set()
    for it in items:
        V, F = load_mesh(it.path)
        nv.add(len(V))
        with single_thread_blas():
            for how in ("shared", "separate"):
                t, c = time.perf_counter(), time.process_time()
                if how == "shared":
                    compute_descriptor_set(V, F, names)
                else:
                    for nm in names:
                        compute_descriptor(V, F, nm)
                tot[how][0] += time.process_time() - c
                tot[how][1] += time.perf_counter() - t
    return {"n": len(items), "vertices": sorted(nv),
            **{how: (cpu / len(items), wall / len(items)) for how, (cpu, wall) in tot.items()}}


def _grid(components, step):
    import itertools

    n = round(1 / step)
    if n < 1 or abs(n * step - 1) > 1e-9:
        from geoshape.errors import InvalidOptionError

        raise InvalidOptionError(f"--grid-step must be 1/n for a positive integer n, got {step}")
    return [dict(zip(components, (c / n for c in combo), strict=True))
            for combo in itertools.product(range(n + 1), repeat=len(components)) if sum(combo) == n]


def _wtext(w) -> str:
    return ", ".join(f"{n} {v:.3g}" for n, v in w.items() if v > 0)


def _fast_nn_ft(D, lab):
    """NN and FT of an all-pairs matrix (query excluded), as retrieval_metrics computes them."""
    import numpy as np

    D = np.array(D, dtype=np.float64)
    n = len(D)
    D[np.arange(n), np.arange(n)] = np.inf
    order = np.argsort(D, axis=1, kind="stable")
    rel = lab[order] == lab[:, None]
    n_rel = (lab[:, None] == lab[None, :]).sum(axis=1) - 1
    ok = n_rel > 0
    cum = np.cumsum(rel, axis=1)
    ft = cum[np.arange(n), np.maximum(n_rel - 1, 0)] / np.maximum(n_rel, 1)
    return float(rel[ok, 0].mean()), float(ft[ok].mean())


#: powers compared (grid best on all collections per power) to show how FUSED_POWER was chosen
POWER_SCAN = (1.0, 2.0, 4.0, 8.0, 12.0, 16.0)


def run(args) -> int:
    import tempfile
    import time
    from pathlib import Path

    import numpy as np

    from geoshape.bench.results import markdown_table, update_results_section
    from geoshape.errors import InvalidOptionError
    from geoshape.metrics.retrieval import retrieval_metrics
    from geoshape.retrieval.fusion import (
        FUSED_GAP_REFERENCE,
        FUSED_K,
        FUSED_POWER,
        FUSED_WEIGHTS,
        GAP_FLOOR,
        fuse_distances,
        query_gaps,
        typical_gaps,
    )
    from geoshape.retrieval.rerank import rerank

    sets = [s.strip() for s in args.sets.split(",") if s.strip()]
    comps = [c.strip() for c in args.components.split(",") if c.strip()]
    missing = [c for c in FUSED_WEIGHTS if c not in comps]
    if missing:
        raise InvalidOptionError(f"--components must include the fused ones; missing {', '.join(missing)}")
    grid = _grid(comps, args.grid_step)
    t_start = time.perf_counter()
    mats, labels, spm, lib, lib_spm = {}, {}, {}, {}, {}
    with tempfile.TemporaryDirectory() as tmpd:
        folders = {}
        for s in sets:
            mats[s], spm[s] = {}, {}
            for c in comps:
                D, lab, sec = _component(s, c, Path(tmpd), args, folders)
                if s in labels and lab != labels[s]:
                    raise InvalidOptionError(f"{s}: the cached {c} matrix has other labels than the others")
                labels[s] = lab
                mats[s][c], spm[s][c] = D, sec
            D, lab, lib_spm[s] = _library(s, Path(tmpd), args, folders)
            if lab != labels[s]:
                raise InvalidOptionError(f"{s}: the library's fused matrix has other labels than the "
                                         "components")
            lib[s] = D
    lab_arr = {s: np.asarray(labels[s]) for s in sets}

    def fuse(s, w, k=FUSED_K, adaptive=True, reference=None, power=FUSED_POWER):
        used = {c: v for c, v in w.items() if v > 0}
        return fuse_distances({c: mats[s][c] for c in used}, used, k=k, adaptive=adaptive,
                              reference=reference, power=power)

    def metrics(D, s):
        m = retrieval_metrics(D, labels[s])
        return m["nearest_neighbor"], m["first_tier"], m["second_tier"], m["map"]

    # the library's own matrix = the fusion of the component matrices (up to the eigen-solver
    # tolerance: its spectral components share one eigen-solve per mesh)
    lib_diff = {s: float(np.max(np.abs(lib[s] - fuse(s, FUSED_WEIGHTS)))) for s in sets}

    cost = _one_core_cost(args.timing_meshes) if args.timing_meshes > 0 and "tosca_r5k" in sets else None
    if cost is not None:
        print(f"one core, per tosca_r5k mesh: {cost}", flush=True)

    # typical gaps per collection; reference = median over the collections used
    typical = {s: typical_gaps(mats[s], k=FUSED_K) for s in sets}

    def reference_of(train):
        return {c: float(np.median([typical[t][c] for t in train])) for c in comps}

    ref_all = reference_of(sets)
    # fast grid: row-normalised matrices and raw gaps once per (set, component)
    normed = {}
    for s in sets:
        off = ~np.eye(len(labels[s]), dtype=bool)
        for c in comps:
            D = mats[s][c]
            med = np.array([np.median(r[o]) for r, o in zip(D, off, strict=True)])
            normed[(s, c)] = (D / np.where(med > 0, med, 1.0)[:, None], query_gaps(D, k=FUSED_K))

    def grid_scores(ref, power):
        """FT + NN/2 of the adaptive fusion of every grid weight vector, per collection."""
        cal = {(s, c): np.maximum(normed[(s, c)][1] / ref[c], GAP_FLOOR) ** power
               for s in sets for c in comps}
        out = []
        for w in grid:
            used = [c for c in comps if w[c] > 0]
            row = {}
            for s in sets:
                W = np.array([w[c] * cal[(s, c)] for c in used])
                W /= W.sum(axis=0)
                D = sum(Wc[:, None] * normed[(s, c)][0] for Wc, c in zip(W, used, strict=True))
                nn, ft = _fast_nn_ft(0.5 * (D + D.T), lab_arr[s])
                row[s] = ft + 0.5 * nn
            out.append(row)
        return out

    def best_of(scores, train):
        return max(range(len(grid)), key=lambda i: np.mean([scores[i][t] for t in train]))

    t0 = time.perf_counter()
    scan = {}
    for pw in sorted(set(POWER_SCAN) | {FUSED_POWER}):
        sc = grid_scores(ref_all, pw)
        i = best_of(sc, sets)
        scan[pw] = (grid[i], float(np.mean([sc[i][t] for t in sets])))
        print(f"power {pw:g}: grid best {_wtext(grid[i])}, mean FT + NN/2 {scan[pw][1]:.4f}", flush=True)
    best_all = scan[FUSED_POWER][0]
    loco, loco_ref = {}, {}
    for held in sets:
        train = [s for s in sets if s != held] or [held]
        loco_ref[held] = reference_of(train)
        sc = grid_scores(loco_ref[held], FUSED_POWER)
        loco[held] = grid[best_of(sc, train)]
    t_grid = time.perf_counter() - t0

    base_w = {c: FUSED_WEIGHTS.get(c, 0.0) for c in comps}
    variants = []  # (label, weights, k, adaptive, power, reference)
    for c in comps:
        variants.append((c, {c: 1.0}, FUSED_K, False, FUSED_POWER, None))
    variants.append(("fusion, fixed weights", base_w, FUSED_K, False, FUSED_POWER, None))
    variants.append(("fusion, adaptive uncalibrated (power 1, no reference: earlier rule)", base_w, FUSED_K,
                     True, 1.0, {}))
    variants.append((LIBRARY_ROW, base_w, FUSED_K, True, FUSED_POWER, None))
    variants.append(("LOCO adaptive", None, FUSED_K, True, FUSED_POWER, "loco"))
    for c, v in FUSED_WEIGHTS.items():
        if v <= 0:
            continue
        for f in (0.5, 2.0):
            w = dict(base_w)
            w[c] = v * f
            tot = sum(w.values())
            variants.append((f"sensitivity: {c} ×{f:g}", {n: x / tot for n, x in w.items()}, FUSED_K, True,
                             FUSED_POWER, None))
    for kk in (max(1, FUSED_K // 2), 2 * FUSED_K):
        variants.append((f"sensitivity: k = {kk}", base_w, kk, True, FUSED_POWER, None))
    for pw in (FUSED_POWER / 2, FUSED_POWER * 2):
        variants.append((f"sensitivity: power {pw:g}", base_w, FUSED_K, True, pw, None))

    header = ["method", "weights", "NN", "FT", "ST", "mAP", "+lcdp NN", "+lcdp FT", "+lcdp ST",
              "+lcdp mAP", "s / mesh"]
    tables, summary = [], {}
    for s in sets:
        rows = []
        for label, w, kk, adaptive, pw, ref in variants:
            w = loco[s] if w is None else w
            ref = loco_ref[s] if ref == "loco" else ref
            # a single component is scored on its own matrix (not row-normalised)
            D = mats[s][next(iter(w))] if len(w) == 1 else fuse(s, w, kk, adaptive, ref, pw)
            if label == LIBRARY_ROW:
                D = lib[s]  # the library's fused method itself
            a, b = metrics(D, s), metrics(rerank(D, "lcdp"), s)
            sec = lib_spm[s] if label == LIBRARY_ROW else sum(spm[s][c] for c, v in w.items() if v > 0)
            extra = [] if kk == FUSED_K else [f"k = {kk}"]
            if adaptive and pw != FUSED_POWER:
                extra.append(f"power {pw:g}")
            wt = "—" if len(w) == 1 else "; ".join([_wtext(w), *extra])
            rows.append([label, wt, *[f"{x:.3f}" for x in a], *[f"{x:.3f}" for x in b], f"{sec:.2f}"])
            summary[(s, label)] = a
            print(f"[{s}] {label}: NN {a[0]:.3f} FT {a[1]:.3f} ST {a[2]:.3f} mAP {a[3]:.3f} | "
                  f"lcdp NN {b[0]:.3f} FT {b[1]:.3f} mAP {b[3]:.3f}", flush=True)
        n = len(labels[s])
        title = f"### {s} ({n} meshes, {len(set(labels[s]))} classes)"
        tables.append(title + "\n\n" + markdown_table(header, rows))
    gap_rows = [[s, *[f"{typical[s][c]:.3f}" for c in comps]] for s in sets]
    gap_rows.append(["median (computed)", *[f"{ref_all[c]:.3f}" for c in comps]])
    gap_rows.append(["library `FUSED_GAP_REFERENCE`",
                     *[f"{FUSED_GAP_REFERENCE[c]:.3f}" if c in FUSED_GAP_REFERENCE else "—" for c in comps]])
    gap_table = markdown_table([f"typical gap (k = {FUSED_K})", *comps], gap_rows)
    scan_table = markdown_table(["power", "grid best weights (all collections)", "mean FT + NN/2"],
                                [[f"{pw:g}", _wtext(w), f"{v:.4f}"] for pw, (w, v) in scan.items()])
    cmd = f"geoshape bench fusion --sets {args.sets} --components {args.components}"
    if args.grid_step != 0.125:
        cmd += f" --grid-step {args.grid_step:g}"
    cmd += folder_flags(args)
    text = (
        "## 3D late fusion of descriptors (fixed vs query-adaptive)\n\n"
        f"Command: `{cmd}`. Components' all-pairs matrices as `geoshape retrieval3d` computes "
        "them; `generated` is the articulated generator of `geoshape bench retrieval3d` "
        f"({args.gen_instances} instances × {args.gen_poses} poses, seed 7), `mixed3d` / `mixed3d_s1` are "
        "`geoshape gen mixed3d` with seed 0 / 1. Fusion (`geoshape.retrieval.fusion.fuse_distances`): "
        "each matrix divided per query by its median; per query and component the gap "
        f"(1 − mean of the {FUSED_K} nearest normalised distances) divided by the component's typical gap "
        "(`FUSED_GAP_REFERENCE`: median over the collections of each collection's median gap, table below), "
        f"raised to the power `FUSED_POWER` = {FUSED_POWER:g}, times w_c, normalised over the components: "
        "those are the query's weights ('fixed': w_c only); weighted sum, symmetrised. Library weights "
        f"`FUSED_WEIGHTS` = {_wtext(FUSED_WEIGHTS)} (`--descriptor fused`, the default of `geoshape "
        "retrieval3d` and of the index); its row is the library's `fused` method run on each collection "
        "(components computed together per mesh, one shared Laplace–Beltrami eigen-solve; max |difference| "
        "from fusing the component matrices: "
        + ", ".join(f"{s} {lib_diff[s]:.1e}" for s in sets)
        + "). LOCO: weights chosen on the other collections by grid search "
        f"({len(grid)} weight vectors, step {args.grid_step:g}, score mean FT + NN/2, power {FUSED_POWER:g}) "
        "with reference gaps computed on those collections only, scored on this one; LOCO weights per "
        "held-out set: "
        + "; ".join(f"{s}: {_wtext(loco[s])}" for s in sets)
        + f". Grid best on all collections (power {FUSED_POWER:g}): {_wtext(best_all)}. Sensitivity: each "
        "library weight ×0.5 / ×2 then renormalised, k halved (floor) / doubled, power halved / doubled. "
        "'+lcdp': `geoshape.retrieval.rerank.rerank(D, \"lcdp\")` with its defaults. 's / mesh': "
        "descriptor wall time per mesh on the parallel runner when the matrix was computed (2 workers on "
        "a shared machine, so noisy), summed over the components computed separately (library row: "
        "measured, shared eigen-solve). "
        + (f"Cost of the library default on one core (`compute_descriptor_set`, single-thread BLAS, "
           f"{cost['n']} tosca_r5k meshes of {'/'.join(map(str, cost['vertices']))} vertices, one at a "
           f"time): {cost['shared'][0]:.2f} s CPU per mesh ({cost['shared'][1]:.2f} s wall on this "
           f"shared machine); the same components each with its own eigen-solve: "
           f"{cost['separate'][0]:.2f} s CPU ({cost['separate'][1]:.2f} s wall). " if cost else "")
        + f"Grid searches {t_grid:.1f} s, total "
        f"{time.perf_counter() - t_start:.1f} s (matrices {'cached' if args.cache else 'computed'}).\n\n"
        "Typical gaps (median over each collection's queries) and the library's reference:\n\n"
        + gap_table
        + "\n\nHow the power was chosen (adaptive fusion, reference gaps of all collections, grid best "
        "by mean FT + NN/2 over all collections):\n\n"
        + scan_table
        + f"\n\nThe library uses power {FUSED_POWER:g} (`FUSED_POWER`: its docstring says how it was "
        "picked within the plateau).\n\n"
        + "\n\n".join(tables)
    )
    print(text)
    if not args.no_write:
        update_results_section("fusion", text)
    return 0
