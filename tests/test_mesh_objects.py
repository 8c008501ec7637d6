"""Library entry points take other libraries' mesh objects and give the same results as arrays."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geoshape.correspondence.mesh_matching import correspond
from geoshape.errors import InvalidMeshError
from geoshape.spectral.embedding import spectral_embedding


def _pair():
    m = trimesh.creation.icosphere(subdivisions=2)
    V1 = np.asarray(m.vertices) * [1.0, 0.8, 0.6]
    rng = np.random.default_rng(0)
    perm = rng.permutation(len(V1))
    V2 = V1[perm] @ np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    inv = np.argsort(perm)
    return V1, np.asarray(m.faces), V2, inv[np.asarray(m.faces)]


def _as(kind, V, F):
    if kind == "tuple":
        return (V, F)
    if kind == "trimesh":
        return trimesh.Trimesh(V, F, process=False)
    if kind == "open3d":
        o3d = pytest.importorskip("open3d", reason="the open3d extra is not installed")
        return o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F))
    import pymeshlab

    return pymeshlab.Mesh(vertex_matrix=V, face_matrix=F)


@pytest.mark.parametrize("kind", ["tuple", "trimesh", "open3d", "pymeshlab"])
def test_correspond_takes_mesh_objects_and_gives_the_array_map(kind):
    V1, F1, V2, F2 = _pair()
    expected = correspond(V1, F1, V2, F2, method="rigid-icp").p2p_12
    got = correspond(_as(kind, V1, F1), _as(kind, V2, F2), method="rigid-icp").p2p_12
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("kind", ["tuple", "trimesh", "open3d", "pymeshlab"])
def test_spectral_embedding_takes_mesh_objects(kind):
    V, F, _, _ = _pair()
    expected = spectral_embedding(V, F, k=4).coords
    np.testing.assert_allclose(spectral_embedding(_as(kind, V, F), k=4).coords, expected, atol=1e-12)


def test_an_unknown_object_is_named_in_the_error():
    V1, F1, _, _ = _pair()
    with pytest.raises(InvalidMeshError, match="source mesh: expected .V, F. arrays, a trimesh.*got dict"):
        correspond({"v": 1}, trimesh.Trimesh(V1, F1, process=False))
