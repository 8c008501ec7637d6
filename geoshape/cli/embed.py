"""``geoshape embed MESH -o OUT.ply``: spectral embedding of a mesh (exact or Nyström).

Writes the embedded mesh (first three embedding coordinates as vertex positions, the
mesh's faces) to ``OUT``, all ``K`` coordinates to ``OUT.npy`` beside it, and prints the
eigenvalues, the parameters used and the wall time of the computation (after loading).
With ``--json``: one JSON object on stdout with ``n_vertices``, ``eigenvalues``,
``seconds`` and the rest.
"""

from __future__ import annotations

import argparse

from geoshape.cli._common import POSITIVE_INT, SEED, RangeType
from geoshape.io.outputs import declare_outputs


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "embed",
        help="spectral embedding of a mesh (geodesic Gaussian affinity, exact or Nystrom)",
        description="Spectral embedding of a mesh (thesis ch. 4): Gaussian affinity of geodesic, "
        "Euclidean or combined distances, top eigenvectors scaled by sqrt(eigenvalue), first "
        "eigenvector dropped. Exact up to 2000 vertices, Nystrom above or when --samples is given.",
    )
    p.add_argument("mesh", metavar="MESH", help="input mesh (OFF/OBJ/PLY/STL, optionally .gz)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.ply",
                   help="embedded mesh to write; all coordinates go to OUT.npy beside it")
    p.add_argument("--dims", type=POSITIVE_INT, default=5, metavar="K",
                   help="embedding dimensions K (K+1 eigenpairs, the first dropped; default 5)")
    p.add_argument("--samples", type=RangeType(int, 2), default=None, metavar="L",
                   help="Nystrom samples L (forces Nystrom; default: exact for <= 2000 vertices, "
                   "else Nystrom with 50 samples)")
    p.add_argument("--method", choices=("auto", "exact", "nystrom"), default="auto",
                   help="eigenpairs from all-pairs distances (exact) or sampled rows (nystrom)")
    p.add_argument("--affinity", choices=("geodesic", "euclidean", "combined"),
                   default="geodesic", help="distances under the Gaussian (default geodesic)")
    p.add_argument("--sigma", default="max", metavar="max|mean|RHO",
                   help="Gaussian width: max distance (default), mean distance, or RHO x mean "
                   "(RHO >= 1e-6)")
    p.add_argument("--geodesics", choices=("graph", "heat", "exact"), default="graph",
                   help="geodesic backend (default graph: shortest paths on the structural graph)")
    p.add_argument("--scaling", choices=("sqrt", "eigenvalue", "none", "squared_sphere"),
                   default="sqrt", help="eigenvector scaling (default sqrt: U sqrt(lambda))")
    p.add_argument("--center", action="store_true",
                   help="centre the kernel instead of dropping the first eigenvector")
    p.add_argument("--no-orthogonalize", action="store_true",
                   help="Nystrom: keep the raw extended eigenvectors (not orthogonalised)")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the first max-min sample")
    p.add_argument("--png", metavar="FILE.png", default=None,
                   help="also render the mesh coloured by the first embedding coordinate")
    p.add_argument("--html", metavar="VIEW.html", default=None,
                   help="offline interactive viewer (one file): the mesh and the embedded mesh, "
                   "coloured by the embedding coordinates")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(handler=run)
    declare_outputs(p, output="mesh", png="picture", html="html")


def run(args: argparse.Namespace) -> int:
    import time

    from geoshape.cli._common import print_json
    from geoshape.errors import InvalidMeshError
    from geoshape.io.mesh_io import load_mesh
    from geoshape.plot.meshes import render_mesh_png
    from geoshape.spectral.affinity import parse_sigma
    from geoshape.spectral.embedded_mesh import save_embedding_mesh, sidecar_path
    from geoshape.spectral.embedding import spectral_embedding

    sigma = parse_sigma(args.sigma)
    V, F = load_mesh(args.mesh)
    method = args.method
    if args.samples is not None and method == "auto":
        method = "nystrom"
    t0 = time.perf_counter()
    try:
        emb = spectral_embedding(
            V, F, k=args.dims, method=method, n_samples=args.samples, affinity=args.affinity,
            sigma=sigma, geodesics=args.geodesics, scaling=args.scaling,
            first="center" if args.center else "drop",
            orthogonalize=not args.no_orthogonalize, seed=args.seed,
        )
    except InvalidMeshError as exc:  # name the file: the library only sees arrays
        raise InvalidMeshError(f"{args.mesh}: {exc}") from None
    seconds = time.perf_counter() - t0
    out = save_embedding_mesh(args.output, emb.coords, F)
    if args.png:
        render_mesh_png(args.png, V, F, emb.coords[:, 0], title="embedding coordinate 1")
    if args.html:
        from geoshape.io.datasets import mesh_stem
        from geoshape.viewer.html import embedding_html, write_html

        write_html(args.html, embedding_html(
            V, F, emb.coords, name=mesh_stem(args.mesh),
            subtitle=f"{emb.coords.shape[1]} coordinates, {args.affinity} affinity, {seconds:.2f} s"))
    params = {k: v for k, v in emb.params.items() if k != "samples"}
    result = {
        "mesh": args.mesh,
        "output": str(out),
        "coordinates": str(sidecar_path(out)),
        "n_vertices": int(len(V)),
        "n_faces": int(len(F)),
        "dims": int(emb.coords.shape[1]),
        "eigenvalues": emb.eigenvalues,
        "seconds": seconds,
        "params": params,
    }
    if args.json:
        print_json(result)
        return 0
    ev = ", ".join(f"{x:.6g}" for x in emb.eigenvalues)
    print(f"{args.mesh}: {len(V)} vertices, {len(F)} faces")
    print(f"eigenvalues: [{ev}]")
    print("parameters: " + ", ".join(f"{k}={v}" for k, v in params.items()))
    print(f"wrote {out} and {sidecar_path(out)} ({emb.coords.shape[1]} coordinates)")
    print(f"time: {seconds:.3f} s")
    return 0
