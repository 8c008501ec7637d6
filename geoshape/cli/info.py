"""``geoshape info MESH…``: print what is in each mesh and what is wrong with it."""

from __future__ import annotations

import argparse
import sys


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "info",
        help="report vertices, faces, components, holes, non-manifold elements of meshes",
        description="Print mesh_report for each mesh (OFF/OBJ/PLY/STL, optionally .gz).",
    )
    p.add_argument("meshes", nargs="+", metavar="MESH", help="mesh files")
    p.add_argument("--json", action="store_true", help="print one JSON object per mesh (a JSON list)")
    p.set_defaults(handler=run)


def _text(path: str, rep: dict, problems: list[str]) -> str:
    lo, hi = rep["bbox_min"], rep["bbox_max"]
    lines = [
        f"{path}",
        f"  vertices {rep['vertices']}, faces {rep['faces']}, edges {rep['edges']}, "
        f"components {rep['components']}, Euler characteristic {rep['euler_characteristic']}",
        f"  area {rep['area']:.6g}, bbox [{lo[0]:.4g}, {lo[1]:.4g}, {lo[2]:.4g}] – "
        f"[{hi[0]:.4g}, {hi[1]:.4g}, {hi[2]:.4g}] (diagonal {rep['bbox_diagonal']:.4g})",
        "  defects: " + ("; ".join(problems) if problems else "none (closed 2-manifold)"),
    ]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from geoshape.cli._common import print_json
    from geoshape.errors import GeoshapeError
    from geoshape.geometry.report import mesh_report, report_problems
    from geoshape.io.mesh_io import load_mesh

    results, failed = [], 0
    for path in args.meshes:
        try:
            V, F = load_mesh(path)
            rep = mesh_report(V, F, name=path)
        except GeoshapeError as exc:
            failed += 1
            print(f"geoshape info: error: {exc}", file=sys.stderr)
            continue
        problems = report_problems(rep)
        if args.json:
            results.append({"file": path, **rep, "problems": problems})
        else:
            print(_text(path, rep, problems))
    if args.json:
        print_json(results)
    return 2 if failed else 0
