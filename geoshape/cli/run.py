"""``geoshape run -i A.ply [-i B.ply] -o OUT.ply -s SCRIPT.mlx``: a meshlabserver-like runner.

Loads the input meshes in order (the first is current), checks every filter name of the
script, applies the filters (geoshape's and PyMeshLab's), writes the current mesh (with
its colours) to ``-o``, and prints one line per filter with its time and outputs.
``--save-script`` writes the script as run, with every parameter resolved, so running it
again reproduces the output.
"""

from __future__ import annotations

import argparse

from geoshape.io.outputs import declare_outputs


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "run",
        help="apply an .mlx filter script (geoshape + PyMeshLab filters) to meshes",
        description="Apply a MeshLab .mlx filter script mixing geoshape filters (see 'geoshape "
        "filters') and PyMeshLab filters to the input meshes; write the current mesh.",
    )
    p.add_argument("-i", "--input", action="append", required=True, metavar="MESH",
                   help="input mesh (repeat for several; the first is the current mesh)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.ply",
                   help="where to write the current mesh at the end (with vertex colours)")
    p.add_argument("-s", "--script", required=True, metavar="SCRIPT.mlx", help="filter script")
    p.add_argument("--save-script", metavar="USED.mlx", default=None,
                   help="write the script as run, with every parameter explicit")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.set_defaults(handler=run)
    declare_outputs(p, output="mesh", save_script="text")


def _short(value) -> str:
    import numpy as np

    if isinstance(value, np.ndarray):
        if value.size <= 6:
            return np.array2string(value, precision=4, separator=", ")
        return f"array{value.shape}"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)) and len(value) > 6:
        return f"[{len(value)} items]"
    return str(value)


def run(args: argparse.Namespace) -> int:
    import logging
    import sys
    import time
    import warnings

    from geoshape_plugins.meshset import MeshSet

    log = logging.getLogger("geoshape.run")

    def progress(fraction: float, message: str = "") -> None:
        log.info("%s: %.0f%%", message or "progress", 100 * fraction)

    t0 = time.perf_counter()
    ms = MeshSet(progress=progress)
    for path in args.input:
        ms.load_new_mesh(path)
    ms.set_current_mesh(0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            applied = ms.apply_filter_script(args.script)
        finally:
            for w in caught:  # one line each on stderr, without the source line
                print(f"geoshape run: warning: {w.message}", file=sys.stderr)
    out = ms.save_current_mesh(args.output)
    if args.save_script:
        ms.save_filter_script(args.save_script)
    seconds = time.perf_counter() - t0
    if args.json:
        from geoshape.cli._common import print_json

        print_json({
            "inputs": args.input, "output": str(out), "script": args.script,
            "saved_script": args.save_script, "seconds": seconds,
            "filters": [{"id": a.script.id, "name": a.script.name, "origin": a.origin,
                         "seconds": a.seconds, "outputs": a.outputs} for a in applied],
        })
        return 0
    for a in applied:
        shown = ", ".join(f"{k}={_short(v)}" for k, v in a.outputs.items())
        print(f"{a.script.line:>4}: {a.script.id} ({a.origin}) {a.seconds:.2f} s"
              + (f": {shown}" if shown else ""))
    mesh = ms.current_mesh()
    print(f"wrote {out} ({mesh.vertex_number()} vertices, {mesh.face_number()} faces"
          f"{', coloured' if mesh.colors is not None else ''})"
          + (f" and {args.save_script}" if args.save_script else ""))
    print(f"{len(applied)} filters in {seconds:.2f} s")
    return 0
