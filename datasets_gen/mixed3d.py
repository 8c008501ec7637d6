"""A mixed articulated + rigid 3D retrieval collection that resembles real shape databases.

Twenty classes in the spirit of the SHREC 2007 watertight track: ten articulated creature
classes (:mod:`creatures3d`: several instances with their own proportions, each in several
poses) and ten rigid object classes (:mod:`rigid3d`: proportions and optional details drawn
per object, the parts fused into one watertight surface by :mod:`union3d`). Then, per mesh:

1. **re-tessellation** to about ``vertices`` vertices (x 0.75-1.3, drawn per mesh) in one of
   two styles drawn independently of the class: ``uniform`` (isotropic remeshing: even,
   near-equilateral triangles) or ``decimated`` (quadric edge collapse of the dense
   polygonised surface: curvature-adaptive, irregular triangles), so the triangulation
   does not give the class away;
2. **defects** on about ``defect_fraction`` of the meshes (:mod:`defects3d`, cycled over the
   kinds): ``components`` (a rigid object's parts left as separate, intersecting shells, or
   small loose blobs next to a one-piece shape), ``holes`` (a few faces deleted), ``flipped``
   (patches of faces wound the other way), ``stretch`` (each axis scaled by 0.9-1.1);
3. **random similarity**: unit bounding-box diagonal, then a uniform random rotation, a
   log-uniform scale in [0.5, 2] and a translation, so neither pose nor size carries the
   class either.

Every mesh is drawn from its own seed (``seed``, class, index), so the same arguments give
byte-identical files.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
from geoshape_datasets_gen._topology import topology_report
from geoshape_datasets_gen.creatures3d import CREATURE_CLASSES, creature_pose, creature_template
from geoshape_datasets_gen.defects3d import DEFECTS, add_debris, flip_patches, punch_holes, stretch_axes
from geoshape_datasets_gen.rigid3d import RIGID_CLASSES, build_rigid
from geoshape_datasets_gen.union3d import concatenate, fuse_parts

from geoshape._options import check_choice, check_whole
from geoshape.errors import InvalidOptionError

__all__ = ["CLASSES", "TESSELLATIONS", "Shape", "retessellate", "random_rotation", "random_similarity",
           "generate_class", "write_collection"]

CLASSES = CREATURE_CLASSES + RIGID_CLASSES

#: re-tessellation styles, drawn per mesh with these probabilities
TESSELLATIONS = ("uniform", "decimated")
_STYLE_P = (0.6, 0.4)

#: poses per creature instance (a class of 12 = 4 instances x 3 poses)
POSES_PER_INSTANCE = 3


class Shape(NamedTuple):
    """One generated mesh.

    Attributes
    ----------
    V : (n, 3) float64
    F : (m, 3) int64
    label : str
        Class.
    defect : str
        ``"none"`` or one of :data:`geoshape_datasets_gen.defects3d.DEFECTS`.
    tessellation : str
        One of :data:`TESSELLATIONS`.
    """

    V: np.ndarray
    F: np.ndarray
    label: str
    defect: str
    tessellation: str


# --------------------------------------------------------------------------- per-mesh steps


def _area(V: np.ndarray, F: np.ndarray) -> float:
    T = V[F]
    return float(0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1).sum())


def _isotropic(V, F, length: float, iterations: int = 3):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F))
    ms.meshing_isotropic_explicit_remeshing(
        iterations=iterations, targetlen=pymeshlab.PureValue(length), checksurfdist=False,
        featuredeg=45.0,  # keeps a box's edges; 30 would also freeze a coarse tube's facets
    )
    ms.meshing_remove_unreferenced_vertices()
    m = ms.current_mesh()
    return (np.ascontiguousarray(m.vertex_matrix(), dtype=np.float64),
            np.ascontiguousarray(m.face_matrix(), dtype=np.int64))


def _quadric_safe(V, F, n: int):
    """Quadric edge collapse to ``n`` vertices that never changes the topology (PyMeshLab)."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F))
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=int(max(4, len(F) - 2 * (len(V) - n))), targetperc=0.0, qualitythr=0.3,
        preservetopology=True, optimalplacement=True, planarquadric=False, autoclean=True,
    )
    ms.meshing_remove_unreferenced_vertices()
    m = ms.current_mesh()
    return (np.ascontiguousarray(m.vertex_matrix(), dtype=np.float64),
            np.ascontiguousarray(m.face_matrix(), dtype=np.int64))


def _repair(V, F):
    """Remove the faces of non-manifold edges, split pinched vertices, close the small holes
    left (PyMeshLab)."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F))
    ms.meshing_repair_non_manifold_edges(method="Remove Faces")
    ms.meshing_repair_non_manifold_vertices()
    ms.meshing_remove_unreferenced_vertices()
    ms.meshing_close_holes(maxholesize=60, selfintersection=False)
    m = ms.current_mesh()
    return (np.ascontiguousarray(m.vertex_matrix(), dtype=np.float64),
            np.ascontiguousarray(m.face_matrix(), dtype=np.int64))


def _decimate(V, F, n: int):
    """Quadric edge collapse to about ``n`` vertices that keeps a closed manifold closed.

    fast-simplification first (aggressiveness 3 of 10: far fewer broken spots than the
    default 7 at the same speed); where it broke a closed manifold (collapses across thin
    walls), its few non-manifold spots are cut out and the holes closed; if that is not
    enough, PyMeshLab's topology-preserving collapse (slower) redoes it from the input.
    """
    import fast_simplification

    if len(V) <= n:
        return V, F
    Vd, Fd = fast_simplification.simplify(V, F, target_reduction=1.0 - n / len(V), agg=3)
    Vd, Fd = np.asarray(Vd, dtype=np.float64), np.asarray(Fd, dtype=np.int64)
    if topology_report(Fd).watertight:
        return Vd, Fd
    before = topology_report(F)
    if not before.watertight:
        return Vd, Fd
    Vd, Fd = _repair(Vd, Fd)
    after = topology_report(Fd)
    if after.watertight and after.n_components == before.n_components:
        return Vd, Fd
    return _quadric_safe(V, F, n)


def retessellate(V: np.ndarray, F: np.ndarray, n: int, style: str) -> tuple[np.ndarray, np.ndarray]:
    """Re-triangulate a surface with about ``n`` vertices.

    Parameters
    ----------
    V : (n0, 3) float64
    F : (m0, 3) int64
    n : int
        Target vertex count (met to within about 20 %).
    style : str
        One of :data:`TESSELLATIONS`; ``decimated`` needs an input with at least 1.5 n
        vertices and falls back to ``uniform`` otherwise.

    Returns
    -------
    V : (n', 3) float64
    F : (m', 3) int64

    Notes
    -----
    ``decimated``: quadric edge collapse straight to n vertices (see :func:`_decimate`: a
    closed manifold stays one). ``uniform``: dense inputs are first decimated to 3 n
    vertices; isotropic remeshing (PyMeshLab, 3 iterations, creases sharper than 45 degrees
    kept) targets the edge length of an equilateral mesh with n vertices,
    ``sqrt(2 area / (sqrt(3) n))``, is redone once with a corrected length if it misses by
    more than 20 %, and a rare pinched vertex it leaves is split.
    """
    check_choice("tessellation", style, TESSELLATIONS)
    if style == "decimated" and len(V) >= 1.5 * n:
        return _decimate(V, F, n)
    V, F = _decimate(V, F, 3 * n)
    length = math.sqrt(2 * _area(V, F) / (math.sqrt(3) * n))
    Vr, Fr = _isotropic(V, F, length)
    if abs(len(Vr) / n - 1) > 0.2:
        Vr, Fr = _isotropic(V, F, length * math.sqrt(len(Vr) / n))
    if not topology_report(Fr).watertight and topology_report(F).watertight:
        Vr, Fr = _repair(Vr, Fr)  # a rare pinched vertex or edge left by the remesher
    return Vr, Fr


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """(3, 3) rotation uniform on SO(3) (normalised Gaussian quaternion)."""
    w, x, y, z = (q := rng.normal(size=4)) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def random_similarity(V: np.ndarray, rng: np.random.Generator, *, scale=(0.5, 2.0),
                      shift: float = 0.5) -> np.ndarray:
    """Normalise to unit bounding-box diagonal, then rotate, scale and move at random.

    Parameters
    ----------
    V : (n, 3) float64
    rng : numpy.random.Generator
    scale : (float, float)
        Range of the log-uniform scale factor.
    shift : float
        Each translation coordinate is uniform in ``[-shift, shift]`` x the scale.

    Returns
    -------
    V : (n, 3) float64
    """
    lo, hi = V.min(axis=0), V.max(axis=0)
    U = (V - (lo + hi) / 2) / float(np.linalg.norm(hi - lo))
    s = math.exp(rng.uniform(math.log(scale[0]), math.log(scale[1])))
    return s * (U @ random_rotation(rng).T + rng.uniform(-shift, shift, 3))


def _finish(V, F, cls: str, defect: str, rng: np.random.Generator, vertices: int, parts=None) -> Shape:
    """Defects, re-tessellation and random similarity of one base surface."""
    n = int(round(vertices * rng.uniform(0.75, 1.3)))
    style = str(rng.choice(TESSELLATIONS, p=_STYLE_P))
    unfused = defect == "components" and parts is not None and len(parts) > 1
    if unfused:
        V, F = concatenate(parts)  # the rigid object's parts as separate, intersecting shells
    if defect == "stretch":
        V = stretch_axes(V, rng)
    if len(V) < 1.5 * n:
        style = "uniform"
    V, F = retessellate(V, F, n, style)
    if defect == "components" and not unfused:  # loose blobs beside a one-piece shape
        V, F = add_debris(V, F, rng, count=int(rng.integers(1, 4)))
    elif defect == "holes":
        V, F = punch_holes(V, F, rng, count=int(rng.integers(2, 5)))
    elif defect == "flipped":
        F = flip_patches(V, F, rng, fraction=rng.uniform(0.05, 0.2), patches=int(rng.integers(1, 4)))
    return Shape(random_similarity(V, rng), F, cls, defect, style)


def _class_seed(seed: int, cls: str, *more: int) -> list:
    return [int(seed), CLASSES.index(cls), *map(int, more)]


def generate_class(
    cls: str,
    count: int,
    *,
    seed: int = 0,
    vertices: int = 2000,
    defects: Sequence[str] | None = None,
    resolution: int = 112,
) -> list[Shape]:
    """Generate ``count`` meshes of one class.

    Parameters
    ----------
    cls : str
        One of :data:`CLASSES`.
    count : int
        Meshes to generate. Creatures come as instances of :data:`POSES_PER_INSTANCE`
        poses each (mesh ``k`` is pose ``k % 3`` of instance ``k // 3``).
    seed : int
        Seed; mesh ``k`` of class ``cls`` depends only on ``(seed, cls, k)`` (and the
        instance template on ``(seed, cls, k // 3)``).
    vertices : int
        Typical vertex count (each mesh draws its own in x [0.75, 1.3]).
    defects : sequence of str, optional
        Per mesh, ``"none"`` or a defect kind (default: no defects).
    resolution : int
        Voxels along the longest side for the creature templates and the fused rigid
        objects (thin rigid parts may use up to 1.25 x more).

    Returns
    -------
    list of Shape
    """
    check_choice("class", cls, CLASSES)
    defects = ["none"] * count if defects is None else list(defects)
    if len(defects) != count:
        raise InvalidOptionError(f"{cls}: {len(defects)} defect entries for {count} meshes")
    out = []
    template, template_of = None, -1
    for k in range(count):
        rng = np.random.default_rng(_class_seed(seed, cls, k, 1))
        if cls in CREATURE_CLASSES:
            inst = k // POSES_PER_INSTANCE
            if inst != template_of:
                inst_seed = int(np.random.SeedSequence(_class_seed(seed, cls, inst)).generate_state(1)[0])
                template = creature_template(cls, seed=inst_seed, resolution=resolution,
                                             target_vertices=int(min(50000, max(1500, 2.5 * vertices))))
                template_of = inst
            V = creature_pose(template, _class_seed(seed, cls, k, 2))
            out.append(_finish(V, template.F, cls, defects[k], rng, vertices))
        else:
            obj = build_rigid(cls, np.random.default_rng(_class_seed(seed, cls, k, 3)))
            V, F = fuse_parts(obj.parts, resolution=resolution, min_feature=obj.min_feature,
                              max_cells=int(1.25 * resolution))
            out.append(_finish(V, F, cls, defects[k], rng, vertices, parts=obj.parts))
    return out


def _assign_defects(n: int, fraction: float, seed: int) -> list[str]:
    """``round(fraction n)`` meshes (at least one if fraction > 0) get a defect, kinds cycled."""
    rng = np.random.default_rng([int(seed), 7919])
    k = min(n, max(1 if fraction > 0 else 0, int(round(fraction * n))))
    out = ["none"] * n
    first = int(rng.integers(len(DEFECTS)))
    for i, j in enumerate(sorted(rng.choice(n, size=k, replace=False).tolist())):
        out[j] = DEFECTS[(first + i) % len(DEFECTS)]
    return out


def write_collection(
    out_dir: str | os.PathLike,
    *,
    classes: Sequence[str] = CLASSES,
    per_class: int = 12,
    seed: int = 0,
    vertices: int = 2000,
    defect_fraction: float = 0.1,
    resolution: int = 112,
    progress=None,
) -> dict:
    """Write the mixed retrieval collection.

    Writes into ``out_dir``: ``<class>_<k>.off`` per mesh, ``labels.csv`` (``file,label``,
    what ``geoshape retrieval3d DIR`` reads), ``defects.csv`` (``file,defect,tessellation``),
    ``generator.json`` (the parameters) and ``README.txt`` (what is in it). Each file is
    written atomically.

    Parameters
    ----------
    out_dir : path
    classes : sequence of str
        Classes, from :data:`CLASSES` (default: all twenty).
    per_class : int
        Meshes per class, in [1, 300].
    seed : int
    vertices : int
        Typical vertex count per mesh, in [300, 50000].
    defect_fraction : float
        Share of meshes with a defect, in [0, 1] (chosen over the whole collection).
    resolution : int
        Voxel resolution of the creature templates and fused objects, in [48, 320].
    progress : callable, optional
        ``progress(done, total, class)`` after each class.

    Returns
    -------
    dict
        ``{"files", "labels", "defects", "tessellations", "seconds"}``, paths relative to
        ``out_dir``.

    Notes
    -----
    About 0.5 s per mesh at the defaults (a creature template is built once per instance).
    """
    from geoshape.io.atomic import write_text_atomic
    from geoshape.io.mesh_io import save_mesh

    classes = [check_choice("class", c, CLASSES) for c in classes]
    if not classes:
        raise InvalidOptionError(f"give at least one class from {', '.join(CLASSES)}")
    if len(set(classes)) != len(classes):
        raise InvalidOptionError(f"classes repeat: {classes}")
    per_class = check_whole("per_class", per_class, 1, 300)
    vertices = check_whole("vertices", vertices, 300, 50000)
    resolution = check_whole("resolution", resolution, 48, 320)
    defect_fraction = float(defect_fraction)
    if not (0.0 <= defect_fraction <= 1.0):
        raise InvalidOptionError(f"defect_fraction must lie in [0, 1], got {defect_fraction!r}")
    t0 = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    defects = _assign_defects(len(classes) * per_class, defect_fraction, seed)
    files, labels, kinds, styles = [], [], [], []
    for ci, cls in enumerate(classes):
        shapes = generate_class(cls, per_class, seed=seed, vertices=vertices, resolution=resolution,
                                defects=defects[ci * per_class:(ci + 1) * per_class])
        for k, sh in enumerate(shapes):
            name = f"{cls}_{k:02d}.off"
            save_mesh(out / name, sh.V, sh.F)
            files.append(name)
            labels.append(cls)
            kinds.append(sh.defect)
            styles.append(sh.tessellation)
        if progress is not None:
            progress(ci + 1, len(classes), cls)
    write_text_atomic(out / "labels.csv",
                      "file,label\n" + "".join(f"{f},{c}\n" for f, c in zip(files, labels, strict=True)))
    write_text_atomic(out / "defects.csv", "file,defect,tessellation\n" + "".join(
        f"{f},{d},{s}\n" for f, d, s in zip(files, kinds, styles, strict=True)))
    params = {
        "generator": "geoshape_datasets_gen.mixed3d.write_collection",
        "classes": classes, "per_class": per_class, "seed": int(seed), "vertices": vertices,
        "defect_fraction": defect_fraction, "resolution": resolution,
        "articulated": [c for c in classes if c in CREATURE_CLASSES],
        "rigid": [c for c in classes if c in RIGID_CLASSES],
    }
    write_text_atomic(out / "generator.json", json.dumps(params, indent=2) + "\n")
    write_text_atomic(out / "README.txt", _readme(files, classes, per_class, seed, vertices, kinds))
    return {"files": files, "labels": labels, "defects": kinds, "tessellations": styles,
            "seconds": time.perf_counter() - t0}


def _readme(files, classes, per_class, seed, vertices, kinds) -> str:
    arti = [c for c in classes if c in CREATURE_CLASSES]
    rigid = [c for c in classes if c in RIGID_CLASSES]
    counts = {d: kinds.count(d) for d in DEFECTS if kinds.count(d)}
    defects = ", ".join(f"{v} {k}" for k, v in counts.items()) or "none"
    return (
        f"mixed3d: {len(files)} meshes (.off), {len(classes)} classes x {per_class}, seed {seed}, "
        f"about {vertices} vertices each (x 0.75-1.3), random rotation, scale and translation.\n"
        f"articulated ({len(arti)}, instances x {POSES_PER_INSTANCE} poses): {', '.join(arti) or '-'}\n"
        f"rigid ({len(rigid)}, fused watertight parts): {', '.join(rigid) or '-'}\n"
        f"defects ({sum(counts.values())} meshes, defects.csv): {defects}\n"
        "labels.csv: file,label (geoshape retrieval3d DIR); generator.json: parameters; "
        "made by geoshape gen mixed3d.\n"
    )
