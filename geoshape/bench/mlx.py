"""``geoshape bench mlx``: MeshLab ``.mlx`` scripts through ``geoshape run`` vs PyMeshLab's own loader.

Every script of ``--scripts`` (default: tests/data/mlx of the repository) runs on a sphere
with a hole and a duplicate face (and a second sphere for two-mesh scripts), once through a
geoshape ``MeshSet`` and once through PyMeshLab's ``load_filter_script`` +
``apply_filter_script``, each script in a fresh process (PyMeshLab remembers the last
values of some filters process-wide). See :mod:`geoshape_plugins.mlx_compat` for what
"same" means. Writes section ``mlx`` of docs/RESULTS.md.
"""

from __future__ import annotations

HELP = "MeshLab .mlx scripts (old and new styles) through geoshape run vs PyMeshLab's own script loader"

_CHILD = """
import json, sys, warnings
from geoshape_plugins.mlx_compat import compare_with_pymeshlab
r = compare_with_pymeshlab(sys.argv[1], sys.argv[2:])
print("RESULT " + json.dumps(r.__dict__))
"""


def add_arguments(parser) -> None:
    from pathlib import Path

    default = Path(__file__).resolve().parents[2] / "tests" / "data" / "mlx"
    parser.add_argument("--scripts", default=str(default), help=f"folder of .mlx scripts (default {default})")
    parser.add_argument("--no-write", action="store_true", help="print only")


def _inputs(folder):
    import numpy as np
    import trimesh

    from geoshape.io.mesh_io import save_mesh

    s = trimesh.creation.icosphere(4)
    save_mesh(folder / "a.ply", s.vertices, np.vstack([s.faces[10:], s.faces[:1]]))
    t = trimesh.creation.icosphere(3)
    save_mesh(folder / "b.ply", t.vertices * 1.05 + [0.02, 0.0, 0.0], t.faces)
    return folder / "a.ply", folder / "b.ply"


def run(args) -> int:
    import json
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from geoshape.bench.results import markdown_table, update_results_section
    from geoshape.errors import InvalidOptionError

    scripts = sorted(Path(args.scripts).glob("*.mlx"))
    if not scripts:
        raise InvalidOptionError(f"--scripts {args.scripts}: no .mlx files")
    rows, failures = [], 0
    with tempfile.TemporaryDirectory(prefix="geoshape-bench-mlx-") as tmp:
        a, b = _inputs(Path(tmp))
        for script in scripts:
            inputs = [a, b] if "two_mesh" in script.name else [a]
            out = subprocess.run([sys.executable, "-c", _CHILD, str(script), *map(str, inputs)],
                                 capture_output=True, text=True, check=False)
            line = next((x for x in out.stdout.splitlines() if x.startswith("RESULT ")), None)
            if line is None:
                rows.append([script.name, "", "", "crashed", "", "no", out.stderr.strip()[-120:]])
                failures += 1
                continue
            r = json.loads(line[len("RESULT "):])
            ok = not r["error"] and r["same"] is not False
            failures += not ok
            same = {True: "yes", False: "**no**", None: "—"}[r["same"]]
            mesh = f"{r['geoshape'][0]} / {r['geoshape'][1]}" if r["geoshape"] else "failed"
            rows.append([script.name, r["filters"], mesh, r["pymeshlab"], r["reference"], same,
                         r["error"] or len(r["warnings"])])
            print(f"{script.name}: {same}", file=sys.stderr)
    table = markdown_table(["script", "filters", "geoshape V / F", "PyMeshLab's own loader",
                            "geoshape compared with", "same mesh", "warnings / error"], rows)
    text = (f"## MeshLab .mlx scripts: geoshape run vs PyMeshLab's own loader\n\n"
            f"`geoshape bench mlx`: {len(scripts)} scripts (`{Path(args.scripts).name}`), "
            f"{len(scripts) - failures} run through "
            "`geoshape run` with PyMeshLab's result; \"refuses\" rows are scripts of older MeshLab versions "
            "that PyMeshLab's own loader stops on.\n\n" + table)
    print(text)
    if not args.no_write:
        update_results_section("mlx", text)
    return 0 if failures == 0 else 1
