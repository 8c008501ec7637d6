"""``geoshape gen …``: write benchmarks whose ground truth is known by construction.

- ``gen decimate MESH --ratios 0.9,0.5,0.1 --out DIR`` writes ``DIR/<stem>_<pct>.off`` and
  ``DIR/<stem>_<pct>.ids`` (one 0-based original vertex id per line, per decimated vertex).
- ``gen spikes MESH --count N --height H --seed S --out OUT.off``: original vertices keep
  ids 0..n-1, spike tips are appended; H is a fraction of the bounding-box diagonal.
- ``gen stretch MESH (--scale SX,SY,SZ | --radius R --factor S) --out OUT.off``: same ids.
- ``gen articulated --out DIR [--classes …] [--instances K] [--poses N] [--seed S]``: posed
  procedural figures with ``labels.csv`` and ``pairs.csv`` (identity ground truth).

Every file is written atomically.
"""

from __future__ import annotations

import argparse

from geoshape.cli._common import (
    NONNEGATIVE_FLOAT,
    NONNEGATIVE_INT,
    POSITIVE_FLOAT,
    POSITIVE_INT,
    SEED,
    RangeType,
)
from geoshape.io.outputs import declare_outputs


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "gen",
        help="generate ground-truth benchmarks (decimation, spikes, stretching, articulated figures)",
        description="Generate meshes whose correspondence to the input is known exactly.",
    )
    sub = p.add_subparsers(dest="gen_command", metavar="GENERATOR")
    p.set_defaults(handler=_missing_generator, _gen_parser=p)

    d = sub.add_parser(
        "decimate",
        help="decimated copies keeping surviving vertices exactly in place, with .ids maps",
        description="Quadric edge collapse without optimal placement: every kept vertex keeps "
        "its original coordinates; DIR/<stem>_<pct>.ids gives its original 0-based id.",
    )
    d.add_argument("mesh", metavar="MESH")
    d.add_argument("--ratios", default="0.9,0.75,0.5,0.25,0.1",
                   help="comma-separated vertex fractions in (0, 1] (default: %(default)s)")
    d.add_argument("--out", required=True, metavar="DIR", help="output folder")
    d.add_argument("--no-preserve-boundary", action="store_true",
                   help="allow collapses that move boundary vertices")
    d.add_argument("--no-preserve-topology", action="store_true",
                   help="allow collapses that change genus (may create non-manifold output)")
    d.add_argument("--backend", default="pymeshlab",
                   help="pymeshlab (default: kept vertices stay in place, DIR/<stem>_<pct>.ids) or "
                   "fast-simplification (faster on large meshes; vertices move, DIR/<stem>_<pct>.map "
                   "gives for each original vertex the decimated vertex it collapsed into)")
    d.set_defaults(handler=run_decimate)
    declare_outputs(d, all_or_nothing=False, out="folder")

    s = sub.add_parser(
        "spikes",
        help="add outlier spikes (original ids kept, spike tips appended)",
        description="Pick COUNT random faces, split each at its centroid and pull the new "
        "vertex off the surface along the face normal by HEIGHT x bounding-box diagonal.",
    )
    s.add_argument("mesh", metavar="MESH")
    s.add_argument("--count", type=NONNEGATIVE_INT, required=True, help="number of spikes (one per face)")
    s.add_argument("--height", type=NONNEGATIVE_FLOAT, required=True,
                   help="tip offset as a fraction of the bounding-box diagonal (>= 0)")
    s.add_argument("--seed", type=SEED, default=0, help="seed of the face draw (default 0)")
    s.add_argument("--out", required=True, metavar="OUT", help="output mesh (.off, .ply, …)")
    s.set_defaults(handler=run_spikes)
    declare_outputs(s, out="mesh")

    t = sub.add_parser(
        "stretch",
        help="non-uniform axis scaling or stretching of one part (same ids)",
        description="Either --scale SX,SY,SZ (about the centroid) or --radius R --factor S "
        "(a graph-geodesic ball of radius R x diagonal around --center, scaled by S along "
        "--direction or its principal axis, with a smooth cosine falloff).",
    )
    t.add_argument("mesh", metavar="MESH")
    t.add_argument("--scale", help="three comma-separated positive axis factors")
    t.add_argument("--radius", type=POSITIVE_FLOAT, help="part stretch: ball radius, fraction of diagonal")
    t.add_argument("--factor", type=POSITIVE_FLOAT, help="part stretch: factor at the ball centre")
    t.add_argument("--center", type=NONNEGATIVE_INT, help="part stretch: centre vertex id (default: random)")
    t.add_argument("--direction", help="part stretch: x,y,z direction (default: principal axis)")
    t.add_argument("--seed", type=SEED, default=0, help="seed for the random centre (default 0)")
    t.add_argument("--out", required=True, metavar="OUT", help="output mesh")
    t.set_defaults(handler=run_stretch)
    declare_outputs(t, out="mesh")

    a = sub.add_parser(
        "articulated",
        help="posed procedural figures (biped, quadruped, hand, snake, octopus) with labels and pairs",
        description="Each instance is one watertight manifold template posed by linear-blend "
        "skinning: all poses of an instance share faces and vertex ids (identity ground truth).",
    )
    a.add_argument("--out", required=True, metavar="DIR", help="output folder")
    a.add_argument("--classes", default=None,
                   help="comma-separated classes (default: all of biped,quadruped,hand,snake,octopus)")
    a.add_argument("--instances", type=POSITIVE_INT, default=1, help="instances per class (default 1)")
    a.add_argument("--poses", type=POSITIVE_INT, default=4, help="poses per instance (default 4)")
    a.add_argument("--seed", type=SEED, default=0, help="seed (default 0)")
    a.add_argument("--vertices", type=RangeType(int, 500, 50000), default=3000,
                   help="vertices per mesh (default 3000)")
    a.add_argument("--resolution", type=RangeType(int, 48, 320), default=128,
                   help="voxels along the longest side before polygonisation (default 128)")
    a.add_argument("--variation", type=NONNEGATIVE_FLOAT, default=0.15,
                   help="intra-class limb length/thickness variation (default 0.15)")
    a.add_argument("--amount", type=RangeType(float, 0.0, 1.0), default=1.0,
                   help="fraction of the joint limits used by random poses (default 1)")
    a.set_defaults(handler=run_articulated)
    declare_outputs(a, all_or_nothing=False, out="folder")

    q = sub.add_parser(
        "perturb2d",
        help="a perturbed copy of a labelled silhouette folder: mirror, noise, notch or erode",
        description="Same file names, classes and labels.csv order as DIR, so scores compare "
        "directly with the clean set. mirror: every other image flipped left-right; noise: "
        "rough boundary; notch: two small bites; erode: thin parts opened away.",
    )
    q.add_argument("folder", metavar="DIR", help="folder with silhouette images and labels.csv")
    q.add_argument("--kind", required=True, help="mirror, noise, notch or erode")
    q.add_argument("--seed", type=SEED, default=0, help="seed (default 0)")
    q.add_argument("--out", required=True, metavar="OUT_DIR", help="output folder")
    q.set_defaults(handler=run_perturb2d)
    declare_outputs(q, all_or_nothing=False, out="folder")


def _missing_generator(args: argparse.Namespace) -> int:
    args._gen_parser.print_help()
    return 2


def _floats(option: str, text: str, count: int | None = None) -> list[float]:
    from geoshape.errors import InvalidOptionError

    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InvalidOptionError(f"{option} must be comma-separated numbers, got {text!r}") from None
    if not values or (count is not None and len(values) != count):
        want = f"{count} " if count else ""
        raise InvalidOptionError(f"{option} must give {want}comma-separated numbers, got {text!r}")
    return values


def decimation_names(stem: str, ratios) -> list[str]:
    """Output stems ``<stem>_<pct>`` (pct = round(100 ratio), 3 digits); clashes refused."""
    from geoshape.errors import InvalidOptionError

    names = [f"{stem}_{round(100 * r):03d}" for r in ratios]
    if len(set(names)) != len(names):
        raise InvalidOptionError(
            f"ratios {list(ratios)} give the same percentage file name twice; use distinct percentages"
        )
    return names


def run_decimate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from geoshape_datasets_gen.decimate import DECIMATION_BACKENDS, check_ratio, decimate_exact, decimate_fast

    from geoshape._options import check_choice
    from geoshape.io.atomic import write_text_atomic
    from geoshape.io.datasets import mesh_stem
    from geoshape.io.mesh_io import load_mesh, save_mesh

    check_choice("decimation backend", args.backend, DECIMATION_BACKENDS)
    ratios = [check_ratio(r) for r in _floats("--ratios", args.ratios)]
    names = decimation_names(mesh_stem(args.mesh), ratios)
    V, F = load_mesh(args.mesh)
    out = Path(args.out)
    for ratio, name in zip(ratios, names, strict=True):
        if args.backend == "fast-simplification":
            col = decimate_fast(V, F, ratio)
            save_mesh(out / f"{name}.off", col.V, col.F)
            write_text_atomic(out / f"{name}.map", "".join(f"{i}\n" for i in col.collapsed_to.tolist()))
            print(f"{out / (name + '.off')}: {len(col.V)} of {len(V)} vertices (asked {ratio:.3g}, got "
                  f"{col.fraction:.4f}), {len(col.F)} faces; {name}.map: original vertex -> decimated vertex")
            continue
        dec = decimate_exact(
            V, F, ratio,
            preserve_boundary=not args.no_preserve_boundary,
            preserve_topology=not args.no_preserve_topology,
        )
        save_mesh(out / f"{name}.off", dec.V, dec.F)
        write_text_atomic(out / f"{name}.ids", "".join(f"{i}\n" for i in dec.orig_ids.tolist()))
        print(f"{out / (name + '.off')}: {len(dec.V)} of {len(V)} vertices "
              f"(asked {ratio:.3g}, got {dec.fraction:.4f}), {len(dec.F)} faces")
    return 0


def run_spikes(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.spikes import add_spikes

    from geoshape.io.mesh_io import load_mesh, save_mesh

    V, F = load_mesh(args.mesh)
    res = add_spikes(V, F, args.count, args.height, seed=args.seed)
    save_mesh(args.out, res.V, res.F)
    offset = float(res.offsets[0]) if len(res.offsets) else 0.0
    print(f"{args.out}: {len(V)} original vertices (ids 0..{len(V) - 1}) + {len(res.offsets)} "
          f"spikes at distance {offset:.6g} from their faces")
    return 0


def run_stretch(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.stretch import stretch_axes, stretch_part

    from geoshape.errors import InvalidOptionError
    from geoshape.io.mesh_io import load_mesh, save_mesh

    part = args.radius is not None or args.factor is not None
    if args.scale is not None and part:
        raise InvalidOptionError("give --scale or --radius/--factor, not both")
    if args.scale is None and not part:
        raise InvalidOptionError("give --scale SX,SY,SZ (axis scaling) or --radius R --factor S (part)")
    if part and (args.radius is None or args.factor is None):
        raise InvalidOptionError("a part stretch needs both --radius and --factor")
    V, F = load_mesh(args.mesh)
    if not part:
        Vs = stretch_axes(V, F, _floats("--scale", args.scale, 3))
        what = f"axes scaled by {args.scale}"
    else:
        direction = None if args.direction is None else _floats("--direction", args.direction, 3)
        res = stretch_part(V, F, radius=args.radius, factor=args.factor, center=args.center,
                           direction=direction, seed=args.seed)
        Vs = res.V
        what = (f"part around vertex {res.center} ({int((res.weights > 0).sum())} vertices) "
                f"stretched by {args.factor:g}")
    save_mesh(args.out, Vs, F)
    print(f"{args.out}: {len(V)} vertices, same ids and faces; {what}")
    return 0


def run_articulated(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.articulated3d import CLASSES, write_collection

    classes = CLASSES if args.classes is None else [c.strip() for c in args.classes.split(",") if c.strip()]
    res = write_collection(
        args.out, classes=classes, instances=args.instances, poses=args.poses, seed=args.seed,
        variation=args.variation, amount=args.amount, target_vertices=args.vertices,
        resolution=args.resolution,
    )
    print(f"{args.out}: {len(res['files'])} meshes in {len(set(res['labels']))} classes, "
          f"{len(res['pairs'])} pairs with identity ground truth (labels.csv, pairs.csv)")
    return 0


def run_perturb2d(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.perturb2d import PERTURBATIONS, perturb_collection

    from geoshape._options import check_choice

    check_choice("perturbation", args.kind, PERTURBATIONS)
    paths = perturb_collection(args.folder, args.out, args.kind, seed=args.seed)
    print(f"{args.out}: {len(paths)} {args.kind} silhouettes with labels.csv")
    return 0
