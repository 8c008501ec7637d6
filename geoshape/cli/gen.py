"""``geoshape gen …``: write benchmarks whose ground truth is known by construction.

- ``gen decimate MESH --ratios 0.9,0.5,0.1 --out DIR`` writes ``DIR/<stem>_<pct>.off`` and
  ``DIR/<stem>_<pct>.ids`` (one 0-based original vertex id per line, per decimated vertex).
- ``gen spikes MESH --count N --height H --seed S --out OUT.off``: original vertices keep
  ids 0..n-1, spike tips are appended; H is a fraction of the bounding-box diagonal.
- ``gen stretch MESH (--scale SX,SY,SZ | --radius R --factor S) --out OUT.off``: same ids.
- ``gen articulated --out DIR [--classes …] [--instances K] [--poses N] [--seed S]``: posed
  procedural figures with ``labels.csv`` and ``pairs.csv`` (identity ground truth).
- ``gen mixed3d --out DIR [--per-class 12] [--seed S] [--vertices N]``: a retrieval collection
  of 10 articulated and 10 rigid classes with ``labels.csv`` (some meshes with defects).
- ``gen remesh MESH --vertices N --seed S --out DIR``: an independently remeshed copy
  ``DIR/<stem>.off`` with ``<stem>.to_original.vts`` / ``<stem>.from_original.vts``.
- ``gen remesh-set --dataset NAME|DIR [--pairs N] --vertices N --seed S --out DIR``: both
  meshes of every pair remeshed independently, composed ground truth, ``pairs.csv``.
- ``gen nonisometric --out DIR [--pairs N] [--seed S] [--families CLASS=A:B]``: one template in
  two body proportions (long/short arms, heavy/slim, ape-like/human-like), posed; exact ground
  truth, ``pairs.csv``.

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

    x = sub.add_parser(
        "mixed3d",
        help="retrieval collection: 10 articulated + 10 rigid classes, re-tessellated, some with defects",
        description="Articulated creatures (human, teddy, hand, ant, octopus, fourleg, fish, bird, "
        "pliers, armadillo: instances x 3 poses) and rigid objects (cup, vase, bottle, chair, table, "
        "spring, gear, bearing, airplane, glasses: fused primitives), each re-tessellated to about "
        "--vertices vertices, randomly rotated, scaled and moved; about --defects of them with holes, "
        "flipped faces, several components or a mild axis stretch. Writes DIR/<class>_<k>.off, "
        "labels.csv (file,label), defects.csv, generator.json and README.txt.",
    )
    x.add_argument("--out", required=True, metavar="DIR", help="output folder")
    x.add_argument("--per-class", type=RangeType(int, 1, 300), default=12,
                   help="meshes per class (default 12)")
    x.add_argument("--classes", default=None, help="comma-separated classes (default: all 20)")
    x.add_argument("--seed", type=SEED, default=0, help="seed (default 0)")
    x.add_argument("--vertices", type=RangeType(int, 300, 50000), default=2000,
                   help="typical vertices per mesh, each drawn in x[0.75, 1.3] (default 2000)")
    x.add_argument("--defects", type=RangeType(float, 0.0, 1.0), default=0.1,
                   help="fraction of meshes with a defect (default 0.1)")
    x.add_argument("--resolution", type=RangeType(int, 48, 320), default=112,
                   help="voxels along the longest side when polygonising (default 112)")
    x.set_defaults(handler=run_mixed3d)
    declare_outputs(x, all_or_nothing=False, out="folder")

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
    _register_dev_sets(sub)


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


def _family_pairs(option: str, text: str) -> dict[str, tuple[str, str]]:
    """``"biped=ape-like:human-like,…"`` → ``{"biped": ("ape-like", "human-like"), …}`` (names
    checked by the generator)."""
    from geoshape.errors import InvalidOptionError

    out = {}
    for item in filter(str.strip, text.split(",")):
        cls, eq, names = item.partition("=")
        if not eq or names.count(":") != 1:
            raise InvalidOptionError(f"{option}: {item.strip()!r} is not CLASS=A:B")
        out[cls.strip()] = tuple(n.strip() for n in names.split(":"))
    return out


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


def run_mixed3d(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.mixed3d import CLASSES, write_collection

    classes = CLASSES if args.classes is None else [c.strip() for c in args.classes.split(",") if c.strip()]
    res = write_collection(
        args.out, classes=classes, per_class=args.per_class, seed=args.seed, vertices=args.vertices,
        defect_fraction=args.defects, resolution=args.resolution,
    )
    n_def = sum(d != "none" for d in res["defects"])
    print(f"{args.out}: {len(res['files'])} meshes in {len(set(res['labels']))} classes, {n_def} with "
          f"defects (labels.csv, defects.csv, README.txt), {res['seconds']:.1f} s")
    return 0


def run_perturb2d(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.perturb2d import PERTURBATIONS, perturb_collection

    from geoshape._options import check_choice

    check_choice("perturbation", args.kind, PERTURBATIONS)
    paths = perturb_collection(args.folder, args.out, args.kind, seed=args.seed)
    print(f"{args.out}: {len(paths)} {args.kind} silhouettes with labels.csv")
    return 0


# ----------------------------------------------------------------------- dev sets (issue #14)


def _register_dev_sets(sub) -> None:
    vertices = RangeType(int, 50, 1_000_000)  # remesh.MIN_VERTICES, MAX_VERTICES (no import at startup)
    r = sub.add_parser(
        "remesh",
        help="an independently remeshed copy of a mesh, with ground truth to the original",
        description="Isotropic remeshing of a randomly rotated, shuffled and slid copy (the seed "
        "changes the triangulation), decimated to N vertices and put back on the original "
        "surface. DIR/<stem>.to_original.vts: line i = 1-based original vertex of new vertex i "
        "(nearest corner of the original face holding it); DIR/<stem>.from_original.vts: line v "
        "= 1-based new vertex of original vertex v.",
    )
    r.add_argument("mesh", metavar="MESH")
    r.add_argument("--vertices", type=vertices, default=5000, help="vertex count (default 5000)")
    r.add_argument("--seed", type=SEED, default=0, help="seed of the triangulation (default 0)")
    r.add_argument("--iterations", type=RangeType(int, 1, 50), default=6,
                   help="isotropic remeshing rounds (default 6)")
    r.add_argument("--out", required=True, metavar="DIR", help="output folder")
    r.set_defaults(handler=run_remesh)
    declare_outputs(r, out="folder")

    s = sub.add_parser(
        "remesh-set",
        help="a correspondence set with both meshes of every pair remeshed independently",
        description="Each mesh of the chosen pairs is remeshed once with its own seed; the ground "
        "truth is composed: remeshed source vertex -> original source vertex -> the dataset's "
        "ground truth -> original target vertex -> remeshed target vertex. Writes meshes/, "
        "maps/, gt/, pairs.csv (and pairs_features.csv for SCAPE), labels.csv, generator.json.",
    )
    s.add_argument("--dataset", required=True,
                   help="dataset folder or set name under the data folder (scape, tosca_r5k, …)")
    s.add_argument("--pairs", type=POSITIVE_INT, default=None,
                   help="number of pairs (default all rows of the pairs file; more than it lists: "
                   "identity sets only, extra seeded random pairs)")
    s.add_argument("--pairs-file", default=None,
                   help="pairs file in the dataset (default pairs_subset.csv if present, else pairs.csv)")
    s.add_argument("--vertices", type=vertices, default=5000, help="vertices per mesh (default 5000)")
    s.add_argument("--seed", type=SEED, default=0, help="seed (default 0)")
    s.add_argument("--iterations", type=RangeType(int, 1, 50), default=6,
                   help="isotropic remeshing rounds (default 6)")
    s.add_argument("--out", required=True, metavar="DIR", help="output folder (outside the dataset)")
    s.set_defaults(handler=run_remesh_set)
    declare_outputs(s, all_or_nothing=False, out="folder")

    n = sub.add_parser(
        "nonisometric",
        help="non-isometric pairs: one template in two body proportions, exact ground truth",
        description="Pairs of long-armed vs short-armed bipeds and heavy vs slim quadrupeds: one "
        "articulated template per pair re-proportioned (limb lengths and thicknesses) and posed "
        "twice; same vertex ids and faces, so vertex i corresponds to vertex i.",
    )
    n.add_argument("--out", required=True, metavar="DIR", help="output folder")
    n.add_argument("--pairs", type=RangeType(int, 1, 10000), default=30, help="number of pairs (default 30)")
    n.add_argument("--classes", default="biped,quadruped",
                   help="comma-separated classes (default: %(default)s)")
    n.add_argument("--templates", type=RangeType(int, 1, 100), default=3,
                   help="templates (instances) per class the pairs cycle over (default 3)")
    n.add_argument("--seed", type=SEED, default=0, help="seed (default 0)")
    n.add_argument("--vertices", type=RangeType(int, 500, 50000), default=5000,
                   help="vertices per mesh (default 5000)")
    n.add_argument("--resolution", type=RangeType(int, 48, 320), default=128,
                   help="voxels along the longest side before polygonisation (default 128)")
    n.add_argument("--variation", type=RangeType(float, 0.0, 0.3), default=0.1,
                   help="proportion variation between templates of a class (default 0.1)")
    n.add_argument("--jitter", type=RangeType(float, 0.0, 0.2), default=0.04,
                   help="log-normal spread of each family's factors per pair (default 0.04)")
    n.add_argument("--amount", type=RangeType(float, 0.0, 1.0), default=1.0,
                   help="fraction of the joint limits used by random poses (default 1)")
    n.add_argument("--families", default=None, metavar="CLASS=A:B,...",
                   help="the two families a class's pairs use, e.g. biped=ape-like:human-like (default: "
                   "long-armed:short-armed bipeds, heavy:slim quadrupeds)")
    n.set_defaults(handler=run_nonisometric)
    declare_outputs(n, all_or_nothing=False, out="folder")


def run_remesh(args: argparse.Namespace) -> int:
    from pathlib import Path

    from geoshape_datasets_gen.remesh import nearest_surface_vertex, remesh

    from geoshape.io.atomic import write_text_atomic
    from geoshape.io.datasets import mesh_stem
    from geoshape.io.mesh_io import load_mesh, save_mesh

    V, F = load_mesh(args.mesh)
    res = remesh(V, F, args.vertices, args.seed, iterations=args.iterations)
    from_orig = nearest_surface_vertex(V, res.V, res.F)
    out, stem = Path(args.out), mesh_stem(args.mesh)
    save_mesh(out / f"{stem}.off", res.V, res.F)
    for suffix, ids in (("to_original", res.to_original), ("from_original", from_orig)):
        write_text_atomic(out / f"{stem}.{suffix}.vts", "".join(f"{i + 1}\n" for i in ids.tolist()))
    print(f"{out / (stem + '.off')}: {len(res.V)} vertices, {len(res.F)} faces (from {len(V)}); "
          f"{stem}.to_original.vts: new -> original vertex (1-based, mean distance "
          f"{float(res.distance.mean()):.4g}); {stem}.from_original.vts: original -> new vertex")
    return 0


def run_remesh_set(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.remesh import write_remeshed_set

    res = write_remeshed_set(
        args.dataset, args.out, n_pairs=args.pairs, pairs_file=args.pairs_file,
        n_vertices=args.vertices, seed=args.seed, iterations=args.iterations,
        progress=lambda done, total, name: print(f"[{done}/{total}] {name}", flush=True),
    )
    extra = " and pairs_features.csv" if res["features"] else ""
    landmarks = [p[2] for p in res["pairs"]]
    print(f"{args.out}: {len(res['meshes'])} remeshed meshes, {len(res['pairs'])} pairs (pairs.csv{extra}), "
          f"{min(landmarks)}-{max(landmarks)} ground-truth landmarks per pair")
    return 0


def run_nonisometric(args: argparse.Namespace) -> int:
    from geoshape_datasets_gen.nonisometric import write_nonisometric_set

    classes = [c.strip() for c in args.classes.split(",") if c.strip()]
    families = _family_pairs("--families", args.families or "")
    res = write_nonisometric_set(
        args.out, n_pairs=args.pairs, classes=classes, templates=args.templates, seed=args.seed,
        target_vertices=args.vertices, resolution=args.resolution, variation=args.variation,
        jitter=args.jitter, amount=args.amount, paired_families=families or None,
    )
    print(f"{args.out}: {len(res['files'])} meshes, {len(res['pairs'])} pairs with exact identity ground "
          f"truth (pairs.csv, corres/*.vts, labels.csv)")
    return 0
