"""Articulated 2D silhouettes with known classes: a seeded, deterministic generator.

Each class is a jointed figure built from capsules (thick segments with round ends) and
ellipses; a *pose* draws the joint angles from class-specific ranges (parts bend at their
joints), jitters part lengths slightly, and applies a random rotation. Figures are rendered
as binary images (``skimage.draw``), scaled to fit the canvas. Same seed → same images.

Classes: ``person`` (head, torso, two-segment arms and legs), ``hand`` (palm, five
fingers of two or three phalanges), ``quadruped`` (body, neck and head, four two-segment
legs, tail), ``star`` (hub with five two-segment arms), ``snake`` (a chain of seven
capsules), ``crab`` (body, two three-segment claws, six short legs).

Usage::

    python -m geoshape_datasets_gen.silhouettes2d OUT_DIR --per-class 5 --seed 0
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

CLASSES = ("person", "hand", "quadruped", "star", "snake", "crab")

__all__ = ["CLASSES", "figure_primitives", "render_primitives", "articulated_silhouette",
           "generate_silhouettes"]


def _chain(start, base_angle, segments, bends):
    """Capsules of a kinematic chain: ``segments = [(length, radius)]``, ``bends`` in radians."""
    prims = []
    p = np.asarray(start, dtype=np.float64)
    angle = base_angle
    for (length, radius), bend in zip(segments, bends, strict=True):
        angle += bend
        q = p + length * np.array([np.cos(angle), np.sin(angle)])
        prims.append(("capsule", p.copy(), q.copy(), radius))
        p = q
    return prims


def figure_primitives(cls: str, rng: np.random.Generator) -> list:
    """Primitives of one random pose of class ``cls`` (unit-ish coordinates, y up)."""
    if cls not in CLASSES:
        from geoshape.errors import InvalidOptionError

        raise InvalidOptionError(f"class must be one of {', '.join(CLASSES)}; got {cls!r}")

    def jit(x):
        return x * rng.uniform(0.93, 1.07)

    def u(lo, hi):
        return np.deg2rad(rng.uniform(lo, hi))

    prims: list = []
    if cls == "person":
        prims.append(("ellipse", np.array([0.0, 0.0]), jit(0.22), jit(0.45), 0.0))
        prims.append(("ellipse", np.array([0.0, 0.56]), 0.15, 0.17, 0.0))
        for side in (-1, 1):
            base = np.pi / 2 - side * np.pi / 2  # 0 (right) or pi (left)
            shoulder = np.array([side * 0.17, 0.33])
            prims += _chain(shoulder, base, [(jit(0.38), 0.07), (jit(0.34), 0.06)],
                            [side * -u(20, 80), side * -u(-40, 90)])
            hip = np.array([side * 0.11, -0.38])
            prims += _chain(hip, -np.pi / 2, [(jit(0.45), 0.09), (jit(0.42), 0.075)],
                            [side * u(-5, 35), side * -u(-10, 70)])
    elif cls == "hand":
        prims.append(("ellipse", np.array([0.0, 0.0]), jit(0.42), jit(0.5), 0.0))
        prims += _chain(np.array([0.0, -0.45]), -np.pi / 2, [(0.22, 0.24)], [0.0])  # wrist
        finger_x = (-0.3, -0.1, 0.1, 0.3)
        finger_len = (0.3, 0.36, 0.34, 0.26)
        for x, length in zip(finger_x, finger_len, strict=True):
            prims += _chain(np.array([x, 0.4]), np.pi / 2 + np.deg2rad(-x * 40),
                            [(jit(length), 0.09), (jit(length * 0.8), 0.085),
                             (jit(length * 0.6), 0.08)],
                            [u(-15, 15), u(-10, 70), u(0, 50)])
        prims += _chain(np.array([0.35, -0.1]), np.deg2rad(20),
                        [(jit(0.3), 0.09), (jit(0.25), 0.08)], [u(-20, 40), u(0, 60)])
    elif cls == "quadruped":
        prims.append(("ellipse", np.array([0.0, 0.0]), jit(0.6), jit(0.22), 0.0))
        neck = _chain(np.array([0.5, 0.1]), np.deg2rad(50), [(jit(0.3), 0.09)], [u(-25, 25)])
        prims += neck
        head_at = neck[-1][2]
        prims.append(("ellipse", head_at + [0.08, 0.0], jit(0.17), 0.1, u(-30, 10)))
        for x in (-0.45, -0.3, 0.3, 0.45):
            prims += _chain(np.array([x, -0.12]), -np.pi / 2,
                            [(jit(0.32), 0.07), (jit(0.3), 0.055)], [u(-35, 35), u(-50, 50)])
        prims += _chain(np.array([-0.58, 0.05]), np.pi + np.deg2rad(20),
                        [(jit(0.25), 0.04), (jit(0.2), 0.035)], [u(-40, 40), u(-50, 50)])
    elif cls == "star":
        prims.append(("ellipse", np.array([0.0, 0.0]), 0.28, 0.28, 0.0))
        for k in range(5):
            a = np.pi / 2 + 2 * np.pi * k / 5
            start = 0.2 * np.array([np.cos(a), np.sin(a)])
            prims += _chain(start, a, [(jit(0.4), 0.09), (jit(0.35), 0.07)],
                            [u(-15, 15), u(-60, 60)])
    elif cls == "snake":
        n = 7
        bends = [u(-35, 35) for _ in range(n)]
        prims += _chain(np.array([0.0, 0.0]), 0.0, [(jit(0.3), 0.09)] * n, bends)
        head_at = prims[-1][2]
        prims.append(("ellipse", head_at, 0.16, 0.11, float(np.sum(bends))))
    elif cls == "crab":
        prims.append(("ellipse", np.array([0.0, 0.0]), jit(0.45), jit(0.3), 0.0))
        for side in (-1, 1):
            base = np.pi / 2 - side * np.deg2rad(50)
            prims += _chain(np.array([side * 0.3, 0.2]), base,
                            [(jit(0.3), 0.07), (jit(0.28), 0.08), (jit(0.22), 0.1)],
                            [side * -u(-20, 30), side * u(20, 80), side * u(30, 90)])
            for k in range(3):
                start = np.array([side * (0.25 + 0.08 * k), -0.15 - 0.02 * k])
                a = -np.pi / 2 + side * np.deg2rad(40 + 20 * k)
                prims += _chain(start, a, [(jit(0.28), 0.045), (jit(0.22), 0.04)],
                                [u(-15, 15), side * u(-40, 10)])
    return prims


def render_primitives(prims: list, size: int = 128, margin: int = 6,
                      rotation: float = 0.0) -> np.ndarray:
    """Rasterise primitives into a ``(size, size)`` bool mask, rotated and scaled to fit."""
    from skimage.draw import disk, ellipse, polygon

    c, s = np.cos(rotation), np.sin(rotation)
    R = np.array([[c, -s], [s, c]])
    pts = []
    for p in prims:
        if p[0] == "capsule":
            _, a, b, r = p
            for q in (a, b):
                pts += [R @ q + [r, r], R @ q - [r, r]]
        else:
            _, ctr, rx, ry, _ = p
            m = max(rx, ry)
            pts += [R @ ctr + [m, m], R @ ctr - [m, m]]
    pts = np.array(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    scale = (size - 2 * margin) / max(hi - lo)
    offset = (size - scale * (hi - lo)) / 2 - scale * lo

    def to_px(q):  # (x, y) -> (row, col)
        x, y = scale * (R @ q) + offset
        return size - 1 - y, x

    mask = np.zeros((size, size), dtype=bool)
    for p in prims:
        if p[0] == "capsule":
            _, a, b, r = p
            (ra, ca), (rb, cb) = to_px(a), to_px(b)
            rr = r * scale
            d = np.array([rb - ra, cb - ca])
            n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-12) * rr
            poly_r = [ra + n[0], rb + n[0], rb - n[0], ra - n[0]]
            poly_c = [ca + n[1], cb + n[1], cb - n[1], ca - n[1]]
            mask[polygon(poly_r, poly_c, shape=mask.shape)] = True
            for rc, cc in ((ra, ca), (rb, cb)):
                mask[disk((rc, cc), rr, shape=mask.shape)] = True
        else:
            _, ctr, rx, ry, ang = p
            rc, cc = to_px(ctr)
            mask[ellipse(rc, cc, ry * scale, rx * scale, shape=mask.shape,
                         rotation=ang + rotation)] = True
    return mask


def articulated_silhouette(cls: str, seed: int, size: int = 128, rotate: bool = True) -> np.ndarray:
    """One pose of class ``cls`` as a bool mask; deterministic in ``(cls, seed)``."""
    rng = np.random.default_rng([seed, CLASSES.index(cls) if cls in CLASSES else 0])
    prims = figure_primitives(cls, rng)
    rotation = float(rng.uniform(0, 2 * np.pi)) if rotate else 0.0
    return render_primitives(prims, size=size, rotation=rotation)


def generate_silhouettes(out_dir: str | os.PathLike, *, per_class: int = 5, classes=CLASSES,
                         seed: int = 0, size: int = 128, rotate: bool = True) -> list[Path]:
    """Write ``per_class`` poses of each class as PNGs and a ``labels.csv`` (``file,label``).

    Files are ``<class>_<k>.png``; rows are grouped by class. Returns the image paths.
    Deterministic: the same arguments write byte-identical files.
    """
    from PIL import Image

    from geoshape.io.atomic import atomic_path, write_text_atomic

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths, lines = [], ["file,label"]
    for cls in classes:
        for k in range(per_class):
            mask = articulated_silhouette(cls, seed * 100003 + k, size=size, rotate=rotate)
            path = out / f"{cls}_{k}.png"
            with atomic_path(path) as tmp:
                Image.fromarray((mask * 255).astype(np.uint8), mode="L").save(tmp, format="PNG")
            paths.append(path)
            lines.append(f"{path.name},{cls}")
    write_text_atomic(out / "labels.csv", "\n".join(lines) + "\n")
    return paths


def main(argv=None) -> int:
    import argparse

    p = argparse.ArgumentParser(description="Generate articulated 2D silhouettes.")
    p.add_argument("out")
    p.add_argument("--per-class", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--size", type=int, default=128)
    a = p.parse_args(argv)
    paths = generate_silhouettes(a.out, per_class=a.per_class, seed=a.seed, size=a.size)
    print(f"wrote {len(paths)} silhouettes and labels.csv to {a.out}")  # noqa: T201
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
