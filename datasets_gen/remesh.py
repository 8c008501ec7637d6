"""Independent remeshing with ground truth to the original mesh, and remeshed pair sets.

Benchmark meshes that share a triangulation (SCAPE's common vertex ids, TOSCA's common
5k remeshing per class) let a method profit from connectivity it will not see on new data.
:func:`remesh` gives a mesh a new, seed-dependent triangulation of the same surface:

1. the mesh is rotated by a random rotation about its centroid, its vertex and face order
   are shuffled, and every vertex slides a little along the surface (a random tangential
   step of 0.2 x its shortest incident edge, put back on the surface by a closest-point
   query) — so the remesher starts from a different, equivalent input for each seed;
2. isotropic explicit remeshing (PyMeshLab: edge split, collapse, flip, tangential
   smoothing, reprojection) at the edge length of an equilateral mesh with slightly more
   than ``n`` vertices, ``sqrt(2 area / (sqrt(3) n))``, corrected when it misses;
3. quadric edge collapse down to exactly ``n`` vertices (when the remesher overshot);
4. the rotation is undone, every new vertex is put on the closest point of the
   *original* surface, and the new vertex ids are shuffled.

The ground truth ``to_original[i]`` of new vertex ``i`` is the original vertex nearest to
that closest point among the three corners of the original face containing it, so a new
vertex is never matched across a gap to an unrelated part, and lies within one original
edge length of its ground-truth vertex. :func:`nearest_surface_vertex` is the same rule
for any points (used for the map from original vertices to a remeshed mesh).

:func:`write_remeshed_set` applies this to a benchmark folder (``pairs.csv`` with identity
or ``.vts`` landmark ground truth): each mesh of the chosen pairs is remeshed once, with
its own seed, and the ground truth of each pair is composed through the originals
(docs/datasets.md states exactly what it means).
"""

from __future__ import annotations

import json
import math
import os
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geoshape._options import check_whole
from geoshape.errors import DatasetError, InvalidOptionError
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

__all__ = ["Remeshed", "remesh", "nearest_surface_vertex", "select_pairs", "ComposedTruth",
           "compose_ground_truth",
           "write_remeshed_set", "MIN_VERTICES", "MAX_VERTICES"]

MIN_VERTICES = 50
MAX_VERTICES = 1_000_000

#: isotropic remeshing with the equilateral edge length gives about 15 % more vertices than
#: asked (PyMeshLab keeps edges between 4/5 and 4/3 of the target); start a little longer
_LENGTH_BIAS = 1.08
#: overshoot aimed at before the final quadric decimation to the exact count
_OVERSHOOT = 1.04


class Remeshed(NamedTuple):
    """An independently remeshed copy of a mesh.

    Attributes
    ----------
    V : (k, 3) float64
        New vertices, each on the original surface (closest point).
    F : (l, 3) int64
        New triangles (a different triangulation for every seed).
    to_original : (k,) int64
        For each new vertex, the 0-based id of its ground-truth original vertex: the corner
        nearest to it of the original face its position lies on.
    distance : (k,) float64
        Euclidean distance from each new vertex to its ground-truth original vertex.
    mesh : object
        The same mesh in the caller's kind (:func:`geoshape.io.interop.mesh_input`).
    """

    V: np.ndarray
    F: np.ndarray
    to_original: np.ndarray
    distance: np.ndarray
    mesh: object = None


def _area(V: np.ndarray, F: np.ndarray) -> float:
    T = V[F]
    return float(0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1).sum())


def _closest_points(P: np.ndarray, V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(face id, closest point) on the surface (V, F) of every point of P (libigl AABB tree)."""
    import igl

    _, face, C = igl.point_mesh_squared_distance(
        np.ascontiguousarray(P, dtype=np.float64), np.ascontiguousarray(V, dtype=np.float64),
        np.ascontiguousarray(F, dtype=np.int64),
    )
    return np.asarray(face, dtype=np.int64), np.asarray(C, dtype=np.float64)


def _nearest_corner(C: np.ndarray, V: np.ndarray, F: np.ndarray, face: np.ndarray) -> np.ndarray:
    corners = F[face]  # (k, 3)
    d = np.linalg.norm(V[corners] - C[:, None, :], axis=2)
    return corners[np.arange(len(C)), d.argmin(axis=1)]


def nearest_surface_vertex(P, V, F) -> np.ndarray:
    """For each point, the vertex of (V, F) nearest to its closest surface point among the
    corners of the face holding that point.

    Parameters
    ----------
    P : (k, 3) array_like of float
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int

    Returns
    -------
    ids : (k,) int64
        0-based vertex ids of (V, F).

    Notes
    -----
    Vectorised through libigl's AABB tree: O((k + m) log m).

    Examples
    --------
    >>> import trimesh
    >>> s = trimesh.creation.icosphere(2)
    >>> ids = nearest_surface_vertex(s.vertices * 1.01, s.vertices, s.faces)
    >>> bool((ids == np.arange(len(s.vertices))).all())
    True
    """
    V, F = check_mesh(V, F, name="mesh")
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    if len(P) == 0:
        return np.zeros(0, dtype=np.int64)
    face, C = _closest_points(P, V, F)
    return _nearest_corner(C, V, F, face)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    w, x, y, z = (q := rng.normal(size=4)) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _slide_on_surface(V: np.ndarray, F: np.ndarray, rng: np.random.Generator, amount: float) -> np.ndarray:
    """Move each vertex by a random tangential step of ``amount`` x its shortest incident
    edge, then back onto the surface (closest point)."""
    n = len(V)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    length = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    shortest = np.full(n, np.inf)
    np.minimum.at(shortest, E[:, 0], length)
    np.minimum.at(shortest, E[:, 1], length)
    shortest[~np.isfinite(shortest)] = 0.0
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])  # area-weighted normals
    normal = np.zeros_like(V)
    for k in range(3):
        np.add.at(normal, F[:, k], fn)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    step = rng.normal(size=(n, 3))
    step -= (step * normal).sum(axis=1, keepdims=True) * normal
    step /= np.maximum(np.linalg.norm(step, axis=1, keepdims=True), 1e-300)
    moved = V + step * (amount * shortest * rng.uniform(0.0, 1.0, n))[:, None]
    return _closest_points(moved, V, F)[1]


def _mesh_arrays(ms) -> tuple[np.ndarray, np.ndarray]:
    m = ms.current_mesh()
    return (np.ascontiguousarray(m.vertex_matrix(), dtype=np.float64),
            np.ascontiguousarray(m.face_matrix(), dtype=np.int64))


def _isotropic(V: np.ndarray, F: np.ndarray, length: float, iterations: int):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F))
    # every parameter given: PyMeshLab re-uses unpassed values from the previous call
    ms.meshing_isotropic_explicit_remeshing(
        iterations=int(iterations),
        adaptive=False,
        selectedonly=False,
        targetlen=pymeshlab.PureValue(float(length)),
        featuredeg=30.0,
        checksurfdist=False,
        maxsurfdist=pymeshlab.PureValue(float(length)),
        splitflag=True,
        collapseflag=True,
        swapflag=True,
        smoothflag=True,
        reprojectflag=True,
    )
    ms.meshing_remove_unreferenced_vertices()
    return _mesh_arrays(ms)


def _decimate_to(V: np.ndarray, F: np.ndarray, n: int, passes: int = 4):
    """Quadric edge collapse (optimal placement, topology kept) down to ``n`` vertices."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F))
    from geoshape_datasets_gen.decimate import quadric_collapse_pass

    for _ in range(passes):
        nv = ms.current_mesh().vertex_number()
        if nv <= n:
            break
        quadric_collapse_pass(ms, n, preserve_boundary=True)
        if ms.current_mesh().vertex_number() >= nv:
            break
    ms.meshing_remove_unreferenced_vertices()
    return _mesh_arrays(ms)


@mesh_input(returns_mesh=True)
def remesh(V, F, n_vertices: int, seed: int = 0, *, iterations: int = 6) -> Remeshed:
    """An independently remeshed copy of a mesh with about ``n_vertices`` vertices, with the
    ground truth to the original vertices.

    Parameters
    ----------
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int
    n_vertices : int
        Wanted vertex count, in [50, 1e6]. Met exactly when the remesher reaches it
        (the usual case); a coarse input whose features stop the collapse may end above it,
        and a surface too small for the count may end below it.
    seed : int
        Seed of the rotation, shuffles and sliding: different seeds give different
        triangulations, the same seed gives bit-identical output.
    iterations : int
        Rounds of the isotropic remesher (default 6).

    Returns
    -------
    Remeshed
        ``(V, F, to_original, distance, mesh)``.

    Notes
    -----
    Inputs with more than 4 ``n_vertices`` vertices are first simplified with
    fast-simplification (for speed; the result is still placed on, and mapped to, the
    original surface). Time O(m log m) per remeshing round; one to three rounds.

    Examples
    --------
    >>> import trimesh
    >>> s = trimesh.creation.icosphere(4)
    >>> r = remesh(s.vertices, s.faces, 1000, seed=1)
    >>> len(r.V), bool(np.allclose(np.linalg.norm(r.V, axis=1), 1, atol=0.01))
    (1000, True)
    """
    V, F = check_mesh(V, F, name="mesh to remesh")
    n_want = check_whole("vertex count", n_vertices, MIN_VERTICES, MAX_VERTICES)
    rng = np.random.default_rng(check_whole("seed", seed, 0, 2**32 - 1))
    centre = V.mean(axis=0)
    R = _random_rotation(rng)
    perm = rng.permutation(len(V))
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(V))
    Vw = (V[perm] - centre) @ R.T
    Fw = inv[F][rng.permutation(len(F))]
    Fw = np.take_along_axis(Fw, (np.arange(3)[None, :] + rng.integers(0, 3, len(Fw))[:, None]) % 3, axis=1)
    Vw = _slide_on_surface(Vw, Fw, rng, 0.2)
    if len(Vw) > 4 * n_want:
        import fast_simplification

        Vs, Fs = fast_simplification.simplify(Vw, Fw, target_reduction=1.0 - 4 * n_want / len(Vw))
        Vw, Fw = np.asarray(Vs, dtype=np.float64), np.asarray(Fs, dtype=np.int64)
    length = _LENGTH_BIAS * math.sqrt(2.0 * _area(Vw, Fw) / (math.sqrt(3.0) * n_want))
    best = None
    for _ in range(3):
        Vr, Fr = _isotropic(Vw, Fw, length, iterations)
        # prefer a result at or above the count (decimated down exactly), then the closest
        key = (len(Vr) < n_want, abs(len(Vr) - n_want))
        if best is None or key < best[0]:
            best = (key, Vr, Fr)
        if n_want <= len(Vr) <= 1.12 * n_want:
            break
        length *= math.sqrt(len(Vr) / (_OVERSHOOT * n_want))
    _, Vr, Fr = best
    if len(Vr) > n_want:
        Vr, Fr = _decimate_to(Vr, Fr, n_want)
    Vr = Vr @ R + centre
    face, C = _closest_points(Vr, V, F)
    to_original = _nearest_corner(C, V, F, face)
    order = rng.permutation(len(C))
    new_id = np.empty_like(order)
    new_id[order] = np.arange(len(order))
    Vn, ids = C[order], to_original[order]
    Fn = new_id[Fr][rng.permutation(len(Fr))]
    dist = np.linalg.norm(Vn - V[ids], axis=1)
    return Remeshed(Vn, np.ascontiguousarray(Fn, dtype=np.int64), ids, dist)


# --------------------------------------------------------------------------- remeshed pair sets

_MESH_SUFFIXES = (".off", ".off.gz", ".ply", ".ply.gz", ".obj", ".obj.gz")


def _resolve_dataset(dataset) -> Path:
    """A benchmark folder: an existing directory, else a set name under the data root."""
    from geoshape.io.datasets import dataset_dir

    path = Path(dataset)
    if path.is_dir():
        return path
    if os.sep in str(dataset) or "/" in str(dataset):
        raise DatasetError(f"{dataset}: no such dataset folder")
    return dataset_dir(str(dataset))


def _default_pairs_file(folder: Path) -> str:
    return "pairs_subset.csv" if (folder / "pairs_subset.csv").is_file() else "pairs.csv"


def _labels(folder: Path) -> dict[Path, str] | None:
    from geoshape.io.datasets import read_labels

    if not (folder / "labels.csv").is_file():
        return None
    return {item.path.resolve(): item.label for item in read_labels(folder)}


def select_pairs(folder, listed: Sequence, n_pairs: int | None, seed: int = 0) -> list:
    """The pairs of a remeshed set, chosen from the dataset's listed pairs.

    Parameters
    ----------
    folder : path
        The dataset folder (for ``labels.csv`` and the mesh files of extra pairs).
    listed : sequence of :class:`geoshape.io.datasets.Pair`
        The rows of the dataset's pairs file, in order.
    n_pairs : int or None
        ``None``: all listed pairs. Up to their number: evenly spaced rows (first and last
        included), so every part of a file grouped by class is kept. More (identity ground
        truth only): all listed pairs, then seeded random extra pairs of distinct meshes from
        the folders of the listed meshes, within one label when the set has ``labels.csv``.

    Returns
    -------
    list of Pair

    Raises
    ------
    InvalidOptionError
        More pairs than the file lists for a landmark set, or than the meshes allow.
    """
    from geoshape.io.datasets import Pair

    listed = list(listed)
    if n_pairs is None:
        return listed
    n_pairs = int(n_pairs)
    if n_pairs < 1:
        raise InvalidOptionError(f"the number of pairs must be at least 1, got {n_pairs}")
    if n_pairs <= len(listed):
        idx = np.round(np.linspace(0, len(listed) - 1, n_pairs)).astype(int) if n_pairs > 1 else [0]
        return [listed[i] for i in idx]
    if not all(p.identity for p in listed):
        raise InvalidOptionError(
            f"the pairs file lists {len(listed)} pairs with landmark ground truth; ask for at most "
            f"{len(listed)} pairs or choose a pairs file with more rows"
        )
    folders = sorted({p.source.parent for p in listed} | {p.target.parent for p in listed})
    meshes = sorted({m for d in folders for m in d.iterdir()
                     if m.is_file() and m.name.lower().endswith(_MESH_SUFFIXES)})
    labels = _labels(Path(folder))
    have = {frozenset((p.source.resolve(), p.target.resolve())) for p in listed}

    def same_label(a: Path, b: Path) -> bool:
        if labels is None:
            return True
        la = labels.get(a.resolve())
        return la is not None and la == labels.get(b.resolve())

    candidates = [(a, b) for i, a in enumerate(meshes) for b in meshes[i + 1:]
                  if frozenset((a.resolve(), b.resolve())) not in have and same_label(a, b)]
    extra = n_pairs - len(listed)
    if extra > len(candidates):
        raise InvalidOptionError(
            f"asked for {n_pairs} pairs but the set allows {len(listed) + len(candidates)}"
        )
    rng = np.random.default_rng([int(seed), 0x9A1])
    chosen = rng.choice(len(candidates), extra, replace=False)
    flip = rng.integers(0, 2, extra)
    out = list(listed)
    for c, f in zip(chosen.tolist(), flip.tolist(), strict=True):
        a, b = candidates[c]
        out.append(Pair(b, a) if f else Pair(a, b))
    return out


class ComposedTruth(NamedTuple):
    """Ground truth of one remeshed pair (see :func:`compose_ground_truth`)."""

    source: np.ndarray
    target: np.ndarray
    target_symmetric: np.ndarray | None
    target_original: np.ndarray


def compose_ground_truth(pair, to_source_original: np.ndarray, target_from_original: np.ndarray,
                         n_source_original: int, n_target_original: int):
    """Ground truth between two remeshed meshes, composed through the originals.

    For each remeshed source vertex ``i``: ``s = to_source_original[i]`` (its original
    vertex), ``t`` = the original target vertex the dataset matches with ``s`` (``t = s``
    for identity ground truth; for landmarks the first landmark ``k`` with
    ``source_landmarks[k] == s`` gives ``t = target_landmarks[k]``, and remeshed vertices
    whose original vertex is no landmark get no ground truth), then
    ``target_from_original[t]``, the remeshed target vertex of ``t``.

    Returns
    -------
    ComposedTruth
        ``source``, ``target``: (k,) int64 0-based ids on the remeshed source and target
        (landmark ``j`` of one matches landmark ``j`` of the other); ``target_symmetric``:
        the mirrored target ids from the dataset's symmetric landmarks, or None;
        ``target_original``: the original target vertex ``t`` of each landmark.
    """
    to_src = np.asarray(to_source_original, dtype=np.int64)
    from_tgt = np.asarray(target_from_original, dtype=np.int64)
    if pair.identity:
        if n_source_original != n_target_original:
            raise DatasetError(
                f"{pair.source.name} -> {pair.target.name}: identity ground truth needs equal vertex "
                f"counts, got {n_source_original} and {n_target_original}"
            )
        return ComposedTruth(np.arange(len(to_src), dtype=np.int64), from_tgt[to_src], None, to_src.copy())
    ls, lt, lts = pair.source_landmarks, pair.target_landmarks, pair.target_symmetric_landmarks
    for name, ids, n in (("source", ls, n_source_original), ("target", lt, n_target_original),
                         ("symmetric target", lts, n_target_original)):
        if ids is not None and (ids.max() >= n):
            raise DatasetError(f"{pair.source.name} -> {pair.target.name}: {name} landmark id "
                               f"{int(ids.max()) + 1} exceeds the mesh's {n} vertices")
    first = np.full(n_source_original, -1, dtype=np.int64)
    uniq, at = np.unique(ls, return_index=True)
    first[uniq] = at
    k = first[to_src]
    keep = np.flatnonzero(k >= 0)
    k = k[keep]
    sym = None if lts is None else from_tgt[lts[k]]
    return ComposedTruth(keep.astype(np.int64), from_tgt[lt[k]], sym, lt[k])


def _vts(ids: np.ndarray) -> str:
    return "".join(f"{i}\n" for i in (np.asarray(ids, dtype=np.int64) + 1).tolist())


def _mesh_seed(seed: int, name: str) -> int:
    return int(np.random.SeedSequence([int(seed), zlib.crc32(name.encode("utf-8"))]).generate_state(1)[0])


GROUND_TRUTH_NOTE = (
    "landmark j of the source file (1-based vertex id of the remeshed source) corresponds to landmark "
    "j of the target file (remeshed target). Composition: remeshed source vertex -> original source "
    "vertex (nearest corner of the original face holding its closest surface point) -> the dataset's "
    "ground truth between the originals (identity, or .vts landmarks: first landmark whose source id "
    "matches; vertices whose original is no landmark are left out) -> original target vertex -> "
    "remeshed target vertex (nearest corner of the remeshed face holding the closest point of the "
    "original vertex). Each snap moves by at most one edge length; the per-pair snap distances / "
    "sqrt(area) are in generator.json."
)


def write_remeshed_set(
    dataset,
    out_dir: str | os.PathLike,
    *,
    n_pairs: int | None = None,
    pairs_file: str | None = None,
    n_vertices: int = 5000,
    seed: int = 0,
    iterations: int = 6,
    progress=None,
) -> dict:
    """Write a remeshed copy of a correspondence set: both meshes of every pair remeshed
    independently, with composed ground truth in the ``pairs.csv`` / ``.vts`` layout.

    Written into ``out_dir`` (each file atomically):

    - ``meshes/<stem>.off``: each mesh of the chosen pairs, remeshed once by :func:`remesh`
      with its own seed (from ``seed`` and the mesh's path in the dataset);
    - ``maps/<stem>.to_original.vts``: line ``i`` = 1-based original vertex of remeshed
      vertex ``i``; ``maps/<stem>.from_original.vts``: line ``v`` = 1-based remeshed vertex of
      original vertex ``v`` (:func:`nearest_surface_vertex`);
    - ``gt/<source>__<target>.src.vts`` / ``.tgt.vts`` (/ ``.tgt_sym.vts``): the composed
      ground truth (:func:`compose_ground_truth`), and ``pairs.csv`` naming them;
    - for SCAPE-like sets with ``Corrs/1.pid`` feature points and ``Corrs/1.sym.info``:
      ``pairs_features.csv`` with ``gt/<pair>.feat_*.vts`` — the feature points snapped to
      each remeshed mesh (``from_original``) with their mirrored partners, for
      symmetry-aware scores;
    - ``labels.csv`` (when the dataset has one) and ``generator.json`` (parameters, meshes,
      per-pair snap distances, what the ground truth means).

    Parameters
    ----------
    dataset : str or path
        A dataset folder, or a set name under the data root (``scape``, ``tosca_r5k``…).
    out_dir : path
        Output folder (never inside the data folder).
    n_pairs : int, optional
        Number of pairs (:func:`select_pairs`); default all rows of the pairs file.
    pairs_file : str, optional
        Default ``pairs_subset.csv`` when the dataset has one, else ``pairs.csv``.
    n_vertices, seed, iterations
        See :func:`remesh`.
    progress : callable, optional
        Called as ``progress(done, total, name)`` after each remeshed mesh.

    Returns
    -------
    dict
        ``{"meshes": [...], "pairs": [(source, target, n_landmarks), ...], "folder": ...}``.
    """
    from geoshape.io.atomic import write_text_atomic
    from geoshape.io.datasets import mesh_stem, read_pairs, scape_feature_points
    from geoshape.io.mesh_io import load_mesh, save_mesh

    n_vertices = check_whole("vertex count", n_vertices, MIN_VERTICES, MAX_VERTICES)
    seed = check_whole("seed", seed, 0, 2**32 - 1)
    folder = _resolve_dataset(dataset)
    out = Path(out_dir)
    if out.resolve() == folder.resolve() or folder.resolve() in out.resolve().parents:
        raise InvalidOptionError(f"{out}: write the remeshed set outside the dataset folder {folder}")
    pairs_file = pairs_file or _default_pairs_file(folder)
    pairs = select_pairs(folder, read_pairs(folder, pairs_file), n_pairs, seed)
    originals = list(dict.fromkeys([p for pair in pairs for p in (pair.source, pair.target)]))
    stems = [mesh_stem(p) for p in originals]
    if len(set(stems)) != len(stems):
        raise DatasetError("two meshes of the chosen pairs share a file name; cannot name the outputs")
    info: dict = {}
    meshes_json = []
    for done, (path, stem) in enumerate(zip(originals, stems, strict=True), start=1):
        rel = os.path.relpath(path, folder)
        V, F = load_mesh(path)
        s = _mesh_seed(seed, rel.replace(os.sep, "/"))
        r = remesh(V, F, n_vertices, s, iterations=iterations)
        from_orig = nearest_surface_vertex(V, r.V, r.F)
        save_mesh(out / "meshes" / f"{stem}.off", r.V, r.F)
        write_text_atomic(out / "maps" / f"{stem}.to_original.vts", _vts(r.to_original))
        write_text_atomic(out / "maps" / f"{stem}.from_original.vts", _vts(from_orig))
        info[path] = dict(stem=stem, V=V, Vr=r.V, to=r.to_original, frm=from_orig,
                          scale=math.sqrt(_area(V, F)))
        meshes_json.append({"file": f"meshes/{stem}.off", "original": rel.replace(os.sep, "/"),
                            "seed": s, "vertices": len(r.V), "faces": len(r.F),
                            "original_vertices": len(V)})
        if progress is not None:
            progress(done, len(originals), stem)
    features = scape_feature_points(folder) if all(p.identity for p in pairs) else None
    rows, feat_rows, pairs_json, result_pairs = [], [], [], []
    for pair in pairs:
        a, b = info[pair.source], info[pair.target]
        src, tgt, sym, t_orig = compose_ground_truth(pair, a["to"], b["frm"], len(a["V"]), len(b["V"]))
        if len(src) == 0:
            raise DatasetError(f"{pair.source.name} -> {pair.target.name}: no remeshed vertex has "
                               "ground truth")
        name = f"{a['stem']}__{b['stem']}"
        write_text_atomic(out / "gt" / f"{name}.src.vts", _vts(src))
        write_text_atomic(out / "gt" / f"{name}.tgt.vts", _vts(tgt))
        sym_file = ""
        if sym is not None:
            sym_file = f"gt/{name}.tgt_sym.vts"
            write_text_atomic(out / sym_file, _vts(sym))
        rows.append(f"meshes/{a['stem']}.off,meshes/{b['stem']}.off,gt/{name}.src.vts,gt/{name}.tgt.vts,"
                    f"{sym_file}\n")
        snap_src = np.linalg.norm(a["Vr"][src] - a["V"][a["to"][src]], axis=1) / a["scale"]
        snap_tgt = np.linalg.norm(b["V"][t_orig] - b["Vr"][tgt], axis=1) / b["scale"]
        pairs_json.append({
            "source": f"meshes/{a['stem']}.off", "target": f"meshes/{b['stem']}.off",
            "original_source": meshes_json[originals.index(pair.source)]["original"],
            "original_target": meshes_json[originals.index(pair.target)]["original"],
            "landmarks": len(src),
            "source_snap_mean": float(snap_src.mean()), "source_snap_max": float(snap_src.max()),
            "target_snap_mean": float(snap_tgt.mean()), "target_snap_max": float(snap_tgt.max()),
        })
        result_pairs.append((f"meshes/{a['stem']}.off", f"meshes/{b['stem']}.off", len(src)))
        if features is not None:
            ids, mirrored = features
            write_text_atomic(out / "gt" / f"{name}.feat_src.vts", _vts(a["frm"][ids]))
            write_text_atomic(out / "gt" / f"{name}.feat_tgt.vts", _vts(b["frm"][ids]))
            write_text_atomic(out / "gt" / f"{name}.feat_tgt_sym.vts", _vts(b["frm"][mirrored]))
            feat_rows.append(f"meshes/{a['stem']}.off,meshes/{b['stem']}.off,gt/{name}.feat_src.vts,"
                             f"gt/{name}.feat_tgt.vts,gt/{name}.feat_tgt_sym.vts\n")
    header = "source,target,source_landmarks,target_landmarks,target_symmetric_landmarks\n"
    write_text_atomic(out / "pairs.csv", header + "".join(rows))
    if feat_rows:
        write_text_atomic(out / "pairs_features.csv", header + "".join(feat_rows))
    labels = _labels(folder)
    if labels is not None:
        write_text_atomic(out / "labels.csv", "file,label\n" + "".join(
            f"meshes/{info[p]['stem']}.off,{labels.get(p.resolve(), '')}\n" for p in originals))
    params = {
        "generator": "geoshape_datasets_gen.remesh.write_remeshed_set",
        "dataset": folder.name, "pairs_file": pairs_file, "pairs": len(pairs),
        "vertices": n_vertices, "seed": seed, "iterations": int(iterations),
        "ground_truth": GROUND_TRUTH_NOTE,
        "features": ("pairs_features.csv: the dataset's feature points snapped to each remeshed mesh "
                     "(original vertex -> remeshed vertex on both sides), with mirrored partners")
        if feat_rows else None,
        "meshes": meshes_json, "pair_ground_truth": pairs_json,
    }
    write_text_atomic(out / "generator.json", json.dumps(params, indent=2) + "\n")
    return {"meshes": [m["file"] for m in meshes_json], "pairs": result_pairs, "folder": str(folder),
            "features": bool(feat_rows)}
