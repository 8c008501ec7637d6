"""``geoshape bench retrieval3d``: 3D retrieval with every descriptor, original vs embedding.

On ``tosca_r5k`` (76 meshes, 8 classes), a generated articulated collection
(``geoshape_datasets_gen.articulated3d.write_collection``) and the two generated mixed
collections ``mixed3d`` / ``mixed3d_s1`` (``geoshape gen mixed3d`` with seed 0 / 1, or
``--mixed DIR`` / ``--mixed-s1 DIR``; folders as ``geoshape bench fusion`` builds them):
every retrieval method of the registry (every descriptor, EVD → CCD and the ``fused``
default), the spectral and embedding ones under every affinity; NN, FT, ST, E, DCG, mAP and
descriptor time per mesh, each score also after LCDP re-ranking
(:func:`geoshape.retrieval.rerank.rerank` with its defaults). Matrices are computed by
:func:`geoshape.retrieval.meshes.retrieval3d_on_folder` (the code path of ``geoshape
retrieval3d DIR --descriptor NAME``) and, with ``--cache DIR``, kept as
``DIR/<set>/<method>[@<affinity>].npz`` so a rerun only scores them. Also: EVD time per mesh
at 5k and 25k vertices, and the query time of the persistent index over 10,000 stored
(synthetic) EVD rows. Writes section ``retrieval3d`` (``--section``) of docs/RESULTS.md after
every row, and precision–recall plots to ``docs/img/retrieval3d_pr_<set>.png``.
"""

from __future__ import annotations

HELP = "3D retrieval: EVD, CCD, EVD->CCD, SHD/LFD/D2 on mesh vs spectral embedding, index query time"

AFFINITIES = ("geodesic", "euclidean", "combined")
SETS = ("generated", "tosca_r5k", "mixed3d", "mixed3d_s1")


def add_arguments(parser) -> None:
    parser.add_argument("--sets", default="generated,tosca_r5k",
                        help=f"comma-separated, of {', '.join(SETS)} (default generated,tosca_r5k)")
    parser.add_argument("--descriptors", default=None,
                        help="comma-separated retrieval methods (default: all)")
    parser.add_argument("--affinities", default=",".join(AFFINITIES),
                        help="affinities for spectral/embedding descriptors (default all three)")
    parser.add_argument("--n-jobs", type=int, default=None, help="workers (default: all cores)")
    parser.add_argument("--gen-poses", type=int, default=4, help="poses per generated instance")
    parser.add_argument("--gen-instances", type=int, default=2, help="instances per generated class")
    parser.add_argument("--index-rows", type=int, default=10000, help="synthetic rows for the query timing")
    parser.add_argument("--hires", type=int, default=3, help="tosca_hires meshes timed for EVD at 25k")
    parser.add_argument("--mixed", default=None, metavar="DIR",
                        help="existing mixed3d folder (default: generate one, seed 0, under --cache or a "
                        "temp folder)")
    parser.add_argument("--mixed-s1", default=None, metavar="DIR",
                        help="existing mixed3d seed-1 folder (default: generate one under --cache or a "
                        "temp folder)")
    parser.add_argument("--cache", default=None, metavar="DIR",
                        help="cache of all-pairs matrices, DIR/<set>/<method>[@<affinity>].npz, reused when "
                        "the descriptor settings match (--mixed M / --mixed-s1 M: under DIR/<name of M>/)")
    parser.add_argument("--cached-only", action="store_true",
                        help="score only the matrices already in --cache; list the others as not run")
    parser.add_argument("--section", default="retrieval3d",
                        help="RESULTS.md section name (default retrieval3d), to keep partial runs apart")
    parser.add_argument("--no-write", action="store_true", help="print only")


def _methods(args):
    from geoshape._options import check_choice
    from geoshape.retrieval.descriptors import DEFAULT_RETRIEVAL_METHOD, RETRIEVAL_METHODS

    if not args.descriptors:  # the default method (fused) first, then the registry's order
        return [DEFAULT_RETRIEVAL_METHOD] + [m for m in RETRIEVAL_METHODS if m != DEFAULT_RETRIEVAL_METHOD]
    names = [m.strip() for m in args.descriptors.split(",") if m.strip()]
    for m in names:
        check_choice("descriptor", m, RETRIEVAL_METHODS)
    return names


def _runs(methods, affinities):
    from geoshape.retrieval.descriptors import MESH_DESCRIPTORS, method_descriptors

    out = []
    for m in methods:
        names = method_descriptors(m)
        if any(MESH_DESCRIPTORS[n].uses_affinity for n in names):
            out += [(m, a) for a in affinities]
        else:
            out.append((m, None))
    return out


def _generated(tmp, args):
    from geoshape_datasets_gen.articulated3d import CLASSES, write_collection

    folder = tmp / "articulated3d"
    write_collection(folder, classes=CLASSES, instances=args.gen_instances, poses=args.gen_poses,
                     seed=7, target_vertices=1500, resolution=80)
    return folder


def _index_timing(tmp, n_rows: int) -> dict:
    import time

    import numpy as np

    from geoshape.retrieval.descriptors import descriptor_params, params_key
    from geoshape.retrieval.index import ShapeIndex

    rng = np.random.default_rng(0)
    X = np.sort(rng.gamma(2.0, 1.0, size=(n_rows, 20)), axis=1)[:, ::-1]
    pk = params_key(descriptor_params("evd"))
    with ShapeIndex(tmp / "synthetic.db") as idx:
        idx.insert_rows((f"/synthetic/{k}.off", "evd", pk, "0" * 64, X[k], 0.0) for k in range(n_rows))
    queries = rng.gamma(2.0, 1.0, size=(20, 20))
    with ShapeIndex(tmp / "synthetic.db") as idx:
        t0 = time.perf_counter()
        idx.query_descriptor(queries[0], "evd", top=10)
        cold = time.perf_counter() - t0
        warm = []
        for q in queries[1:]:
            t0 = time.perf_counter()
            idx.query_descriptor(q, "evd", top=10)
            warm.append(time.perf_counter() - t0)
    return {"rows": n_rows, "cold_ms": 1000 * cold, "warm_ms": 1000 * float(np.median(warm)),
            "warm_max_ms": 1000 * float(np.max(warm))}


def _evd_hires(n: int) -> dict:
    import time

    import numpy as np

    from geoshape.io.datasets import dataset_dir
    from geoshape.io.mesh_io import load_mesh
    from geoshape.parallel import single_thread_blas
    from geoshape.retrieval.descriptors.evd import evd_descriptor

    folder = dataset_dir("tosca_hires", required=False)
    if folder is None or n < 1:
        return {}
    files = sorted(folder.glob("*.off*"))[:: max(1, len(sorted(folder.glob("*.off*"))) // n)][:n]
    times, heat_times, sizes = [], [], []
    with single_thread_blas():
        for f in files:
            V, F = load_mesh(f)
            t0 = time.perf_counter()
            evd_descriptor(V, F)
            t1 = time.perf_counter()
            evd_descriptor(V, F, config="heat")
            heat_times.append(time.perf_counter() - t1)
            times.append(t1 - t0)
            sizes.append(len(V))
    return {"n": len(times), "vertices": f"{min(sizes)}–{max(sizes)}",
            "mean_s": float(np.mean(times)), "max_s": float(np.max(times)),
            "heat_mean_s": float(np.mean(heat_times)), "heat_max_s": float(np.max(heat_times))}


def _check_sets(sets) -> None:
    from geoshape._options import check_choice

    for name in sets:
        check_choice("set", name, SETS)


def _cache_tag(set_name: str, args) -> str:
    """Cache subfolder of a set: as ``geoshape bench fusion`` names it; the generated articulated
    set also by its size (instances, poses)."""
    from geoshape.bench.fusion import _cache_tag as fusion_tag

    if set_name == "generated":
        return f"generated-i{args.gen_instances}-p{args.gen_poses}"
    return fusion_tag(set_name, args)


def _set_folder(set_name: str, tmp, args):
    """The folder of a set; a generated mixed collection is written once under ``--cache``
    (``DIR/src/<set>``) and reused, or into the temp folder without a cache."""
    from pathlib import Path

    from geoshape.bench.fusion import _folder

    given = {"mixed3d": args.mixed, "mixed3d_s1": args.mixed_s1}.get(set_name)
    if set_name in ("mixed3d", "mixed3d_s1") and not given and args.cache:
        src = Path(args.cache) / "src"
        if (src / set_name / "labels.csv").is_file():
            return src / set_name
        src.mkdir(parents=True, exist_ok=True)
        return _folder(set_name, src, args)
    return _folder(set_name, tmp, args)


def _cache_key(method: str, affinity) -> str:
    """What the cached matrix depends on: the method's descriptors and their parameters."""
    import json

    from geoshape.retrieval.descriptors import FUSIONS, descriptor_params, method_descriptors
    from geoshape.retrieval.meshes import DEFAULT_RERANK_K

    names = method_descriptors(method)
    key = {"method": method, "affinity": affinity, "rerank_k": DEFAULT_RERANK_K,
           "params": {n: descriptor_params(n, affinity, 0) for n in names},
           "weights": {n: FUSIONS[method][n] for n in names} if method in FUSIONS else None}
    return json.dumps(key, sort_keys=True, default=str)


def _matrix(set_name, method, affinity, args, get_folder) -> dict:
    """``D``, ``labels``, ``seconds_per_mesh`` (by descriptor), ``seconds``, ``n``, ``cached``
    of one method on one set: from the cache when its key matches, else
    :func:`retrieval3d_on_folder` (then stored)."""
    import json
    from pathlib import Path

    import numpy as np

    key = _cache_key(method, affinity)
    path = None
    if args.cache:
        stem = f"{method}@{affinity}" if affinity else method
        path = Path(args.cache) / _cache_tag(set_name, args) / f"{stem}.npz"
        if path.is_file():
            z = np.load(path)
            if str(z["key"]) == key:
                return {"D": z["D"], "labels": [str(x) for x in z["labels"]],
                        "seconds_per_mesh": json.loads(str(z["spm"])), "seconds": float(z["seconds"]),
                        "cached": True}
    if getattr(args, "cached_only", False):
        return None
    from geoshape.retrieval.meshes import retrieval3d_on_folder

    res = retrieval3d_on_folder(get_folder(), method, affinity=affinity, n_jobs=args.n_jobs, progress=False)
    out = {"D": res["D"], "labels": list(res["labels"]), "seconds_per_mesh": res["seconds_per_mesh"],
           "seconds": float(res["seconds"]), "cached": False}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp_path = path.with_suffix(".tmp.npz")
        np.savez(tmp_path, D=out["D"], labels=np.array(out["labels"]), key=key,
                 spm=json.dumps(out["seconds_per_mesh"]), seconds=out["seconds"])
        tmp_path.replace(path)
    return out


METRIC_KEYS = ("nearest_neighbor", "first_tier", "second_tier", "e_measure", "dcg", "map")


def _scores(D, labels) -> tuple[dict, dict]:
    """Retrieval metrics of ``D`` and of its LCDP re-ranking (library defaults)."""
    from geoshape.metrics.retrieval import retrieval_metrics
    from geoshape.retrieval.rerank import rerank

    return retrieval_metrics(D, labels), retrieval_metrics(rerank(D, "lcdp"), labels)


def _row(set_name, method, affinity, res, met, met_rr) -> list:
    from geoshape.retrieval.descriptors import FUSIONS, MESH_DESCRIPTORS, method_descriptors

    names = method_descriptors(method)
    domain = "/".join(sorted({MESH_DESCRIPTORS[n].domain for n in names}))
    spm = res["seconds_per_mesh"]
    if method in FUSIONS:  # components computed together: one cost
        per = f"{sum(spm[n] for n in names):.3f}"
    else:
        per = " + ".join(f"{spm[n]:.3f}" for n in names)
    return [set_name, method, domain, affinity or "-", *(met[k] for k in METRIC_KEYS),
            *(met_rr[k] for k in METRIC_KEYS), per,
            f"{res['seconds']:.1f}"]


def run(args) -> int:
    import os
    import platform
    import tempfile
    import time
    from pathlib import Path

    from geoshape.bench.results import default_results_path, update_results_section
    from geoshape.plot.retrieval import plot_precision_recall

    methods = _methods(args)
    affinities = [a.strip() for a in args.affinities.split(",") if a.strip()]
    sets = [s.strip() for s in args.sets.split(",") if s.strip()]
    _check_sets(sets)
    img_dir = default_results_path().parent / "img"
    state = {"rows": [], "notes": [], "index": None, "hires": None, "sizes": {}, "missing": {}}
    stamp = time.strftime("%Y-%m-%d")
    workers = args.n_jobs or os.cpu_count()

    def write():
        md = _section(state, args, stamp, workers, platform.machine())
        if not args.no_write:
            update_results_section(args.section, md)
        return md

    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        state["index"] = _index_timing(tmp, args.index_rows) if args.index_rows > 0 else None
        print(f"index query: {state['index']}", flush=True)
        state["hires"] = _evd_hires(args.hires)
        print(f"EVD 25k: {state['hires']}", flush=True)
        write()
        for set_name in sets:
            folders = {}

            def get_folder(set_name=set_name, folders=folders):
                if set_name not in folders:
                    folders[set_name] = _set_folder(set_name, tmp, args)
                return folders[set_name]

            curves = {}
            for m, aff in _runs(methods, affinities):
                print(f"[{set_name}] {m} {aff or ''} …", flush=True)
                res = _matrix(set_name, m, aff, args, get_folder)
                if res is None:
                    state["missing"].setdefault(set_name, []).append(f"{m}@{aff}" if aff else m)
                    print("  not in the cache: skipped", flush=True)
                    continue
                labels = res["labels"]
                state["sizes"][set_name] = (len(labels), len(set(labels)))
                met, met_rr = _scores(res["D"], labels)
                state["rows"].append(_row(set_name, m, aff, res, met, met_rr))
                if aff in (None, "geodesic"):
                    curves[m] = met
                print(f"  NN {met['nearest_neighbor']:.3f} FT {met['first_tier']:.3f} "
                      f"mAP {met['map']:.3f} | +lcdp NN {met_rr['nearest_neighbor']:.3f} "
                      f"FT {met_rr['first_tier']:.3f} mAP {met_rr['map']:.3f} | {res['seconds']:.1f} s"
                      f"{' (cached)' if res['cached'] else ''}", flush=True)
                write()
            if curves and not args.no_write:
                plot_precision_recall(curves, img_dir / f"retrieval3d_pr_{set_name}.png",
                                      title=f"{set_name} ({state['sizes'][set_name][0]} meshes)")
    md = write()
    print(md)
    return 0


def _command(args) -> str:
    from geoshape.bench.fusion import folder_flags

    cmd = f"geoshape bench retrieval3d --sets {args.sets} --affinities {args.affinities}"
    if args.descriptors:
        cmd += f" --descriptors {args.descriptors}"
    if args.index_rows != 10000:
        cmd += f" --index-rows {args.index_rows}"
    if args.hires != 3:
        cmd += f" --hires {args.hires}"
    cmd += folder_flags(args)
    if getattr(args, "cached_only", False):
        cmd += " --cached-only"
    return cmd + f" --section {args.section}"


def _section(state, args, stamp, workers, machine) -> str:
    from geoshape.bench.experiments._common import machine_note
    from geoshape.bench.results import markdown_table, workers_note

    header = ["set", "descriptor", "domain", "affinity", "NN", "FT", "ST", "E", "DCG", "mAP",
              "+lcdp NN", "+lcdp FT", "+lcdp ST", "+lcdp E", "+lcdp DCG", "+lcdp mAP",
              "s / mesh", "total s"]
    idx = state["index"] or {}
    hires = state["hires"] or {}
    sizes = "; ".join(f"{k}: {n} meshes, {c} classes" for k, (n, c) in state.get("sizes", {}).items())
    lines = [
        f"## 3D retrieval (descriptors on meshes and on spectral embeddings): {args.section}",
        "",
        f"Command: `{_command(args)}` "
        f"({stamp}, {workers_note(workers)}, {machine}). Generated set: `write_collection(classes=CLASSES, "
        f"instances={args.gen_instances}, poses={args.gen_poses}, seed=7, target_vertices=1500, "
        "resolution=80)`; `mixed3d` / `mixed3d_s1`: `geoshape gen mixed3d` with seed 0 / 1"
        f"{f' ({sizes})' if sizes else ''}. Every matrix is the one of `geoshape retrieval3d DIR "
        "--descriptor NAME [--affinity A]` (`retrieval3d_on_folder`); `fused` is the default of "
        "`geoshape retrieval3d` (components computed together per mesh, one shared eigen-solve). "
        "'+lcdp': the same matrix after `geoshape.retrieval.rerank.rerank(D, \"lcdp\")` "
        "(library defaults). 's / mesh' is the mean descriptor compute time per mesh in one worker "
        "(single BLAS thread, file reading excluded; for evd_ccd: EVD + CCD; for fused: all "
        "components) when the matrix was computed; 'total s' is the wall time of descriptors + "
        "matrix (+ re-ranking of evd_ccd) then, on 1–2 workers of a machine shared with other jobs "
        "(with --cache the matrices may come from earlier partial runs), so noisy. "
        f"Load: {machine_note()}.",
        "",
        "Domains: `original` = descriptor on the mesh, `embedding` = on the 3D spectral embedding "
        "(2nd–4th √λ-scaled eigenvectors, same faces), `spectral` = EVD/CCD themselves.",
        "",
        markdown_table(header, state["rows"]),
        "",
    ]
    if state.get("missing"):
        lines += ["Not run (no cached matrix): " + "; ".join(
            f"{k}: {', '.join(v)}" for k, v in state["missing"].items()) + ".", ""]
    if idx:
        lines.append(f"Index query (top-10, χ² over {idx['rows']} stored 20-D EVD rows, query "
                     f"descriptor given): first query incl. loading from SQLite "
                     f"{idx['cold_ms']:.1f} ms, then median {idx['warm_ms']:.2f} ms "
                     f"(max {idx['warm_max_ms']:.2f} ms).")
    if hires:
        lines.append(f"EVD on tosca_hires ({hires['n']} meshes, {hires['vertices']} vertices, "
                     f"one thread): mean {hires['mean_s']:.2f} s, max {hires['max_s']:.2f} s per mesh; "
                     f"evd_heat mean {hires['heat_mean_s']:.2f} s, max {hires['heat_max_s']:.2f} s.")
    from geoshape.retrieval.descriptors.evd import EVD_N_SAMPLES

    lines += ["", NOTES.format(samples=EVD_N_SAMPLES)]
    return "\n".join(lines) + "\n"


NOTES = (
    "Reading the tosca_r5k rows: three of its eight classes are human bodies (david, michael, "
    "victoria) whose intrinsic geometry differs only in proportions, so bending-invariant global "
    "descriptors confuse them; nearly all EVD nearest-neighbour errors are human-to-human. "
    "`evd` is the area-weighted narrow-kernel configuration ({samples} samples, sigma = 0.1 "
    "sqrt(area)); `evd_thesis` the thesis' (60 unweighted samples, sigma = max); `evd_heat` the "
    "narrow-kernel limit of `evd`, computed from 20 exact Laplace-Beltrami eigenvalues without "
    "sampling or geodesic error. The sampled settings in between are compared by `geoshape bench "
    "evd` (section evd-settings, with first tier per class and the same exact-spectrum reference). "
    "What keeps the sampled EVD from NN = 1.0 / FT >= 0.95 on this set is david vs michael: "
    "scale-invariantly their eigenvalues differ by about as much as one character's poses spread "
    "them, and the sampled EVD separates the two less than the exact reference does (table at the "
    "end of evd-settings); their sizes differ by far more, but a scale-invariant descriptor does "
    "not see size. EVD -> CCD re-ranks by a correspondence cost that is less "
    "discriminative than the EVD it re-ranks. SHD, LFD and D2 are compared on the original mesh "
    "and on the geodesic embedding in the same table (thesis Fig. 4.10 claim: better on the "
    "embedding). See docs/retrieval3d.md. `mixed3d` / `mixed3d_s1`: 240 meshes each, 20 classes × 12 "
    "(10 articulated, 10 rigid man-made; about 2000 vertices, random rotation, scale and translation; "
    "24 meshes with defects), so unlike tosca_r5k they reward extrinsic descriptors (pcavox, lfd, shd) "
    "as much as bending-invariant ones; `fused` combines both kinds. LCDP re-ranking (k = 4 "
    "neighbours, 5 iterations) raises FT / ST / mAP when the first neighbours are mostly right, and "
    "can lower NN (a query's single nearest match is replaced by its neighbourhood's consensus)."
)
