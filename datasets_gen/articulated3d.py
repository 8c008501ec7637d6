"""Procedural articulated 3D figures with identity ground truth between poses.

A figure class (biped, quadruped, hand, snake, octopus) is a skeleton: a tree of joints,
each with a rest position, a tube radius and up to two bending axes with angle limits.
One *instance* of a class (limb lengths and thicknesses varied by a seed) is turned into
one watertight, manifold, single-component triangle mesh:

1. an implicit field, the smooth union of tapered capsules around the bones, is sampled
   on a voxel grid (only near each bone);
2. its zero level set is polygonised with marching cubes and the largest component kept;
3. the mesh is cleaned and decimated with quadric edge collapse (topology preserving)
   to a chosen vertex count, then checked for watertightness and manifoldness.

Poses are produced by linear-blend skinning of that one template: joint rotations are
composed down the tree and every vertex follows a smooth blend of the transforms of the
bones nearest to it. Every pose of an instance therefore has the same faces and vertex
ids, and vertex ``i`` of one pose corresponds to vertex ``i`` of any other.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geoshape._options import check_choice, check_whole
from geoshape.errors import GeoshapeError, InvalidOptionError
from geoshape.geometry.mesh import largest_component, signed_volume

__all__ = [
    "CLASSES",
    "Skeleton",
    "Template",
    "Figure",
    "make_skeleton",
    "limb_groups",
    "build_template",
    "random_pose",
    "pose_vertices",
    "generate_figure",
    "write_collection",
]

CLASSES = ("biped", "quadruped", "hand", "snake", "octopus")

_DEG = math.pi / 180.0


# --------------------------------------------------------------------------- skeletons


@dataclass(frozen=True)
class Skeleton:
    """A tree of joints in its rest pose.

    Attributes
    ----------
    positions : (J, 3) float64
        Rest positions of the joints.
    parents : (J,) int64
        Parent of each joint, ``-1`` for the root (joint 0). Parents precede children.
    radii : (J,) float64
        Radius of the body tube at each joint (bones taper linearly between joints).
    axes : (J, 2, 3) float64
        Up to two unit bending axes per joint, in rest coordinates.
    limits : (J, 2) float64
        Largest bending angle (radians) about each axis; 0 locks that axis.
    name : str
        Class name.
    """

    positions: np.ndarray
    parents: np.ndarray
    radii: np.ndarray
    axes: np.ndarray
    limits: np.ndarray
    name: str

    @property
    def bones(self) -> np.ndarray:
        """(B, 2) int64 ``(parent joint, child joint)`` of every bone, in joint order."""
        child = np.flatnonzero(self.parents >= 0)
        return np.column_stack([self.parents[child], child])


class _Builder:
    """Collects joints for a skeleton: offsets from the parent, grouped into limbs."""

    def __init__(self):
        self.offsets, self.parents, self.radii, self.axes, self.limits, self.limbs = (
            [], [], [], [], [], []
        )

    def add(self, parent, offset, radius, limb, axes=(), limits=()):
        ax = np.zeros((2, 3))
        lim = np.zeros(2)
        for k, (a, lo) in enumerate(zip(axes, limits, strict=True)):
            a = np.asarray(a, dtype=np.float64)
            ax[k] = a / np.linalg.norm(a)
            lim[k] = lo * _DEG
        self.offsets.append(np.asarray(offset, dtype=np.float64))
        self.parents.append(parent)
        self.radii.append(float(radius))
        self.axes.append(ax)
        self.limits.append(lim)
        self.limbs.append(limb)
        return len(self.parents) - 1

    def chain(self, parent, offsets, radii, limb, axes=(), limits=()):
        j = parent
        for off, r in zip(offsets, radii, strict=True):
            j = self.add(j, off, r, limb, axes, limits)
        return j

    def build(self, name: str, rng: np.random.Generator | None, variation: float) -> Skeleton:
        offsets = np.array(self.offsets)
        radii = np.array(self.radii)
        if rng is not None and variation > 0:
            groups = sorted(set(self.limbs))
            length = dict(zip(groups, rng.uniform(1 - variation, 1 + variation, len(groups)),
                              strict=True))
            thick = dict(zip(groups, rng.uniform(1 - variation / 2, 1 + variation / 2, len(groups)),
                             strict=True))
            offsets = offsets * np.array([length[g] for g in self.limbs])[:, None]
            radii = radii * np.array([thick[g] for g in self.limbs])
        parents = np.array(self.parents, dtype=np.int64)
        pos = np.zeros_like(offsets)
        for j, p in enumerate(parents):
            pos[j] = offsets[j] if p < 0 else pos[p] + offsets[j]
        return Skeleton(pos, parents, radii, np.array(self.axes), np.array(self.limits), name)


X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _biped(b: _Builder) -> None:
    # standing along +y, facing +z, arms out sideways (T-pose)
    pelvis = b.add(-1, (0, 1.0, 0), 0.14, "torso")
    spine = b.add(pelvis, (0, 0.22, 0), 0.14, "torso", (X, Z), (20, 15))
    chest = b.add(spine, (0, 0.24, 0), 0.16, "torso", (X, Y), (20, 25))
    neck = b.add(chest, (0, 0.2, 0), 0.065, "neck", (X, Y), (25, 35))
    head = b.add(neck, (0, 0.14, 0.01), 0.115, "head")
    b.add(head, (0, 0.1, 0), 0.095, "head")
    for s in (1, -1):
        sh = b.add(chest, (0.2 * s, 0.04, 0), 0.065, "shoulder")
        el = b.add(sh, (0.28 * s, 0, 0), 0.055, "arm", (Z, Y), (70, 40))
        wr = b.add(el, (0.26 * s, 0, 0), 0.047, "arm", (Y, Z), (80, 15))
        b.add(wr, (0.1 * s, 0, 0), 0.05, "hand", (Z, Y), (35, 20))
        hip = b.add(pelvis, (0.1 * s, -0.06, 0), 0.085, "hip")
        kn = b.add(hip, (0.02 * s, -0.43, 0), 0.065, "leg", (X, Z), (50, 20))
        an = b.add(kn, (0.01 * s, -0.42, 0), 0.05, "leg", (X,), (70,))
        b.add(an, (0, -0.04, 0.13), 0.047, "foot", (X,), (25,))


def _quadruped(b: _Builder) -> None:
    # body along +x, legs down -y
    hips = b.add(-1, (-0.45, 0.8, 0), 0.16, "body")
    mid = b.add(hips, (0.45, 0.02, 0), 0.17, "body", (Y, Z), (20, 12))
    sh = b.add(mid, (0.45, 0.03, 0), 0.16, "body", (Y, Z), (20, 12))
    neck = b.add(sh, (0.22, 0.24, 0), 0.09, "neck", (Z, Y), (30, 35))
    head = b.add(neck, (0.18, 0.1, 0), 0.12, "head", (Z, Y), (25, 25))
    b.add(head, (0.2, -0.07, 0), 0.065, "snout")
    b.chain(hips, [(-0.25, 0.05, 0), (-0.25, 0.04, 0), (-0.22, -0.03, 0)],
            [0.065, 0.055, 0.05], "tail", (Y, Z), (40, 30))
    for top, limb in ((sh, "front"), (hips, "hind")):
        for s in (1, -1):
            j = b.add(top, (0, -0.08, 0.14 * s), 0.085, limb)
            j = b.add(j, (0.02, -0.32, 0.01 * s), 0.065, limb, (Z, X), (40, 15))
            j = b.add(j, (-0.02, -0.32, 0), 0.05, limb, (Z,), (60,))
            b.add(j, (0.08, -0.04, 0), 0.05, limb, (Z,), (30,))


def _hand(b: _Builder) -> None:
    # palm in the x-y plane, fingers along +y, palm facing +z
    wrist = b.add(-1, (0, 0, 0), 0.1, "palm")
    knuckles_x = (-0.225, -0.075, 0.075, 0.225)
    spread = (-10.0, -3.0, 3.0, 10.0)
    lengths = ((0.2, 0.13, 0.1), (0.23, 0.15, 0.11), (0.22, 0.14, 0.1), (0.17, 0.11, 0.09))
    for k, (x, ang, lens) in enumerate(zip(knuckles_x, spread, lengths, strict=True)):
        d = np.array([math.sin(ang * _DEG), math.cos(ang * _DEG), 0.0])
        kn = b.add(wrist, (x, 0.48 - 0.03 * abs(k - 1.5), 0), 0.062, "palm")
        b.chain(kn, [tuple(d * L) for L in lens], [0.055, 0.05, 0.047], f"finger{k}",
                (X, Z), (75, 10))
    th = b.add(wrist, (0.2, 0.08, 0), 0.075, "thumb", (Y, Z), (25, 20))
    b.chain(th, [(0.13, 0.12, 0.02), (0.1, 0.1, 0.02), (0.08, 0.08, 0.01)],
            [0.062, 0.055, 0.05], "thumb", (X, Z), (50, 15))


def _snake(b: _Builder) -> None:
    n = 9
    tail = b.add(-1, (-1.0, 0.1, 0), 0.055, "body")
    j = tail
    for k in range(1, n):
        r = 0.055 + 0.03 * math.sin(math.pi * k / (n - 1)) if k < n - 1 else 0.07
        j = b.add(j, (0.23, 0, 0), r, "body", (Y, Z), (35, 15))
    b.add(j, (0.1, 0, 0), 0.075, "head", (Y, Z), (25, 15))


def _octopus(b: _Builder) -> None:
    body = b.add(-1, (0, 0, 0), 0.24, "body")
    b.add(body, (0, 0.28, 0), 0.2, "mantle")
    arms = 8
    for k in range(arms):
        a = 2 * math.pi * k / arms
        d = np.array([math.cos(a), 0.0, math.sin(a)])
        side = np.cross(d, Y)  # bending up/down turns about this axis
        j = b.add(body, tuple(0.2 * d + (0, -0.08, 0)), 0.1, "arm")
        b.chain(j, [tuple(0.25 * d - (0, 0.04, 0)), tuple(0.24 * d), tuple(0.22 * d)],
                [0.08, 0.065, 0.052], "arm", (tuple(side), Y), (40, 25))


_BUILDERS = {
    "biped": _biped,
    "quadruped": _quadruped,
    "hand": _hand,
    "snake": _snake,
    "octopus": _octopus,
}


def limb_groups(cls: str) -> list[str]:
    """The limb group of every joint of a class's skeleton (e.g. ``"arm"``, ``"leg"``), in
    joint order: the groups whose length and thickness vary together."""
    check_choice("figure class", cls, CLASSES)
    b = _Builder()
    _BUILDERS[cls](b)
    return list(b.limbs)


def make_skeleton(cls: str, *, seed: int | None = None, variation: float = 0.15) -> Skeleton:
    """The rest skeleton of a figure class, limbs varied by ``seed``.

    Parameters
    ----------
    cls : str
        One of :data:`CLASSES`.
    seed : int, optional
        Seed of the intra-class variation; ``None`` gives the canonical figure.
    variation : float
        Relative spread of limb-group lengths (``±variation``) and thicknesses
        (``±variation / 2``), in [0, 0.3]. Left and right limbs vary together.

    Returns
    -------
    Skeleton
    """
    check_choice("figure class", cls, CLASSES)
    variation = float(variation)
    if not (0.0 <= variation <= 0.3):
        raise InvalidOptionError(f"variation must lie in [0, 0.3], got {variation!r}")
    b = _Builder()
    _BUILDERS[cls](b)
    rng = None if seed is None else np.random.default_rng([int(seed), CLASSES.index(cls)])
    return b.build(cls, rng, variation)


# --------------------------------------------------------------------------- template mesh


def _cone_distance(P, a, b, ra, rb):
    """Approximate signed distance from points P (k, 3) to a tapered capsule a-b."""
    ab = b - a
    L2 = float(ab @ ab)
    t = np.clip((P - a) @ ab / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(P))
    q = a + t[:, None] * ab
    return np.linalg.norm(P - q, axis=1) - (ra + t * (rb - ra)), t


def _bone_distances(sk: Skeleton, P: np.ndarray):
    """(k, B) distances of points to every bone's tapered capsule and (k, B) radii there."""
    bones = sk.bones
    D = np.empty((len(P), len(bones)))
    R = np.empty_like(D)
    for i, (pa, ch) in enumerate(bones):
        ra, rb = sk.radii[pa], sk.radii[ch]
        D[:, i], t = _cone_distance(P, sk.positions[pa], sk.positions[ch], ra, rb)
        R[:, i] = ra + t * (rb - ra)
    return D, R


def _implicit_grid(sk: Skeleton, resolution: int, blend: float):
    """Smooth union of the bone capsules sampled on a grid: (field, origin, spacing)."""
    lo = (sk.positions - sk.radii[:, None]).min(axis=0)
    hi = (sk.positions + sk.radii[:, None]).max(axis=0)
    h = float((hi - lo).max()) / resolution
    pad = 3 * h + blend
    lo, hi = lo - pad, hi + pad
    shape = np.ceil((hi - lo) / h).astype(int) + 1
    big = float(np.linalg.norm(hi - lo))
    field = np.full(shape, big)
    for pa, ch in sk.bones:
        a, b = sk.positions[pa], sk.positions[ch]
        ra, rb = sk.radii[pa], sk.radii[ch]
        r = max(ra, rb) + blend + h
        i0 = np.maximum(np.floor((np.minimum(a, b) - r - lo) / h).astype(int), 0)
        i1 = np.minimum(np.ceil((np.maximum(a, b) + r - lo) / h).astype(int) + 1, shape)
        axes = [lo[k] + h * np.arange(i0[k], i1[k]) for k in range(3)]
        G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        d, _ = _cone_distance(G.reshape(-1, 3), a, b, ra, rb)
        d = d.reshape(G.shape[:3])
        sub = field[i0[0]:i1[0], i0[1]:i1[1], i0[2]:i1[2]]
        # polynomial smooth minimum: equals min(a, b) when |a - b| >= blend
        k = max(blend, 1e-12)
        w = np.maximum(k - np.abs(sub - d), 0.0) / k
        sub[...] = np.minimum(sub, d) - w * w * k / 4.0
    return field, lo, h


class Template(NamedTuple):
    """One instance of a figure class in its rest pose, ready to be posed.

    Attributes
    ----------
    V : (n, 3) float64
        Rest vertices.
    F : (m, 3) int64
        Triangles (closed, manifold, one component, outward oriented).
    weights : (n, B) float64
        Skinning weight of each vertex for each bone (rows sum to 1).
    skeleton : Skeleton
    """

    V: np.ndarray
    F: np.ndarray
    weights: np.ndarray
    skeleton: Skeleton


def _skinning_weights(
    sk: Skeleton, V: np.ndarray, F: np.ndarray, sharpness: float, smoothing: int
) -> np.ndarray:
    """Smooth weights from distances to the bones, limited to bones touching the nearest,
    then averaged ``smoothing`` times over mesh neighbours (softens concave creases)."""
    D, R = _bone_distances(sk, V)  # (n, B)
    bones = sk.bones
    B = len(bones)
    # bones are adjacent when they share a joint
    share = (
        (bones[:, None, 1] == bones[None, :, 0])
        | (bones[:, None, 0] == bones[None, :, 1])
        | (bones[:, None, 0] == bones[None, :, 0])
    )
    share |= np.eye(B, dtype=bool)
    nearest = D.argmin(axis=1)
    allowed = share[nearest]  # (n, B)
    tau = sharpness * R[np.arange(len(V)), nearest]  # (n,)
    excess = (D - D[np.arange(len(V)), nearest][:, None]) / tau[:, None]
    W = np.where(allowed, np.exp(-excess), 0.0)
    W[W < 1e-6] = 0.0
    W /= W.sum(axis=1, keepdims=True)
    if smoothing > 0:
        import scipy.sparse as sp

        n = len(V)
        E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n)).tocsr()
        A = ((A + A.T) > 0).astype(np.float64)
        mean = sp.diags(1.0 / np.asarray(A.sum(axis=1)).ravel()) @ A
        for _ in range(int(smoothing)):
            W = 0.5 * W + 0.5 * (mean @ W)
        W[W < 1e-6] = 0.0
        W /= W.sum(axis=1, keepdims=True)
    return W


def build_template(
    skeleton: Skeleton,
    *,
    target_vertices: int = 3000,
    resolution: int = 128,
    blend: float | None = None,
    skin_sharpness: float = 0.5,
    skin_smoothing: int = 3,
) -> Template:
    """Skin a skeleton into one watertight manifold mesh with skinning weights.

    Parameters
    ----------
    skeleton : Skeleton
    target_vertices : int
        Vertex count after decimation, in [500, 50000] (the marching-cubes mesh is
        decimated to it; if it already has fewer vertices it is kept as is).
    resolution : int
        Voxels along the longest side of the figure's bounding box, in [48, 320]. The
        thinnest limbs of the built-in classes span at least 2 voxels at 96.
    blend : float, optional
        Width of the smooth union of the capsules (default 0.6 x the thinnest radius).
    skin_sharpness : float
        Width of the weight transition around a joint, as a fraction of the local
        tube radius (smaller = stiffer joints).
    skin_smoothing : int
        Rounds of neighbour averaging of the weights (0 = raw distance weights).

    Returns
    -------
    Template

    Raises
    ------
    InvalidOptionError
        Out-of-range parameters.
    GeoshapeError
        The polygonised surface is not a closed manifold (raise ``resolution``).

    Notes
    -----
    Time O(resolution^3) for the field (evaluated only near bones) and marching cubes,
    plus O(m log m) for decimation; memory O(resolution^3).
    """
    import pymeshlab
    from geoshape_datasets_gen._topology import topology_report
    from skimage.measure import marching_cubes

    target_vertices = int(target_vertices)
    resolution = int(resolution)
    if not (500 <= target_vertices <= 50000):
        raise InvalidOptionError(f"target_vertices must lie in [500, 50000], got {target_vertices}")
    if not (48 <= resolution <= 320):
        raise InvalidOptionError(f"resolution must lie in [48, 320], got {resolution}")
    if blend is None:
        blend = 0.6 * float(skeleton.radii.min())
    field, origin, h = _implicit_grid(skeleton, resolution, float(blend))
    Vm, Fm, _, _ = marching_cubes(field, level=0.0, spacing=(h, h, h), allow_degenerate=False)
    Vm = Vm.astype(np.float64) + origin
    Vm, Fm = largest_component(Vm, Fm.astype(np.int64))
    if signed_volume(Vm, Fm) < 0:
        Fm = Fm[:, ::-1].copy()
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=Vm, face_matrix=Fm))
    ms.meshing_remove_duplicate_vertices()
    ms.meshing_remove_null_faces()
    ms.meshing_remove_unreferenced_vertices()
    nv = ms.current_mesh().vertex_number()
    if nv > target_vertices:
        from geoshape_datasets_gen.decimate import quadric_collapse_pass

        quadric_collapse_pass(ms, target_vertices, preserve_boundary=False)
    mesh = ms.current_mesh()
    V = np.ascontiguousarray(mesh.vertex_matrix(), dtype=np.float64)
    F = np.ascontiguousarray(mesh.face_matrix(), dtype=np.int64)
    report = topology_report(F)
    if not (report.watertight and report.n_components == 1 and report.n_vertices == len(V)):
        raise GeoshapeError(
            f"{skeleton.name}: generated surface is not a closed single-component manifold "
            f"({report}); try a higher resolution"
        )
    if signed_volume(V, F) < 0:
        F = F[:, ::-1].copy()
    W = _skinning_weights(skeleton, V, F, float(skin_sharpness), int(skin_smoothing))
    return Template(V, F, W, skeleton)


# --------------------------------------------------------------------------- posing


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    C = 1 - c
    return np.array(
        [
            [c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C],
        ]
    )


def random_pose(skeleton: Skeleton, seed, *, amount: float = 1.0) -> np.ndarray:
    """Joint angles drawn uniformly within ``amount`` x each joint's limits.

    Parameters
    ----------
    skeleton : Skeleton
    seed : int or sequence of int
        Seed of the draw (anything ``numpy.random.default_rng`` accepts).
    amount : float
        Fraction of the joint limits used, in [0, 1].

    Returns
    -------
    angles : (J, 2) float64
        Radians about the two bending axes of each joint.
    """
    amount = float(amount)
    if not (0.0 <= amount <= 1.0):
        raise InvalidOptionError(f"pose amount must lie in [0, 1], got {amount!r}")
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, skeleton.limits.shape) * skeleton.limits * amount


def joint_transforms(skeleton: Skeleton, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rotation and translation of every joint's frame for the given angles.

    A point ``x`` rigidly attached below joint ``j`` goes to ``R[j] @ x + t[j]``.

    Returns
    -------
    R : (J, 3, 3) float64
    t : (J, 3) float64
    """
    J = len(skeleton.parents)
    angles = np.asarray(angles, dtype=np.float64).reshape(J, 2)
    R = np.empty((J, 3, 3))
    t = np.empty((J, 3))
    for j, p in enumerate(skeleton.parents):
        Rl = _axis_angle(skeleton.axes[j, 0], angles[j, 0]) if skeleton.limits[j, 0] else np.eye(3)
        if skeleton.limits[j, 1]:
            Rl = _axis_angle(skeleton.axes[j, 1], angles[j, 1]) @ Rl
        c = skeleton.positions[j]
        tl = c - Rl @ c  # local rotation about the joint's rest position
        if p < 0:
            R[j], t[j] = Rl, tl
        else:
            R[j], t[j] = R[p] @ Rl, R[p] @ tl + t[p]
    return R, t


def pose_vertices(template: Template, angles: np.ndarray) -> np.ndarray:
    """Vertices of the template posed by linear-blend skinning.

    Parameters
    ----------
    template : Template
    angles : (J, 2) array_like
        Joint angles, e.g. from :func:`random_pose`.

    Returns
    -------
    V : (n, 3) float64
        Posed vertices (use with ``template.F``; ids unchanged).

    Notes
    -----
    Time O(n B), memory O(n B) for n vertices and B bones.
    """
    R, t = joint_transforms(template.skeleton, angles)
    parent_of_bone = template.skeleton.bones[:, 0]
    Rb, tb = R[parent_of_bone], t[parent_of_bone]  # each bone follows its parent joint
    moved = np.einsum("bij,nj->nbi", Rb, template.V) + tb[None]  # (n, B, 3)
    return np.einsum("nb,nbi->ni", template.weights, moved)


# --------------------------------------------------------------------------- figures


class Figure(NamedTuple):
    """Several poses of one instance of a figure class.

    Attributes
    ----------
    poses : (P, n, 3) float64
        Vertex positions of each pose; vertex ``i`` corresponds across poses.
    F : (m, 3) int64
        Faces shared by all poses.
    template : Template
        Rest mesh, weights and skeleton.
    angles : (P, J, 2) float64
        Joint angles of each pose.
    """

    poses: np.ndarray
    F: np.ndarray
    template: Template
    angles: np.ndarray


def generate_figure(
    cls: str,
    *,
    poses: int = 4,
    seed: int = 0,
    instance: int = 0,
    variation: float = 0.15,
    amount: float = 1.0,
    target_vertices: int = 3000,
    resolution: int = 128,
) -> Figure:
    """Generate ``poses`` poses of one instance of a figure class.

    Parameters
    ----------
    cls : str
        One of :data:`CLASSES`.
    poses : int
        Number of poses, in [1, 1000]. All are random (none is the rest pose).
    seed, instance : int
        Together they fix the instance's proportions and every pose: the same values
        give bit-identical output.
    variation : float
        Intra-class variation of limb lengths/thicknesses (see :func:`make_skeleton`).
    amount : float
        Fraction of the joint limits used by the random poses (see :func:`random_pose`).
    target_vertices, resolution : int
        Mesh size and voxel resolution (see :func:`build_template`).

    Returns
    -------
    Figure

    Examples
    --------
    >>> fig = generate_figure("snake", poses=2, seed=3, target_vertices=800, resolution=64)
    >>> fig.poses.shape[0], fig.poses.shape[2]
    (2, 3)
    """
    check_choice("figure class", cls, CLASSES)
    poses = check_whole("poses", poses, 1, 1000)
    ci = CLASSES.index(cls)
    inst_seed = int(np.random.SeedSequence([int(seed), ci, int(instance)]).generate_state(1)[0])
    sk = make_skeleton(cls, seed=inst_seed, variation=variation)
    tpl = build_template(sk, target_vertices=target_vertices, resolution=resolution)
    angles = np.stack(
        [
            random_pose(sk, [int(seed), ci, int(instance), k], amount=amount)
            for k in range(poses)
        ]
    )
    Vs = np.stack([pose_vertices(tpl, a) for a in angles])
    return Figure(Vs, tpl.F, tpl, angles)


def write_collection(
    out_dir: str | os.PathLike,
    *,
    classes: Sequence[str] = CLASSES,
    instances: int = 1,
    poses: int = 4,
    seed: int = 0,
    variation: float = 0.15,
    amount: float = 1.0,
    target_vertices: int = 3000,
    resolution: int = 128,
    progress=None,
) -> dict:
    """Write a benchmark of posed figures with identity ground truth.

    Writes into ``out_dir``: one mesh per pose ``<class><instance>_<pose>.off``
    (e.g. ``hand0_03.off``), ``labels.csv`` (``file,label``; label = class),
    ``pairs.csv`` (every pair of poses of the same instance, landmark columns empty =
    identity ground truth, the format of the shared benchmark sets) and
    ``generator.json`` (the parameters). Every file is written atomically.

    Parameters
    ----------
    out_dir : path
    classes : sequence of str
        Classes to generate, from :data:`CLASSES`.
    instances : int
        Instances per class (different proportions, different meshes), in [1, 100].
    poses : int
        Poses per instance, in [1, 1000].
    seed, variation, amount, target_vertices, resolution
        See :func:`generate_figure`.
    progress : callable, optional
        Called as ``progress(done, total)`` after each instance.

    Returns
    -------
    dict
        ``{"files": [...], "labels": [...], "pairs": [(source, target), ...]}``
        with paths relative to ``out_dir``.

    Notes
    -----
    Time: ``len(classes) * instances`` template builds (about a second each at the
    defaults) plus O(n B) per pose.
    """
    from geoshape.io.atomic import write_text_atomic
    from geoshape.io.mesh_io import save_mesh

    classes = [check_choice("figure class", c, CLASSES) for c in classes]
    if not classes:
        raise InvalidOptionError(f"give at least one figure class from {', '.join(CLASSES)}")
    if len(set(classes)) != len(classes):
        raise InvalidOptionError(f"figure classes repeat: {classes}")
    instances = check_whole("instances", instances, 1, 100)
    poses = check_whole("poses", poses, 1, 1000)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files, labels, pairs = [], [], []
    total, done = len(classes) * instances, 0
    for cls in classes:
        for inst in range(instances):
            fig = generate_figure(
                cls, poses=poses, seed=seed, instance=inst, variation=variation,
                amount=amount, target_vertices=target_vertices, resolution=resolution,
            )
            names = [f"{cls}{inst}_{k:02d}.off" for k in range(poses)]
            for name, Vp in zip(names, fig.poses, strict=True):
                save_mesh(out / name, Vp, fig.F)
            files += names
            labels += [cls] * poses
            pairs += [(names[a], names[b]) for a in range(poses) for b in range(a + 1, poses)]
            done += 1
            if progress is not None:
                progress(done, total)
    write_text_atomic(
        out / "labels.csv", "file,label\n" + "".join(f"{f},{c}\n" for f, c in zip(files, labels, strict=True))
    )
    header = "source,target,source_landmarks,target_landmarks,target_symmetric_landmarks\n"
    write_text_atomic(out / "pairs.csv", header + "".join(f"{s},{t},,,\n" for s, t in pairs))
    params = {
        "generator": "geoshape_datasets_gen.articulated3d.write_collection",
        "classes": classes, "instances": instances, "poses": poses, "seed": int(seed),
        "variation": float(variation), "amount": float(amount),
        "target_vertices": int(target_vertices), "resolution": int(resolution),
        "ground_truth": "identity: vertex i of a pose corresponds to vertex i of every "
                        "other pose of the same instance",
    }
    write_text_atomic(out / "generator.json", json.dumps(params, indent=2) + "\n")
    return {"files": files, "labels": labels, "pairs": pairs}
