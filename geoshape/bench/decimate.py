"""``geoshape bench decimate``: the two decimation backends on a ≥ 1M-face mesh, time and memory.

Each (backend, ratio) runs in a fresh subprocess on the same mesh (an icosphere, subdivided
``--subdivisions`` times: 8 gives 1,310,720 faces) so its peak resident memory
(``ru_maxrss``) is its own. ``pymeshlab`` is :func:`geoshape_datasets_gen.decimate.decimate_exact`
(no optimal placement, exact kept ids, retried passes to meet the vertex target);
``fast-simplification`` is :func:`~geoshape_datasets_gen.decimate.decimate_fast` (vertices
move; the collapse map is replayed). Writes section ``decimate`` of docs/RESULTS.md.
"""

from __future__ import annotations

HELP = "decimation backends (PyMeshLab exact ids vs fast-simplification collapse map) on a 1M-face mesh"

_CHILD = """
import resource, sys, time
import trimesh
from geoshape_datasets_gen.decimate import decimate_exact, decimate_fast
backend, ratio, sub = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
m = trimesh.creation.icosphere(subdivisions=sub)
V, F = m.vertices, m.faces
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
d = decimate_fast(V, F, ratio) if backend == "fast-simplification" else decimate_exact(V, F, ratio)
seconds = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(len(F), len(d.F), d.fraction, seconds, before / 1024, peak / 1024)
"""


def add_arguments(parser) -> None:
    parser.add_argument("--subdivisions", type=int, default=8, help="icosphere subdivisions (8: 1.3M faces)")
    parser.add_argument("--ratios", default="0.5,0.1,0.01", help="vertex fractions (default 0.5,0.1,0.01)")
    parser.add_argument("--no-write", action="store_true", help="print only")


def run(args) -> int:
    import subprocess
    import sys

    from geoshape.bench.results import markdown_table, update_results_section

    rows = []
    for ratio in [float(r) for r in args.ratios.split(",")]:
        for backend in ("pymeshlab", "fast-simplification"):
            done = subprocess.run([sys.executable, "-c", _CHILD, backend, str(ratio), str(args.subdivisions)],
                                  capture_output=True, text=True)
            if done.returncode != 0:
                print(done.stderr, file=sys.stderr)
                return 1
            faces, out_faces, fraction, seconds, base_mb, peak_mb = done.stdout.split()
            rows.append([backend, f"{int(faces):,}", ratio, f"{float(fraction):.4f}", f"{int(out_faces):,}",
                         f"{float(seconds):.2f}", f"{float(peak_mb) - float(base_mb):.0f}",
                         f"{float(peak_mb):.0f}"])
            print(rows[-1])
    text = (
        "## Decimation backends on a large mesh\n\n"
        f"Command: `geoshape bench decimate --subdivisions {args.subdivisions} --ratios {args.ratios}`. "
        "One subprocess per row on the same icosphere; `pymeshlab` keeps every surviving vertex "
        "in place (ground truth: original ids, `.ids`), `fast-simplification` moves vertices "
        "(ground truth: the replayed collapse map, `.map`). Peak memory is `ru_maxrss` of the "
        "row's process; 'added' is the growth during decimation.\n\n"
        + markdown_table(["backend", "faces in", "vertex ratio asked", "got", "faces out", "seconds",
                          "memory added MB", "peak MB"], rows)
    )
    print(text)
    if not args.no_write:
        update_results_section("decimate", text)
    return 0
