"""``geoshape bench spectral``: Nyström fidelity vs the exact embedding, and time/memory.

Two parts (``--part``):

``fidelity``
    On tosca_r5k meshes (~5k vertices): the exact k = 5 embedding (eigenvectors 2–6 of
    the geodesic Gaussian affinity, σ = max) against Nyström with l samples, with and
    without orthogonalisation. Reported: the cosine of the largest principal angle between
    the two 5-D subspaces (``scipy.linalg.subspace_angles``; 1 = same subspace), and the
    ratios Nyström / exact of the 5 eigenvalues.
``timing``
    Wall time (after loading) and peak resident memory of the exact embedding of a 5k
    mesh and of the Nyström embedding (default l) of 5k, 25k (tosca_hires dog0) and
    ~100k vertices (tosca_hires cat0 upsampled once by ``igl.upsample``). Each case runs in
    a fresh Python process (peak RSS from ``getrusage``), three times.
"""

from __future__ import annotations

HELP = "Nystrom fidelity vs exact embedding (tosca_r5k) and time/memory at 5k, 25k, 100k vertices"

SAMPLE_COUNTS = (10, 25, 50, 100, 200)


def add_arguments(parser) -> None:
    parser.add_argument("--part", choices=("fidelity", "timing", "all"), default="all")
    parser.add_argument("--meshes", type=int, default=8,
                        help="tosca_r5k meshes for the fidelity part (round-robin over classes)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per timing case")
    parser.add_argument("--no-write", action="store_true", help="print only, do not update RESULTS.md")


def _fidelity(args) -> str:
    import numpy as np
    from scipy.linalg import subspace_angles

    from geoshape.bench.geodesics import pick_meshes
    from geoshape.bench.results import markdown_table
    from geoshape.geometry.geodesics import GeodesicSolver
    from geoshape.io.mesh_io import load_mesh
    from geoshape.spectral.embedding import spectral_embedding

    paths = pick_meshes(args.meshes)
    stats: dict = {}
    for path in paths:
        V, F = load_mesh(path)
        solver = GeodesicSolver(V, F, "graph")
        ex = spectral_embedding(V, F, k=5, method="exact", solver=solver)
        for l in SAMPLE_COUNTS:  # noqa: E741
            for orth in (True, False):
                ny = spectral_embedding(V, F, k=5, method="nystrom", n_samples=l,
                                        orthogonalize=orth, solver=solver)
                cos = float(np.cos(subspace_angles(ex.coords, ny.coords)).min())
                ratio = ny.eigenvalues / ex.eigenvalues
                stats.setdefault((l, orth), []).append((cos, ratio))
        print(f"{path.name}: done", flush=True)
    rows = []
    for (l, orth), vals in sorted(stats.items(), key=lambda kv: (kv[0][0], not kv[0][1])):
        cos = np.array([c for c, _ in vals])
        ratios = np.concatenate([r for _, r in vals])
        rows.append([l, "yes" if orth else "no", float(cos.min()), float(cos.mean()),
                     float(ratios.min()), float(np.median(ratios)), float(ratios.max())])
    names = ", ".join(p.name.replace(".off.gz", "") for p in paths)
    return (
        "## Nyström fidelity vs the exact embedding\n\n"
        f"Written by `geoshape bench spectral --part fidelity --meshes {args.meshes}`. Meshes "
        f"(tosca_r5k): {names}. Geodesic Gaussian affinity (graph geodesics, σ = max), k = 5 "
        "(eigenvectors 2–6), √λ scaling, max-min samples with seed 0. cos = cosine of the "
        "largest principal angle between the exact and Nyström 5-D subspaces (1 = identical); "
        "ratio = Nyström / exact eigenvalue, over the 5 eigenvalues of every mesh.\n\n"
        + markdown_table(["l", "orthogonalised", "min cos", "mean cos", "min ratio",
                          "median ratio", "max ratio"], rows)
        + "\n\nOrthogonalisation (eigenpairs of the Nyström approximation through a thin QR, "
        "sample-block eigenvalues below 1e-4 × max left out) is what makes the extension "
        "faithful; the raw extension Ū = Bᵀ U Λ⁻¹ leaves a tilted subspace. The default is "
        "orthogonalised with l = 50."
    )


def _child(path: str, method: str, n_samples, upsample: int) -> None:
    """Run one timing case in this process and print a JSON line (used by ``_timing``)."""
    import json
    import resource
    import time

    from geoshape.io.mesh_io import load_mesh
    from geoshape.spectral.embedding import spectral_embedding

    V, F = load_mesh(path)
    for _ in range(upsample):
        import igl

        V, F = igl.upsample(V, F)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter()
    emb = spectral_embedding(V, F, k=5, method=method, n_samples=n_samples)
    seconds = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"n": len(V), "seconds": seconds, "peak_mb": peak / 1024,
                      "base_mb": base / 1024, "l": emb.params.get("n_samples")}))


def _timing(args) -> str:
    import json
    import subprocess
    import sys

    import numpy as np

    from geoshape.bench.results import markdown_table
    from geoshape.io.datasets import dataset_dir
    from geoshape.spectral.nystrom import DEFAULT_N_SAMPLES

    r5k = str(dataset_dir("tosca_r5k") / "vtx_5k" / "cat0.off.gz")
    hires = dataset_dir("tosca_hires")
    cases = [
        ("exact", r5k, "exact", None, 0),
        ("Nyström", r5k, "nystrom", None, 0),
        ("Nyström", str(hires / "dog0.off.gz"), "nystrom", None, 0),
        ("Nyström", str(hires / "cat0.off.gz"), "nystrom", None, 1),
    ]
    rows = []
    for label, path, method, l, up in cases:  # noqa: E741
        runs = []
        for _ in range(args.repeats):
            code = (f"from geoshape.bench.spectral import _child; "
                    f"_child({path!r}, {method!r}, {l!r}, {up})")
            out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                                 text=True).stdout
            runs.append(json.loads(out.strip().splitlines()[-1]))
        secs = [r["seconds"] for r in runs]
        r0 = runs[0]
        name = path.split("/")[-1].replace(".off.gz", "") + (" ×upsample" if up else "")
        rows.append([label, name, r0["n"], r0["l"] or "—", float(min(secs)),
                     float(np.median(secs)), float(max(r["peak_mb"] for r in runs)),
                     float(max(r["peak_mb"] - r["base_mb"] for r in runs))])
        print(rows[-1], flush=True)
    return (
        "## Spectral embedding: time and memory\n\n"
        f"Written by `geoshape bench spectral --part timing --repeats {args.repeats}`. k = 5, "
        f"geodesic affinity on graph geodesics, σ = max; Nyström with the default "
        f"l = {DEFAULT_N_SAMPLES}, orthogonalised. Seconds: wall time of `spectral_embedding` "
        "after loading (structural graph, sampling and geodesics, affinity, eigenpairs "
        "included), min and median of the runs, each in a fresh process. Peak RSS: the "
        "process high-water mark (Python + NumPy + mesh); 'added' subtracts the mark before "
        "the embedding. The machine has 2 cores shared with other jobs during the run: "
        "times are upper bounds.\n\n"
        + markdown_table(["method", "mesh", "vertices", "l", "seconds (min)", "seconds (median)",
                          "peak RSS MB", "added MB"], rows)
    )


def run(args) -> int:
    from geoshape.bench.results import update_results_section

    parts = ("fidelity", "timing") if args.part == "all" else (args.part,)
    for part in parts:
        md = _fidelity(args) if part == "fidelity" else _timing(args)
        print(md)
        if not args.no_write:
            print(f"updated {update_results_section('spectral-' + part, md)}")
    return 0
