"""Per-mesh primitives of geoshape/geometry/mesh.py on shapes with known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geoshape.geometry.geodesics import GeodesicSolver
from geoshape.geometry.mesh import (
    ZERO_LENGTH_EPS,
    edge_graph,
    face_areas,
    face_normals,
    undirected_edges,
    unique_edges,
    vertex_areas,
    vertex_components,
)
from geoshape.geometry.sampling import euclidean_farthest_point_sampling

TRIANGLE_V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
TRIANGLE_F = np.array([[0, 1, 2]])
TETRA_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])


def icosphere(subdivisions: int):
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def unit_cube():
    V = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return V, F


def test_unit_right_triangle():
    assert face_areas(TRIANGLE_V, TRIANGLE_F).tolist() == [0.5]
    np.testing.assert_array_equal(face_normals(TRIANGLE_V, TRIANGLE_F), [[0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(face_normals(TRIANGLE_V, TRIANGLE_F[:, ::-1]), [[0.0, 0.0, -1.0]])
    np.testing.assert_array_equal(face_normals(2 * TRIANGLE_V, TRIANGLE_F, unit=False), [[0, 0, 4.0]])
    np.testing.assert_allclose(vertex_areas(TRIANGLE_V, TRIANGLE_F), [1 / 6] * 3)


def test_cube_has_twelve_faces_of_total_area_six():
    V, F = unit_cube()
    areas = face_areas(V, F)
    assert len(areas) == 12
    assert areas.sum() == pytest.approx(6.0)
    np.testing.assert_allclose(areas, 0.5)
    assert vertex_areas(V, F).sum() == pytest.approx(6.0)
    N = face_normals(V, F)
    np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0)
    assert set(map(tuple, np.abs(N).round(12))) == {(1, 0, 0), (0, 1, 0), (0, 0, 1)}
    assert len(unique_edges(F)) == 18  # 12 cube edges + 6 face diagonals
    assert vertex_components(len(V), F)[0] == 1


def test_degenerate_face_has_zero_area_and_zero_normal():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    F = np.array([[0, 1, 2], [0, 0, 1]])
    assert face_areas(V, F).tolist() == [0.0, 0.0]
    assert np.array_equal(face_normals(V, F), np.zeros((2, 3)))
    assert unique_edges(F).tolist() == [[0, 1], [0, 2], [1, 2]]  # no self-loop


def test_tetrahedron_has_six_unique_edges_each_in_two_faces():
    edges, counts = unique_edges(TETRA_F, return_counts=True)
    assert edges.tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    assert counts.tolist() == [2] * 6
    assert edges.dtype == np.int64
    assert unique_edges(np.zeros((0, 3), int)).shape == (0, 2)
    e, c = unique_edges(np.zeros((0, 3), int), return_counts=True)
    assert e.shape == (0, 2) and c.shape == (0,)
    assert undirected_edges(np.array([[3, 1], [1, 3], [2, 2], [0, 4]])).tolist() == [[0, 4], [1, 3]]


def test_two_disjoint_triangles_are_two_components():
    V = np.vstack([TRIANGLE_V, TRIANGLE_V + 5.0, [[9.0, 9.0, 9.0]]])
    F = np.array([[0, 1, 2], [3, 4, 5]])
    n, labels = vertex_components(len(V), F)
    assert n == 3  # the unreferenced vertex is a component of its own
    assert labels.tolist() == [0, 0, 0, 1, 1, 1, 2]
    assert vertex_components(len(V) - 1, F)[0] == 2
    assert vertex_components(4, np.zeros((0, 3), int))[0] == 4


def test_edge_graph_weights_and_zero_length_edges():
    V, F = icosphere(1)
    G = edge_graph(V, F)
    E = unique_edges(F)
    assert G.nnz == 2 * len(E)
    assert (G != G.T).nnz == 0
    np.testing.assert_allclose(G[E[:, 0], E[:, 1]].A1, np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1))
    # a duplicate vertex: the edge of length zero stays an edge, tiny or exactly 0
    Vd = np.vstack([TRIANGLE_V, TRIANGLE_V[:1]])
    Fd = np.array([[0, 1, 2], [3, 1, 0]])
    diag = np.sqrt(2.0)
    assert edge_graph(Vd, Fd)[0, 3] == pytest.approx(ZERO_LENGTH_EPS * diag)
    raw = edge_graph(Vd, Fd, raw_lengths=True)
    assert raw.nnz == edge_graph(Vd, Fd).nnz and raw[0, 3] == 0.0


def test_raw_geodesic_solver_keeps_components_apart():
    V, F = icosphere(1)
    V2 = np.vstack([V, V + [5.0, 0, 0]])
    F2 = np.vstack([F, F + len(V)])
    bridged = GeodesicSolver(V2, F2, "graph").distances([0])[0]
    raw = GeodesicSolver(V2, F2, "graph", raw=True).distances([0])[0]
    assert np.isfinite(bridged).all()
    assert np.isinf(raw[len(V):]).all()
    np.testing.assert_array_equal(raw[: len(V)], GeodesicSolver(V, F, "graph").distances([0])[0])
    heat = GeodesicSolver(V, F, "heat", raw=True).distances([3])[0]
    clipped = GeodesicSolver(V, F, "heat").distances([3])[0]
    others = np.arange(len(V)) != 3
    np.testing.assert_array_equal(np.maximum(heat, 0.0)[others], clipped[others])


def test_euclidean_farthest_point_sampling():
    X = np.array([[0.0, 0.0], [1.0, 0.0], [10.0, 0.0], [4.0, 3.0], [9.0, 0.5]])
    s = euclidean_farthest_point_sampling(X, 3, seed=0)
    assert len(set(s.tolist())) == 3 and s.dtype == np.int64
    assert set(s[:2].tolist()) == {0, 2}  # the two extremities come first
    np.testing.assert_array_equal(euclidean_farthest_point_sampling(X, 9), np.arange(5))
    # invariant to permuting and sign-flipping the columns
    np.testing.assert_array_equal(euclidean_farthest_point_sampling(-X[:, ::-1], 3, seed=0), s)
