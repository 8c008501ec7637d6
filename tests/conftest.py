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


@pytest.fixture
def no_other_threads(monkeypatch):
    """Threads left by earlier tests (a Dask client, pools) make beside refuse to fork; these
    tests check the forked path itself, so they ignore them (the refusal has its own test)."""
    import geoshape.parallel

    monkeypatch.setattr(geoshape.parallel, "_other_threads", lambda: [])
