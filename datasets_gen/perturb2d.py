"""Perturbed copies of a labelled silhouette collection: mirrored, noisy, notched, eroded.

Each perturbation maps a folder with images and ``labels.csv`` to a new folder with the same
file names, classes and row order, so scores on the copy compare directly with the clean set:

- ``mirror``: every other image (chosen with the seed) flipped left–right — the same object
  facing the other way (a shape and its mirror image are the same shape for retrieval);
- ``noise``: the boundary roughened by adding and removing small discs centred on random
  boundary pixels (radius ≈ 1.5 % of the object's size), as a careless segmentation does;
- ``notch``: two small bites (radius ≈ 6 % of the size) taken out of the boundary, the
  "small notches" of compact shapes;
- ``erode``: a morphological opening of radius ≈ 3 % of the size — thin parts (legs,
  tentacles, branches) shrink or vanish, thick parts barely change.

Sizes are fractions of the object's bounding-box diagonal, so the same setting means the same
thing on a 128² and a 1024² image. Deterministic: the same folder, kind and seed give
byte-identical files. O(h·w) per image.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from geoshape.errors import InvalidOptionError

PERTURBATIONS = ("mirror", "noise", "notch", "erode")

__all__ = ["PERTURBATIONS", "perturb_mask", "perturb_collection"]


def _disc(radius: float) -> np.ndarray:
    r = max(1, int(round(radius)))
    y, x = np.ogrid[-r : r + 1, -r : r + 1]
    return x * x + y * y <= radius * radius + 0.25


def _boundary(mask: np.ndarray) -> np.ndarray:
    from scipy import ndimage

    return np.argwhere(mask & ~ndimage.binary_erosion(mask))


def _stamp(mask: np.ndarray, centre, radius: float, value: bool) -> None:
    d = _disc(radius)
    r = d.shape[0] // 2
    y, x = int(centre[0]), int(centre[1])
    y0, y1, x0, x1 = (
        max(0, y - r),
        min(mask.shape[0], y + r + 1),
        max(0, x - r),
        min(mask.shape[1], x + r + 1),
    )
    sub = d[y0 - (y - r) : y1 - (y - r), x0 - (x - r) : x1 - (x - r)]
    mask[y0:y1, x0:x1][sub] = value


def perturb_mask(mask, kind: str, rng: np.random.Generator, *, index: int = 0, parity: int = 0) -> np.ndarray:
    """One perturbed copy of a binary mask ``(h, w)`` (``True`` = object); see the module text.

    ``mirror`` flips the items whose position ``index`` in the collection has the same parity
    as ``parity`` (every other one); the other kinds draw from ``rng``.
    """
    from scipy import ndimage

    if kind not in PERTURBATIONS:
        raise InvalidOptionError(f"perturbation must be one of {', '.join(PERTURBATIONS)}; got {kind!r}")
    mask = np.asarray(mask, dtype=bool).copy()
    rows, cols = np.nonzero(mask)
    if len(rows) == 0:
        return mask
    size = float(np.hypot(rows.max() - rows.min() + 1, cols.max() - cols.min() + 1))
    if kind == "mirror":
        return mask[:, ::-1].copy() if index % 2 == parity % 2 else mask
    if kind == "erode":
        return ndimage.binary_opening(mask, structure=_disc(0.03 * size)) | _largest_core(mask)
    edge = _boundary(mask)
    if kind == "notch":
        for p in edge[rng.choice(len(edge), size=min(2, len(edge)), replace=False)]:
            _stamp(mask, p, 0.06 * size, False)
        return mask
    count = max(4, len(edge) // 12)  # noise: bumps and dents along the boundary
    for p, grow in zip(
        edge[rng.choice(len(edge), size=min(count, len(edge)), replace=False)],
        rng.random(count) < 0.5,
        strict=False,
    ):
        _stamp(mask, p, 0.015 * size, bool(grow))
    return mask


def _largest_core(mask: np.ndarray) -> np.ndarray:
    """A pixel of the object's deepest interior, so an opening never empties the image."""
    from scipy import ndimage

    depth = ndimage.distance_transform_edt(mask)
    core = np.zeros_like(mask)
    core[np.unravel_index(int(np.argmax(depth)), depth.shape)] = True
    return core


def perturb_collection(
    src: str | os.PathLike, dst: str | os.PathLike, kind: str, *, seed: int = 0
) -> list[Path]:
    """Write the ``kind`` perturbation of every image of ``src`` (with its ``labels.csv``) to ``dst``.

    Images are written as PNG masks (white object on black) under the same names with a
    ``.png`` suffix; ``labels.csv`` keeps the order and classes. Returns the written paths.
    """
    from PIL import Image

    from geoshape.io.atomic import atomic_path, write_text_atomic
    from geoshape.io.datasets import read_labels
    from geoshape.io.silhouette import load_silhouette

    if kind not in PERTURBATIONS:
        raise InvalidOptionError(f"perturbation must be one of {', '.join(PERTURBATIONS)}; got {kind!r}")
    items = read_labels(src)
    out = Path(dst)
    if out.resolve() == Path(src).resolve():
        raise InvalidOptionError(f"{dst}: the output folder is the input folder; choose another")
    names = [Path(item.path).with_suffix(".png").name for item in items]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InvalidOptionError(f"{src}: several images would be written as {', '.join(twice)}")
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng([seed, PERTURBATIONS.index(kind)])
    parity = int(rng.integers(2))
    lines, paths = ["file,label"], []
    for i, (item, name) in enumerate(zip(items, names, strict=True)):
        mask = perturb_mask(load_silhouette(item.path), kind, rng, index=i, parity=parity)
        with atomic_path(out / name, suffix=".png") as tmp:
            Image.fromarray((mask * 255).astype(np.uint8)).save(tmp, format="PNG")
        lines.append(f"{name},{item.label}")
        paths.append(out / name)
    write_text_atomic(out / "labels.csv", "\n".join(lines) + "\n")
    return paths
