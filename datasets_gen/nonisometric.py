"""Non-isometric pairs with exact ground truth: one template, two body proportions.

Each pair is built from one template of the articulated generator
(:mod:`geoshape_datasets_gen.articulated3d`: a watertight mesh with skinning weights on a
skeleton) turned into two *families* of proportions — long-armed vs short-armed bipeds,
heavy vs slim quadrupeds — and posed differently. Both meshes keep the template's vertex
ids and faces, so the ground truth is exact: vertex ``i`` of the source corresponds to
vertex ``i`` of the target. The pair is far from isometric: limb lengths and thicknesses
change by tens of per cent, so geodesic distances change with them.

Re-proportioning (:func:`reproportion`) scales, per limb group, the bone lengths and the
tube radii of the skeleton; every vertex follows the bones it is skinned to: in the frame
of a bone its position along the bone is stretched with the bone and its distance from the
bone with the local radius (beyond a bone's end, both with the joint's radius, so two bones
meeting at a joint move a vertex near it identically). The skinning weights blend the
per-bone positions, as for posing.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError

__all__ = ["FAMILIES", "MIRROR_AXIS", "NonisometricPair", "scaled_skeleton", "reproportion",
           "mirror_map", "make_pair", "write_nonisometric_set"]

#: per class, two families of proportions: limb group -> (length factor, thickness factor);
#: groups not named keep (1, 1)
FAMILIES: dict[str, dict[str, dict[str, tuple[float, float]]]] = {
    "biped": {
        "long-armed": {"arm": (1.35, 0.85), "hand": (1.2, 0.9), "shoulder": (1.1, 0.9)},
        "short-armed": {"arm": (0.72, 1.15), "hand": (0.85, 1.1), "shoulder": (0.9, 1.1)},
        # a gorilla-like body against a slim human-like one (paired with ``paired_families``): long, thick
        # arms and shoulders, short thick legs, a heavy torso and almost no neck. Against
        # "human-like" the arms grow by 30 % and the legs shrink by a third, every part thickens by
        # about half; the area grows by about a third.
        "ape-like": {"arm": (1.3, 1.35), "hand": (1.25, 1.2), "shoulder": (1.3, 1.3), "torso": (0.9, 1.45),
                     "hip": (1.1, 1.3), "leg": (0.72, 1.35), "foot": (0.9, 1.2), "neck": (0.5, 1.4),
                     "head": (0.9, 1.1)},
        "human-like": {"arm": (1.0, 0.9), "shoulder": (1.0, 0.9), "torso": (1.0, 0.9), "leg": (1.05, 0.9)},
    },
    "quadruped": {
        "heavy": {"body": (1.0, 1.4), "front": (0.85, 1.3), "hind": (0.85, 1.3), "neck": (0.9, 1.3),
                  "head": (1.0, 1.15), "tail": (0.9, 1.2)},
        "slim": {"body": (1.05, 0.75), "front": (1.2, 0.8), "hind": (1.2, 0.8), "neck": (1.2, 0.8),
                 "head": (1.0, 0.9), "tail": (1.15, 0.8)},
    },
}

#: the coordinate axis across which each class is left/right symmetric (about 0)
MIRROR_AXIS = {"biped": 0, "quadruped": 2}


def scaled_skeleton(skeleton, limbs: Sequence[str], factors: Mapping[str, tuple[float, float]]):
    """The skeleton with each joint's offset from its parent scaled by its limb group's
    length factor and its radius by the thickness factor (the root stays in place).

    Parameters
    ----------
    skeleton : articulated3d.Skeleton
    limbs : sequence of str
        Limb group of every joint (:func:`articulated3d.limb_groups`).
    factors : mapping
        Limb group -> ``(length factor, thickness factor)``, both > 0.

    Returns
    -------
    articulated3d.Skeleton
    """
    from geoshape_datasets_gen.articulated3d import Skeleton

    for g, (lf, tf) in factors.items():
        if not (lf > 0 and tf > 0):
            raise InvalidOptionError(f"limb group {g!r}: factors must be positive, got {(lf, tf)}")
    parents = skeleton.parents
    length = np.array([factors.get(g, (1.0, 1.0))[0] for g in limbs], dtype=np.float64)
    thick = np.array([factors.get(g, (1.0, 1.0))[1] for g in limbs], dtype=np.float64)
    pos = skeleton.positions.copy()
    for j, p in enumerate(parents):
        if p >= 0:
            pos[j] = pos[p] + length[j] * (skeleton.positions[j] - skeleton.positions[p])
    return Skeleton(pos, parents.copy(), skeleton.radii * thick, skeleton.axes.copy(),
                    skeleton.limits.copy(), skeleton.name)


def reproportion(template, factors: Mapping[str, tuple[float, float]]):
    """The template with other limb proportions: same faces, ids and skinning weights.

    Parameters
    ----------
    template : articulated3d.Template
    factors : mapping
        Limb group -> ``(length factor, thickness factor)``.

    Returns
    -------
    articulated3d.Template
        Rest vertices moved, skeleton scaled (:func:`scaled_skeleton`); pose it with
        :func:`articulated3d.pose_vertices`.

    Notes
    -----
    Time and memory O(n B) for n vertices and B bones.
    """
    from geoshape_datasets_gen.articulated3d import Template, limb_groups

    skA = template.skeleton
    skB = scaled_skeleton(skA, limb_groups(skA.name), factors)
    V, W = template.V, template.weights
    out = np.zeros_like(V)
    for i, (pa, ch) in enumerate(skA.bones):
        nz = np.flatnonzero(W[:, i] > 0)
        if len(nz) == 0:
            continue
        a, c = skA.positions[pa], skA.positions[ch]
        a2, c2 = skB.positions[pa], skB.positions[ch]
        L, L2 = float(np.linalg.norm(c - a)), float(np.linalg.norm(c2 - a2))
        u = (c - a) / L
        X = V[nz]
        s = (X - a) @ u
        radial = X - a - s[:, None] * u
        t = np.clip(s / L, 0.0, 1.0)
        k = (skB.radii[pa] + t * (skB.radii[ch] - skB.radii[pa])) / (
            skA.radii[pa] + t * (skA.radii[ch] - skA.radii[pa]))
        s2 = np.where(s < 0, s * k, np.where(s > L, L2 + (s - L) * k, s * (L2 / L)))
        out[nz] += W[nz, i, None] * (a2 + s2[:, None] * u + k[:, None] * radial)
    return Template(out, template.F, W, skB)


def mirror_map(V: np.ndarray, F: np.ndarray, axis: int) -> np.ndarray:
    """For each vertex, the vertex nearest its mirror image across the plane ``x[axis] = 0``
    (:func:`remesh.nearest_surface_vertex`): an approximate left/right ground truth, within
    one edge length."""
    from geoshape_datasets_gen.remesh import nearest_surface_vertex

    M = np.asarray(V, dtype=np.float64).copy()
    M[:, axis] *= -1.0
    return nearest_surface_vertex(M, V, F)


class NonisometricPair(NamedTuple):
    """Two differently proportioned, differently posed copies of one template.

    Attributes
    ----------
    source, target : (n, 3) float64
        Posed vertices; vertex ``i`` of one corresponds to vertex ``i`` of the other.
    F : (m, 3) int64
        Faces of both.
    families : (str, str)
        Proportion family of the source and the target.
    factors : (dict, dict)
        Limb group -> (length, thickness) factor actually used for each side.
    rest : (Template, Template)
        The re-proportioned rest templates of both sides (unposed).
    """

    source: np.ndarray
    target: np.ndarray
    F: np.ndarray
    families: tuple
    factors: tuple
    rest: tuple


def _jittered(factors: Mapping[str, tuple[float, float]], rng: np.random.Generator, jitter: float) -> dict:
    return {g: (float(lf * np.exp(rng.normal(0.0, jitter))), float(tf * np.exp(rng.normal(0.0, jitter))))
            for g, (lf, tf) in sorted(factors.items())}


def make_pair(template, families: tuple[str, str], seed, *, jitter: float = 0.04,
              amount: float = 1.0) -> NonisometricPair:
    """One non-isometric pair from a template: family ``families[0]`` posed as the source,
    ``families[1]`` as the target, each factor perturbed by ``exp(N(0, jitter))``.

    Parameters
    ----------
    template : articulated3d.Template
    families : (str, str)
        Names from ``FAMILIES[template.skeleton.name]``.
    seed : int or sequence of int
        Seed of the jitter and of both poses.
    jitter : float
        Log-normal spread of the family factors, in [0, 0.2].
    amount : float
        Fraction of the joint limits used by the poses (:func:`articulated3d.random_pose`).

    Examples
    --------
    >>> from geoshape_datasets_gen.articulated3d import build_template, make_skeleton
    >>> tpl = build_template(make_skeleton("biped"), target_vertices=800, resolution=64)
    >>> p = make_pair(tpl, ("long-armed", "short-armed"), seed=0)
    >>> p.source.shape == p.target.shape == tpl.V.shape
    True
    """
    from geoshape_datasets_gen.articulated3d import pose_vertices, random_pose

    cls = template.skeleton.name
    check_choice("class with proportion families", cls, tuple(FAMILIES))
    for f in families:
        check_choice(f"{cls} family", f, tuple(FAMILIES[cls]))
    jitter = float(jitter)
    if not (0.0 <= jitter <= 0.2):
        raise InvalidOptionError(f"jitter must lie in [0, 0.2], got {jitter!r}")
    rng = np.random.default_rng(seed)
    factors, rests, posed = [], [], []
    for fam in families:
        fac = _jittered(FAMILIES[cls][fam], rng, jitter)
        rest = reproportion(template, fac)
        angles = random_pose(rest.skeleton, rng.integers(0, 2**32), amount=amount)
        factors.append(fac)
        rests.append(rest)
        posed.append(pose_vertices(rest, angles))
    return NonisometricPair(posed[0], posed[1], template.F, tuple(families), tuple(factors), tuple(rests))


def _group_measures(skeleton, limbs: Sequence[str]) -> dict[str, tuple[float, float]]:
    """Limb group -> (total bone length into its joints, mean joint radius)."""
    out = {}
    for g in sorted(set(limbs)):
        js = [j for j, lg in enumerate(limbs) if lg == g]
        length = sum(float(np.linalg.norm(skeleton.positions[j] - skeleton.positions[skeleton.parents[j]]))
                     for j in js if skeleton.parents[j] >= 0)
        out[g] = (length, float(np.mean(skeleton.radii[js])))
    return out


def _paired_families(classes: Sequence[str], families: Mapping[str, Sequence[str]] | None) -> dict:
    """Per class of ``classes``, the two families its pairs use: ``families[cls]`` checked
    (two distinct names of :data:`FAMILIES` ``[cls]``), else the class's first two."""
    families = dict(families or {})
    for cls in families:
        if cls not in classes:
            raise InvalidOptionError(f"families given for class {cls!r}, which is not generated "
                                     f"(classes: {', '.join(classes)})")
    paired = {}
    for cls in classes:
        names = tuple(families.get(cls, tuple(FAMILIES[cls])[:2]))
        if len(names) != 2 or names[0] == names[1]:
            raise InvalidOptionError(f"{cls}: give two different families, got {list(names)}")
        paired[cls] = tuple(check_choice(f"{cls} family", f, tuple(FAMILIES[cls])) for f in names)
    return paired


def write_nonisometric_set(
    out_dir: str | os.PathLike,
    *,
    n_pairs: int = 30,
    classes: Sequence[str] = ("biped", "quadruped"),
    templates: int = 3,
    seed: int = 0,
    target_vertices: int = 5000,
    resolution: int = 128,
    variation: float = 0.1,
    jitter: float = 0.04,
    amount: float = 1.0,
    paired_families: Mapping[str, Sequence[str]] | None = None,
    progress=None,
) -> dict:
    """Write non-isometric pairs with exact ground truth in the ``pairs.csv`` layout.

    Pair ``k`` uses class ``classes[k % len(classes)]``; per class the pairs cycle over
    ``templates`` instances (proportions varied by ``variation`` as in the articulated
    generator) and alternate the direction between two families of :data:`FAMILIES`: those
    ``paired_families`` names for the class (e.g. ``{"biped": ("ape-like", "human-like")}``), else
    the class's first two (long- vs short-armed bipeds, heavy vs slim quadrupeds). Written into
    ``out_dir`` (each file atomically): ``p<k>_<class><instance>_<family>.off`` (two per
    pair), ``corres/<class><instance>.vts`` (ids 1..n: identity ground truth as landmarks),
    ``corres/<class><instance>.sym.vts`` (left/right mirror, :func:`mirror_map`),
    ``pairs.csv`` (source, target, both landmark files = the ``.vts``, the ``.sym.vts``),
    ``labels.csv`` (label = class) and ``generator.json`` (parameters; per pair the
    families, factors and the target/source ratio of every limb group's length and
    thickness).

    Returns
    -------
    dict
        ``{"files": [...], "pairs": [(source, target), ...], "ratios": [...]}``.

    Notes
    -----
    Time: ``len(classes) * templates`` template builds (about a second each) plus
    O(n B) per mesh.
    """
    from geoshape_datasets_gen.articulated3d import CLASSES, build_template, limb_groups, make_skeleton

    from geoshape.io.atomic import write_text_atomic
    from geoshape.io.mesh_io import save_mesh

    classes = [check_choice("class with proportion families", c, tuple(FAMILIES)) for c in classes]
    if not classes or len(set(classes)) != len(classes):
        raise InvalidOptionError(f"give distinct classes from {', '.join(FAMILIES)}, got {list(classes)}")
    for name, value, lo, hi in (("pairs", n_pairs, 1, 10000), ("templates", templates, 1, 100)):
        if isinstance(value, bool) or int(value) != value or not (lo <= int(value) <= hi):
            raise InvalidOptionError(f"{name} must be a whole number in [{lo}, {hi}], got {value!r}")
    n_pairs, templates, seed = int(n_pairs), int(templates), int(seed)
    paired = _paired_families(classes, paired_families)
    out = Path(out_dir)
    cache: dict = {}
    files, labels, rows, ratios, pairs_json = [], [], [], [], []
    for k in range(n_pairs):
        cls = classes[k % len(classes)]
        j = k // len(classes)
        inst = j % templates
        ci = CLASSES.index(cls)
        if (cls, inst) not in cache:
            inst_seed = int(np.random.SeedSequence([seed, ci, inst, 0x1505]).generate_state(1)[0])
            tpl = build_template(make_skeleton(cls, seed=inst_seed, variation=variation),
                                 target_vertices=target_vertices, resolution=resolution)
            tname = f"{cls}{inst}"
            n = len(tpl.V)
            write_text_atomic(out / "corres" / f"{tname}.vts", "".join(f"{i}\n" for i in range(1, n + 1)))
            sym = mirror_map(tpl.V, tpl.F, MIRROR_AXIS[cls])
            write_text_atomic(out / "corres" / f"{tname}.sym.vts",
                              "".join(f"{i + 1}\n" for i in sym.tolist()))
            cache[(cls, inst)] = (tpl, tname)
        tpl, tname = cache[(cls, inst)]
        fams = paired[cls]
        fams = fams if (j // templates + inst) % 2 == 0 else fams[::-1]
        pair = make_pair(tpl, fams, [seed, ci, k], jitter=jitter, amount=amount)
        names = [f"p{k:02d}_{tname}_{f}.off" for f in fams]
        for name, Vp in zip(names, (pair.source, pair.target), strict=True):
            save_mesh(out / name, Vp, pair.F)
        files += names
        labels += [cls, cls]
        rows.append(f"{names[0]},{names[1]},corres/{tname}.vts,corres/{tname}.vts,corres/{tname}.sym.vts\n")
        limbs = limb_groups(cls)
        ms, mt = (_group_measures(r.skeleton, limbs) for r in pair.rest)
        ratio = {g: {"length": mt[g][0] / ms[g][0] if ms[g][0] > 0 else 1.0, "thickness": mt[g][1] / ms[g][1]}
                 for g in ms}
        ratios.append(ratio)
        pairs_json.append({"source": names[0], "target": names[1], "template": tname, "families": list(fams),
                           "factors": list(pair.factors), "target_over_source": ratio})
        if progress is not None:
            progress(k + 1, n_pairs, names[0])
    write_text_atomic(out / "labels.csv", "file,label\n" + "".join(
        f"{f},{c}\n" for f, c in zip(files, labels, strict=True)))
    header = "source,target,source_landmarks,target_landmarks,target_symmetric_landmarks\n"
    write_text_atomic(out / "pairs.csv", header + "".join(rows))
    params = {
        "generator": "geoshape_datasets_gen.nonisometric.write_nonisometric_set",
        "pairs": n_pairs, "classes": classes, "templates": templates, "seed": seed,
        "target_vertices": int(target_vertices), "resolution": int(resolution),
        "variation": float(variation), "jitter": float(jitter), "amount": float(amount),
        "families": FAMILIES,
        "paired_families": {c: list(f) for c, f in paired.items()},
        "ground_truth": "exact identity: vertex i of the source corresponds to vertex i of the target "
                        "(both are the same template re-proportioned and posed; corres/<template>.vts "
                        "lists 1..n). .sym.vts: the vertex nearest the mirror image of each vertex of the "
                        "rest template (left/right, within one edge length).",
        "pair_details": pairs_json,
    }
    write_text_atomic(out / "generator.json", json.dumps(params, indent=2) + "\n")
    return {"files": files, "pairs": [(r.split(",")[0], r.split(",")[1]) for r in rows], "ratios": ratios}
