"""Shared test helpers: seeded RNGs, small generated meshes, and data-bound skipping."""

from __future__ import annotations

import numpy as np
import pytest


def shared_dataset(name: str):
    """Folder of benchmark set ``name`` or skip the test with the reason it is absent."""
    from geoshape.io.datasets import dataset_dir

    folder = dataset_dir(name, required=False)
    if folder is None:
        pytest.skip(
            f"benchmark data {name!r} not found: set GEOSHAPE_DATA or put ../shared/data beside the repo"
        )
    return folder


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def icosphere(subdivisions: int = 3, radius: float = 1.0):
    """A unit icosphere ``(V, F)`` (trimesh's construction, vertices on the sphere)."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def grid_mesh(nx: int = 10, ny: int = 10, size: float = 1.0):
    """A flat triangulated square grid in the z = 0 plane, ``(V, F)``."""
    xs, ys = np.meshgrid(np.linspace(0, size, nx), np.linspace(0, size, ny), indexing="ij")
    V = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(nx * ny)])
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return V, F.astype(np.int64)


def wobbly_contours(n: int = 96) -> list:
    """Four distinct star-like closed contours ``(n, 2)``, counter-clockwise."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    out = []
    for a, b in ((0.3, 0.15), (0.25, 0.2), (0.1, 0.4), (0.45, 0.0)):
        r = 1 + a * np.cos(3 * t) + b * np.sin(2 * t)
        out.append(np.c_[r * np.cos(t), r * np.sin(t)])
    return out


def similar(P, theta: float = 0.9, scale: float = 2.5, shift=(4.0, -7.0)):
    """``P (N, 2)`` rotated by ``theta``, scaled and shifted."""
    R = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    return scale * P @ R.T + np.asarray(shift)


@pytest.fixture
def no_other_threads(monkeypatch):
    """Threads left by earlier tests (a Dask client, pools) make beside refuse to fork; these
    tests check the forked path itself, so they ignore them (the refusal has its own test)."""
    import geoshape.parallel

    monkeypatch.setattr(geoshape.parallel, "_other_threads", lambda: [])
