"""``geoshape bench retrieval3d``: 3D retrieval with every descriptor, original vs embedding.

On ``tosca_r5k`` (76 meshes, 8 classes) and on a generated articulated collection
(``geoshape_datasets_gen.articulated3d.write_collection``): every descriptor of the registry (and
EVD → CCD), the spectral and embedding ones under every affinity; NN, FT, ST, E, DCG, mAP,
descriptor time per mesh. Also: EVD time per mesh at 5k and 25k vertices, and the query
time of the persistent index over 10,000 stored (synthetic) EVD rows. Writes section
``retrieval3d`` of docs/RESULTS.md after every row, and precision–recall plots to
``docs/img/retrieval3d_pr_<set>.png``.
"""

from __future__ import annotations

HELP = "3D retrieval: EVD, CCD, EVD->CCD, SHD/LFD/D2 on mesh vs spectral embedding, index query time"

AFFINITIES = ("geodesic", "euclidean", "combined")


def add_arguments(parser) -> None:
    parser.add_argument("--sets", default="generated,tosca_r5k",
                        help="comma-separated: generated, tosca_r5k (default both)")
    parser.add_argument("--descriptors", default=None,
                        help="comma-separated retrieval methods (default: all)")
    parser.add_argument("--affinities", default=",".join(AFFINITIES),
                        help="affinities for spectral/embedding descriptors (default all three)")
    parser.add_argument("--n-jobs", type=int, default=None, help="workers (default: all cores)")
    parser.add_argument("--gen-poses", type=int, default=4, help="poses per generated instance")
    parser.add_argument("--gen-instances", type=int, default=2, help="instances per generated class")
    parser.add_argument("--index-rows", type=int, default=10000, help="synthetic rows for the query timing")
    parser.add_argument("--hires", type=int, default=3, help="tosca_hires meshes timed for EVD at 25k")
    parser.add_argument("--section", default="retrieval3d",
                        help="RESULTS.md section name (default retrieval3d), to keep partial runs apart")
    parser.add_argument("--no-write", action="store_true", help="print only")


def _methods(args):
    from geoshape._options import check_choice
    from geoshape.retrieval.descriptors import RETRIEVAL_METHODS

    if not args.descriptors:
        return list(RETRIEVAL_METHODS)
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


def run(args) -> int:
    import os
    import platform
    import tempfile
    import time
    from pathlib import Path

    from geoshape.bench.results import default_results_path, update_results_section
    from geoshape.io.datasets import dataset_dir
    from geoshape.plot.retrieval import plot_precision_recall
    from geoshape.retrieval.descriptors import MESH_DESCRIPTORS, method_descriptors
    from geoshape.retrieval.meshes import retrieval3d_on_folder

    methods = _methods(args)
    affinities = [a.strip() for a in args.affinities.split(",") if a.strip()]
    sets = [s.strip() for s in args.sets.split(",") if s.strip()]
    img_dir = default_results_path().parent / "img"
    state = {"rows": [], "notes": [], "index": None, "hires": None}
    stamp = time.strftime("%Y-%m-%d")
    workers = args.n_jobs or os.cpu_count()

    def write():
        md = _section(state, args, stamp, workers, platform.machine())
        if not args.no_write:
            update_results_section(args.section, md)
        return md

    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        state["index"] = _index_timing(tmp, args.index_rows)
        print(f"index query: {state['index']}", flush=True)
        state["hires"] = _evd_hires(args.hires)
        print(f"EVD 25k: {state['hires']}", flush=True)
        write()
        for set_name in sets:
            folder = _generated(tmp, args) if set_name == "generated" else dataset_dir(set_name)
            curves = {}
            for m, aff in _runs(methods, affinities):
                print(f"[{set_name}] {m} {aff or ''} …", flush=True)
                res = retrieval3d_on_folder(folder, m, affinity=aff, n_jobs=args.n_jobs,
                                            progress=False)
                met = res["metrics"]
                names = method_descriptors(m)
                domain = "/".join(sorted({MESH_DESCRIPTORS[n].domain for n in names}))
                per = " + ".join(f"{res['seconds_per_mesh'][n]:.3f}" for n in names)
                state["rows"].append([set_name, m, domain, aff or "-", met["nearest_neighbor"],
                                      met["first_tier"], met["second_tier"], met["e_measure"],
                                      met["dcg"], met["map"], per, f"{res['seconds']:.1f}"])
                if aff in (None, "geodesic"):
                    curves[m] = met
                print(f"  NN {met['nearest_neighbor']:.3f} FT {met['first_tier']:.3f} "
                      f"mAP {met['map']:.3f} {res['seconds']:.1f} s", flush=True)
                write()
                if curves and not args.no_write:
                    plot_precision_recall(curves, img_dir / f"retrieval3d_pr_{set_name}.png",
                                          title=f"{set_name} ({len(res['files'])} meshes)")
    md = write()
    print(md)
    return 0


def _section(state, args, stamp, workers, machine) -> str:
    from geoshape.bench.experiments._common import machine_note
    from geoshape.bench.results import markdown_table

    header = ["set", "descriptor", "domain", "affinity", "NN", "FT", "ST", "E", "DCG", "mAP",
              "s / mesh", "total s"]
    idx = state["index"] or {}
    hires = state["hires"] or {}
    lines = [
        f"## 3D retrieval (descriptors on meshes and on spectral embeddings): {args.section}",
        "",
        f"Command: `geoshape bench retrieval3d --sets {args.sets} --affinities {args.affinities}"
        f"{' --descriptors ' + args.descriptors if args.descriptors else ''}"
        f"{f' --index-rows {args.index_rows}' if args.index_rows != 10000 else ''}"
        f"{f' --hires {args.hires}' if args.hires != 3 else ''} --section {args.section}` "
        f"({stamp}, {workers} workers, {machine}). Generated set: `write_collection(classes=CLASSES, "
        f"instances={args.gen_instances}, poses={args.gen_poses}, seed=7, target_vertices=1500, "
        "resolution=80)`. 's / mesh' is the mean descriptor compute time per mesh in one worker "
        "(single BLAS thread, file reading excluded; for evd_ccd: EVD + CCD); 'total s' is the "
        f"wall time of descriptors + matrix (+ re-ranking). Load: {machine_note()}.",
        "",
        "Domains: `original` = descriptor on the mesh, `embedding` = on the 3D spectral embedding "
        "(2nd–4th √λ-scaled eigenvectors, same faces), `spectral` = EVD/CCD themselves.",
        "",
        markdown_table(header, state["rows"]),
        "",
    ]
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
    "embedding). See docs/retrieval3d.md."
)
