"""Articulated creature classes for retrieval: the figures of :mod:`articulated3d` and more.

Four classes reuse the skeletons of :mod:`geoshape_datasets_gen.articulated3d` (``human`` =
biped, ``fourleg`` = quadruped, ``hand``, ``octopus``); six new skeletons are built with the
same joint-tree API: ``teddy`` (round body, big head, ears, stubby limbs), ``ant`` (three
body parts, six three-segment legs, antennae), ``fish`` (a laterally flattened body bending
side to side, a forked tail and fins), ``bird`` (broad flat wings that flap, tail fan, legs),
``pliers`` (two rigid arms crossing at a hinge) and ``armadillo`` (a hunched biped with long
ears, snout, claws and tail).

Capsules are round, so flat parts are made after skinning by a per-bone affine squash:
every vertex moves by the skinning-weighted blend of ``q_b + S_b (v - q_b)``, where ``q_b``
is its nearest point on bone ``b`` and ``S_b`` a diagonal scaling of that bone's limb group
(a wing's feather bones widened along the chord and thinned across it). A whole-figure
squash (a fish's flat sides, the pliers' flat arms) scales the joints with the mesh. The
posing machinery (linear-blend skinning) is the one of :mod:`articulated3d`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from geoshape_datasets_gen.articulated3d import (
    Skeleton,
    Template,
    X,
    Y,
    Z,
    _Builder,
    build_template,
    make_skeleton,
    pose_vertices,
    random_pose,
)

from geoshape._options import check_choice

__all__ = ["CREATURE_CLASSES", "creature_template", "creature_pose"]

CREATURE_CLASSES = ("human", "teddy", "hand", "ant", "octopus", "fourleg", "fish", "bird", "pliers",
                    "armadillo")

# classes that are articulated3d's own figures
_REUSED = {"human": "biped", "fourleg": "quadruped", "hand": "hand", "octopus": "octopus"}


def _teddy(b: _Builder) -> None:
    pelvis = b.add(-1, (0, 0.55, 0), 0.2, "torso")
    belly = b.add(pelvis, (0, 0.18, 0.02), 0.26, "torso", (X, Z), (10, 10))
    chest = b.add(belly, (0, 0.2, -0.02), 0.22, "torso", (X, Y), (15, 20))
    neck = b.add(chest, (0, 0.14, 0), 0.13, "neck", (X, Y), (20, 35))
    head = b.add(neck, (0, 0.16, 0), 0.22, "head")
    b.add(head, (0, 0.06, 0), 0.2, "head")
    b.add(head, (0, -0.06, 0.2), 0.09, "snout")
    for s in (1, -1):
        ear = b.add(head, (0.15 * s, 0.15, -0.02), 0.07, "ear")
        b.add(ear, (0.03 * s, 0.03, 0), 0.075, "ear")
        sh = b.add(chest, (0.2 * s, 0.02, 0), 0.1, "arm")
        el = b.add(sh, (0.17 * s, -0.1, 0.02), 0.09, "arm", (Z, X), (50, 40))
        b.add(el, (0.12 * s, -0.1, 0.04), 0.095, "paw", (Z, X), (30, 30))
        hip = b.add(pelvis, (0.13 * s, -0.06, 0), 0.13, "leg")
        kn = b.add(hip, (0.04 * s, -0.2, 0.06), 0.12, "leg", (X, Z), (50, 20))
        b.add(kn, (0, -0.12, 0.12), 0.12, "foot", (X,), (30,))


def _ant(b: _Builder) -> None:
    # body along +x (head forward), legs splayed sideways (+-z) down to the ground
    th = b.add(-1, (0, 0.4, 0), 0.075, "thorax")
    th2 = b.add(th, (0.18, 0.03, 0), 0.08, "thorax")
    neck = b.add(th2, (0.08, 0.02, 0), 0.045, "neck", (Z, Y), (20, 25))
    head = b.add(neck, (0.08, 0.0, 0), 0.1, "head")
    hf = b.add(head, (0.08, -0.01, 0), 0.08, "head")
    pet = b.add(th, (-0.1, -0.01, 0), 0.04, "petiole", (Z, Y), (20, 20))
    g1 = b.add(pet, (-0.1, 0.02, 0), 0.13, "gaster")
    g2 = b.add(g1, (-0.16, -0.01, 0), 0.15, "gaster")
    b.add(g2, (-0.14, -0.04, 0), 0.07, "gaster")
    for s in (1, -1):
        m = b.add(hf, (0.06, -0.03, 0.04 * s), 0.03, "mandible")
        b.add(m, (0.05, 0, -0.03 * s), 0.022, "mandible")
        a = b.add(head, (0.04, 0.08, 0.05 * s), 0.03, "antenna")
        a = b.add(a, (0.08, 0.12, 0.06 * s), 0.025, "antenna", (Z, Y), (30, 20))
        b.add(a, (0.14, -0.06, 0.06 * s), 0.022, "antenna", (Z, Y), (35, 25))
        # front, middle, hind legs: coxa, femur (up and out), tibia (down), tarsus
        for k, (base, fx, tx) in enumerate(((th2, 0.12, 0.12), (th, 0.02, -0.02), (th, -0.1, -0.16))):
            j = b.add(base, (0.0, -0.04, 0.06 * s), 0.04, f"leg{k}")
            j = b.add(j, (fx, 0.14, 0.22 * s), 0.032, f"leg{k}", (Y, X), (25, 20))
            j = b.add(j, (tx, -0.34, 0.16 * s), 0.028, f"leg{k}", (X, Y), (20, 15))
            b.add(j, (tx * 0.5, -0.07, 0.1 * s), 0.024, f"leg{k}", (X,), (20,))


def _fish(b: _Builder) -> None:
    # body along +x, bending side to side (about y); fins flattened afterwards
    mid = b.add(-1, (0, 0.5, 0), 0.2, "body")
    front = b.add(mid, (0.22, 0.0, 0), 0.17, "body", (Y,), (8,))
    head = b.add(front, (0.18, -0.01, 0), 0.12, "head", (Y, Z), (10, 5))
    b.add(head, (0.12, -0.01, 0), 0.05, "head")
    r1 = b.add(mid, (-0.22, 0.0, 0), 0.15, "body", (Y,), (20,))
    r2 = b.add(r1, (-0.2, 0.0, 0), 0.08, "body", (Y,), (25,))
    r3 = b.add(r2, (-0.15, 0.0, 0), 0.04, "peduncle", (Y,), (25,))
    for ang, length in ((-40, 0.26), (-20, 0.2), (0, 0.15), (20, 0.2), (40, 0.26)):
        a = ang * math.pi / 180
        b.add(r3, (-length * math.cos(a), length * math.sin(a), 0), 0.022, "caudal", (Y,), (15,))
    for dx, h in ((0.05, 0.26), (-0.06, 0.27), (-0.16, 0.22)):
        b.add(mid, (dx - 0.06, h, 0), 0.03, "dorsal")
    b.add(r1, (-0.08, -0.2, 0), 0.03, "anal")
    for s in (1, -1):
        b.add(front, (-0.12, -0.1, 0.2 * s), 0.035, "pectoral", (Y, X), (25, 20))


def _bird(b: _Builder) -> None:
    # body along +x, wings along +-z (flattened and widened afterwards), tail fan behind
    body = b.add(-1, (0, 0.5, 0), 0.15, "body")
    chest = b.add(body, (0.2, 0.04, 0), 0.17, "body")
    neck = b.add(chest, (0.12, 0.14, 0), 0.075, "neck", (Z, Y), (30, 30))
    head = b.add(neck, (0.05, 0.1, 0), 0.085, "head", (Z, Y), (20, 30))
    b.add(head, (0.14, -0.03, 0), 0.022, "beak")
    tail = b.add(body, (-0.18, 0.0, 0), 0.1, "tailbase", (Z, Y), (15, 15))
    for ang in (-25, 0, 25):
        a = ang * math.pi / 180
        b.add(tail, (-0.25 * math.cos(a), 0.02, 0.25 * math.sin(a)), 0.035, "tail")
    for s in (1, -1):
        sh = b.add(chest, (0.0, 0.06, 0.12 * s), 0.07, "wing", (X, Y), (40, 15))
        el = b.add(sh, (-0.03, 0.02, 0.3 * s), 0.055, "wing", (X, Y), (35, 15))
        wr = b.add(el, (-0.06, 0.0, 0.3 * s), 0.045, "wing", (X, Y), (30, 15))
        b.add(wr, (-0.15, 0, 0.25 * s), 0.03, "wingtip", (X,), (20,))
        hip = b.add(body, (0.05, -0.12, 0.07 * s), 0.06, "leg")
        kn = b.add(hip, (0.03, -0.18, 0.01 * s), 0.03, "leg", (Z,), (30,))
        b.add(kn, (0.08, -0.02, 0), 0.025, "foot")


def _pliers(b: _Builder) -> None:
    # two rigid arms crossing at a hinge about z: each arm's jaw and handle lie on opposite sides
    hinge = b.add(-1, (0, 0, 0), 0.07, "hinge")
    for s in (1, -1):
        arm = b.add(hinge, (0, 0, 0.025 * s), 0.06, "arm", (Z,), (9,))
        j = b.add(arm, (0.18, 0.025 * s, 0), 0.05, "jaw")
        b.add(j, (0.16, -0.015 * s, 0), 0.025, "jaw")
        h = b.add(arm, (-0.3, -0.04 * s, 0), 0.045, "handle")
        h = b.add(h, (-0.3, -0.025 * s, 0), 0.05, "handle")
        b.add(h, (-0.12, -0.005 * s, 0), 0.045, "handle")


def _armadillo(b: _Builder) -> None:
    pelvis = b.add(-1, (0, 0.9, 0), 0.16, "torso")
    spine = b.add(pelvis, (0, 0.22, -0.04), 0.19, "torso", (X, Z), (25, 15))
    chest = b.add(spine, (0, 0.22, 0.05), 0.17, "torso", (X, Y), (25, 25))
    neck = b.add(chest, (0, 0.14, 0.06), 0.08, "neck", (X, Y), (30, 35))
    head = b.add(neck, (0, 0.1, 0.04), 0.1, "head")
    b.add(head, (0, -0.02, 0.17), 0.045, "snout")
    b.chain(pelvis, [(0, -0.06, -0.2), (0, -0.2, -0.2), (0, -0.15, -0.18)], [0.07, 0.05, 0.03], "tail",
            (X, Y), (30, 30))
    for s in (1, -1):
        e = b.add(head, (0.07 * s, 0.12, -0.03), 0.05, "ear")
        b.add(e, (0.06 * s, 0.15, -0.02), 0.035, "ear", (X, Z), (25, 20))
        sh = b.add(chest, (0.2 * s, 0.02, 0), 0.075, "arm")
        el = b.add(sh, (0.2 * s, -0.12, 0.05), 0.06, "arm", (Z, Y), (50, 40))
        wr = b.add(el, (0.16 * s, -0.12, 0.1), 0.05, "arm", (Y, Z), (40, 20))
        for dx in (-0.04, 0.0, 0.04):
            b.add(wr, (0.05 * s + dx, -0.04, 0.09), 0.022, "claw")
        hip = b.add(pelvis, (0.12 * s, -0.05, 0), 0.1, "leg")
        kn = b.add(hip, (0.05 * s, -0.33, 0.08), 0.08, "leg", (X, Z), (40, 15))
        an = b.add(kn, (0, -0.33, -0.06), 0.06, "leg", (X,), (50,))
        b.add(an, (0, -0.04, 0.15), 0.06, "foot", (X,), (20,))


@dataclasses.dataclass(frozen=True)
class _Spec:
    builder: object = None
    squash: tuple = (1.0, 1.0, 1.0)  # whole-figure scaling before posing
    flatten: tuple = ()  # (limb group, (sx, sy, sz)) scalings about each bone of the group
    amount: float = 0.8  # fraction of the joint limits used by poses
    variation: float = 0.2  # limb length / thickness spread between instances


_SPECS = {
    "human": _Spec(amount=0.8, variation=0.22),
    "fourleg": _Spec(amount=0.8, variation=0.25),
    "hand": _Spec(amount=0.8, variation=0.2),
    "octopus": _Spec(amount=1.0, variation=0.25),
    "teddy": _Spec(_teddy, amount=0.9, variation=0.22),
    "ant": _Spec(_ant, amount=0.9, variation=0.2),
    "fish": _Spec(_fish, squash=(1.0, 1.0, 0.6), amount=1.0, variation=0.2,
                  flatten=(("caudal", (1.0, 1.6, 0.3)), ("dorsal", (1.8, 1.0, 0.3)),
                           ("anal", (1.6, 1.0, 0.3)), ("pectoral", (1.4, 0.3, 1.0)))),
    "bird": _Spec(_bird, amount=0.9, variation=0.2,
                  flatten=(("wing", (2.6, 0.35, 1.0)), ("wingtip", (2.0, 0.35, 1.0)),
                           ("tail", (1.0, 0.3, 1.6)))),
    "pliers": _Spec(_pliers, squash=(1.0, 1.0, 0.5), amount=1.0, variation=0.18,
                    flatten=(("jaw", (1.0, 1.3, 0.8)),)),
    "armadillo": _Spec(_armadillo, amount=0.8, variation=0.2),
}


def _skeleton(cls: str, seed: int, variation: float) -> tuple[Skeleton, list]:
    """Rest skeleton of a creature class and the limb group of every joint."""
    spec = _SPECS[cls]
    if cls in _REUSED:
        sk = make_skeleton(_REUSED[cls], seed=seed, variation=variation)
        return dataclasses.replace(sk, name=cls), [""] * len(sk.parents)
    b = _Builder()
    spec.builder(b)
    return b.build(cls, np.random.default_rng([int(seed), CREATURE_CLASSES.index(cls)]), variation), b.limbs


def _flatten(tpl: Template, limbs: list, flatten) -> np.ndarray:
    """Vertices after the per-limb squash about each bone (see the module notes). (n, 3)."""
    sk = tpl.skeleton
    bones = sk.bones
    V = tpl.V
    out = np.zeros_like(V)
    scales = dict(flatten)
    for i, (pa, ch) in enumerate(bones):
        w = tpl.weights[:, i]
        S = scales.get(limbs[ch])
        if S is None:
            out += w[:, None] * V
            continue
        a, c = sk.positions[pa], sk.positions[ch]
        ab = c - a
        t = np.clip((V - a) @ ab / float(ab @ ab), 0.0, 1.0)
        q = a + t[:, None] * ab
        out += w[:, None] * (q + (V - q) * np.asarray(S))
    return out


def creature_template(
    cls: str, *, seed: int, target_vertices: int = 3000, resolution: int = 112
) -> Template:
    """One instance (proportions drawn from ``seed``) of a creature class, ready to pose.

    Parameters
    ----------
    cls : str
        One of :data:`CREATURE_CLASSES`.
    seed : int
        Seed of the instance's limb lengths and thicknesses.
    target_vertices, resolution : int
        See :func:`geoshape_datasets_gen.articulated3d.build_template`.

    Returns
    -------
    Template
        Closed manifold rest mesh (flat parts already squashed) with skinning weights; its
        skeleton's joints are scaled with any whole-figure squash.
    """
    check_choice("creature class", cls, CREATURE_CLASSES)
    spec = _SPECS[cls]
    sk, limbs = _skeleton(cls, seed, spec.variation)
    tpl = build_template(sk, target_vertices=target_vertices, resolution=resolution)
    V = _flatten(tpl, limbs, spec.flatten) if spec.flatten else tpl.V
    sq = np.asarray(spec.squash, dtype=np.float64)
    sk = dataclasses.replace(tpl.skeleton, positions=tpl.skeleton.positions * sq)
    return Template(V * sq, tpl.F, tpl.weights, sk)


def creature_pose(template: Template, seed) -> np.ndarray:
    """A random pose of a creature template.

    Parameters
    ----------
    template : Template
        From :func:`creature_template` (its skeleton's name is the class).
    seed : int or sequence of int
        Seed of the joint angles.

    Returns
    -------
    V : (n, 3) float64
        Posed vertices (faces ``template.F``).
    """
    cls = template.skeleton.name
    angles = random_pose(template.skeleton, seed, amount=_SPECS[cls].amount)
    if cls == "pliers":  # the two arms open symmetrically-ish, never cross
        arms = np.flatnonzero(template.skeleton.parents == 0)
        side = np.sign(template.skeleton.positions[arms, 2] - template.skeleton.positions[0, 2])
        angles[arms, 0] = side * np.abs(angles[arms, 0])
    return pose_vertices(template, angles)
