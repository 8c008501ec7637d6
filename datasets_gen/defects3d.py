"""Seeded real-world mesh defects: holes, inconsistent winding, mild stretch, loose debris.

Scanned and modelled meshes in real collections are rarely clean: some faces are missing,
patches are wound the other way, an axis is slightly rescaled, small loose pieces float
next to the object. Each function here adds one such defect to a triangle mesh, drawing
where and how much from a ``numpy.random.Generator`` (the same state gives the same mesh).
Sizes are relative to the mesh (bounding-box diagonal or mean edge length).
"""

from __future__ import annotations

import numpy as np

from geoshape.geometry.mesh import drop_unreferenced

__all__ = ["DEFECTS", "mean_edge_length", "punch_holes", "flip_patches", "stretch_axes",
           "add_debris"]

#: defect kinds of the mixed collection; ``components`` = several connected components
DEFECTS = ("components", "holes", "flipped", "stretch")


def _centroids(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    return V[F].mean(axis=1)


def _distance_to_seeds(P: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """(k,) distance of each point of ``P`` (k, 3) to its nearest seed of ``seeds`` (s, 3)."""
    return np.sqrt(((P[:, None, :] - seeds[None]) ** 2).sum(axis=2)).min(axis=1)


def mean_edge_length(V: np.ndarray, F: np.ndarray) -> float:
    """Mean length of the face edges (each interior edge counted twice)."""
    return float(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=2).mean())


def punch_holes(V: np.ndarray, F: np.ndarray, rng: np.random.Generator, *, count: int = 3,
                size: tuple = (1.5, 3.0)) -> tuple[np.ndarray, np.ndarray]:
    """Delete the faces around ``count`` random faces: small holes with open boundaries.

    Parameters
    ----------
    V : (n, 3) float64
    F : (m, 3) int64
    rng : numpy.random.Generator
    count : int
        Number of holes (seed faces drawn without replacement).
    size : (float, float)
        Range of each hole's radius, in mean edge lengths (faces whose centroid lies
        within it are deleted; the seed face always is).

    Returns
    -------
    V : (n', 3) float64
    F : (m', 3) int64
        Vertices left without a face are dropped.
    """
    C = _centroids(V, F)
    seeds = rng.choice(len(F), size=min(int(count), len(F)), replace=False)
    radii = rng.uniform(size[0], size[1], len(seeds)) * mean_edge_length(V, F)
    d = np.sqrt(((C[:, None, :] - C[seeds][None]) ** 2).sum(axis=2))  # (m, count)
    drop = (d <= radii[None]).any(axis=1)
    drop[seeds] = True
    return drop_unreferenced(V, F[~drop])


def flip_patches(V: np.ndarray, F: np.ndarray, rng: np.random.Generator, *, fraction: float = 0.1,
                 patches: int = 3) -> np.ndarray:
    """Reverse the winding of about ``fraction`` of the faces, in ``patches`` compact patches.

    Parameters
    ----------
    V : (n, 3) float64
    F : (m, 3) int64
    rng : numpy.random.Generator
    fraction : float
        Share of faces flipped (those nearest to the patch seeds).
    patches : int
        Number of patch seeds (random faces).

    Returns
    -------
    F : (m, 3) int64
        Same faces, some with reversed vertex order.
    """
    C = _centroids(V, F)
    seeds = C[rng.choice(len(F), size=min(int(patches), len(F)), replace=False)]
    d = _distance_to_seeds(C, seeds)
    flip = d <= np.quantile(d, float(fraction))
    out = F.copy()
    out[flip] = out[flip][:, ::-1]
    return out


def stretch_axes(V: np.ndarray, rng: np.random.Generator, *, low: float = 0.9,
                 high: float = 1.1) -> np.ndarray:
    """Scale each coordinate axis by its own factor in ``[low, high]`` about the centroid.

    Returns
    -------
    V : (n, 3) float64
    """
    c = V.mean(axis=0)
    return c + (V - c) * rng.uniform(low, high, 3)


def add_debris(V: np.ndarray, F: np.ndarray, rng: np.random.Generator, *, count: int = 2,
               size: tuple = (0.015, 0.035), gap: tuple = (0.02, 0.06)) -> tuple[np.ndarray, np.ndarray]:
    """Add ``count`` small loose blobs (icospheres) floating just off the surface.

    Parameters
    ----------
    V : (n, 3) float64
    F : (m, 3) int64
    rng : numpy.random.Generator
    count : int
        Number of blobs (each a separate connected component).
    size, gap : (float, float)
        Ranges of the blob radius and of its distance from a surface vertex, both as
        fractions of the bounding-box diagonal; blobs go outwards from the centroid.

    Returns
    -------
    V : (n + 42 count, 3) float64
    F : (m + 80 count, 3) int64
    """
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=1)
    Vi, Fi = np.asarray(ico.vertices, dtype=np.float64), np.asarray(ico.faces, dtype=np.int64)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    c = V.mean(axis=0)
    anchors = V[rng.choice(len(V), size=int(count), replace=False)]
    out = anchors - c
    out /= np.linalg.norm(out, axis=1, keepdims=True) + 1e-12
    r = rng.uniform(size[0], size[1], int(count)) * diag
    g = rng.uniform(gap[0], gap[1], int(count)) * diag
    centres = anchors + out * (g + r)[:, None]
    blobs = (Vi[None] * r[:, None, None] + centres[:, None]).reshape(-1, 3)
    faces = (Fi[None] + len(V) + len(Vi) * np.arange(int(count))[:, None, None]).reshape(-1, 3)
    return np.concatenate([V, blobs]), np.concatenate([F, faces])
