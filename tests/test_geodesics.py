"""Geodesic backends, the structural graph and max-min sampling.

Tolerances per backend (relative error against the analytic distance, for distances
above a few edge lengths):

- ``exact``: flat grid 1e-9 (exact on a plane), unit icosphere (4 subdivisions) 2e-3
  (the polyhedron is not the sphere).
- ``heat``: max 8 % (near the boundary of the grid), mean 3 %.
- ``graph``: never shorter than the straight line on the plane; max 45 % (a path along
  grid edges where no diagonal exists is up to sqrt(2) too long), mean 12 %.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh, icosphere
from scipy.sparse.csgraph import connected_components

from geoshape.errors import GeoshapeError, InvalidMeshError, InvalidOptionError, ResourceLimitError
from geoshape.geometry.geodesics import (
    GeodesicSolver,
    all_pairs_geodesics,
    geodesic_distances,
)
from geoshape.geometry.graph import bridging_edges, structural_graph
from geoshape.geometry.mesh import edge_graph, unique_edges, vertex_components
from geoshape.geometry.sampling import farthest_point_sampling, geodesic_voronoi_sampling

TOL = {  # method: (max relative, mean relative)
    "exact": (2e-3, 1e-3),
    "heat": (0.08, 0.03),
    "graph": (0.45, 0.12),
}


def _rel_errors(D, true, floor):
    mask = true > floor
    return np.abs(D - true)[mask] / true[mask]


@pytest.mark.parametrize("method", ["graph", "heat", "exact"])
def test_flat_grid_distances(method):
    V, F = grid_mesh(21, 21)
    src = [0, 220]
    true = np.linalg.norm(V[src][:, None] - V[None], axis=2)
    D = geodesic_distances(V, F, src, method)
    assert D.shape == (2, len(V))
    assert np.allclose(D[[0, 1], src], 0.0, atol=1e-12)
    rel = _rel_errors(D, true, 0.2)
    max_tol, mean_tol = TOL[method]
    if method == "exact":
        max_tol = mean_tol = 1e-9
    assert rel.max() <= max_tol and rel.mean() <= mean_tol
    if method == "graph":
        assert np.all(D >= true - 1e-12)


@pytest.mark.parametrize("method", ["graph", "heat", "exact"])
def test_sphere_great_circle(method):
    V, F = icosphere(4)
    src = [0, 100]
    true = np.arccos(np.clip(V[src] @ V.T, -1.0, 1.0))
    D = GeodesicSolver(V, F, method).distances(src)
    rel = _rel_errors(D, true, 0.3)
    max_tol, mean_tol = TOL[method]
    assert rel.max() <= max_tol and rel.mean() <= mean_tol


def _two_parts():
    """Two unit grids in z = 0 whose unique nearest pair is (1, 1) – (1.5, 1.5)."""
    V1, F1 = grid_mesh(6, 6)
    V2, F2 = grid_mesh(6, 6)
    V2 = V2 + [1.5, 1.5, 0.0]
    return np.vstack([V1, V2]), np.vstack([F1, F2 + len(V1)])


def _soup(V, F):
    """Unshare every vertex: each triangle becomes its own component."""
    return V[F.ravel()].copy(), np.arange(3 * len(F)).reshape(-1, 3)


def test_mesh_edges_and_components():
    E = unique_edges(np.array([[0, 1, 2], [2, 1, 3], [0, 0, 1]]))
    assert E.tolist() == [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
    n_comp, labels = vertex_components(5, np.array([[0, 1, 2]]))
    assert n_comp == 3 and labels[0] == labels[1] == labels[2] != labels[3] != labels[4]
    assert edge_graph([[0, 0, 0], [3, 4, 0], [0, 1, 0]], [[0, 1, 2]])[0, 1] == pytest.approx(5.0)


def test_structural_graph_connected_mesh_adds_nothing():
    V, F = icosphere(2)
    assert len(bridging_edges(V, F)) == 0
    G = structural_graph(V, F)
    assert (G != edge_graph(V, F)).nnz == 0


@pytest.mark.parametrize("p", [1, 2])
def test_structural_graph_two_parts_only_bridges(p):
    V, F = _two_parts()
    B = bridging_edges(V, F, p)
    _, labels = vertex_components(len(V), F)
    assert len(B) >= 1 and np.all(labels[B[:, 0]] != labels[B[:, 1]])
    G = structural_graph(V, F, p)
    assert connected_components(G)[0] == 1
    # all mesh edges kept, the only extra edges are the bridges
    mesh = set(map(tuple, unique_edges(F)))
    r, c = G.nonzero()
    extra = {(a, b) for a, b in zip(r.tolist(), c.tolist(), strict=True) if a < b} - mesh
    assert extra == set(map(tuple, B.tolist()))
    if p == 1:  # two clusters: the EMST crosses once, at the unique nearest pair
        assert B.tolist() == [[35, 36]]


@pytest.mark.parametrize("p", [1, 2])
def test_structural_graph_triangle_soup(p):
    V, F = _soup(*icosphere(1))
    n_comp, labels = vertex_components(len(V), F)
    assert n_comp == len(F)
    G = structural_graph(V, F, p)
    assert connected_components(G)[0] == 1
    B = bridging_edges(V, F, p)
    assert np.all(labels[B[:, 0]] != labels[B[:, 1]])
    assert G.nnz == 2 * (len(unique_edges(F)) + len(B))
    # coincident vertices of a soup are linked by (near) zero-length edges
    D = geodesic_distances(V, F, [0])
    assert np.isfinite(D).all()


def test_point_cloud_graph():
    rng = np.random.default_rng(0)
    V = rng.standard_normal((300, 3))
    G = structural_graph(V, np.zeros((0, 3), dtype=int))
    assert connected_components(G)[0] == 1
    assert G.nnz == 2 * (len(V) - 1)  # p = 1: the EMST itself


def test_p_zero_on_disconnected_mesh_is_refused():
    V, F = _two_parts()
    with pytest.raises(InvalidOptionError, match="p = 0"):
        structural_graph(V, F, p=0)
    Vs, Fs = icosphere(1)
    assert connected_components(structural_graph(Vs, Fs, p=0))[0] == 1


@pytest.mark.parametrize("method", ["heat", "exact"])
def test_surface_backends_combine_with_bridges(method):
    V, F = _two_parts()
    solver = GeodesicSolver(V, F, method)
    assert solver.method == method
    D = solver.distances([0])[0]
    # part 1: straight lines; part 2: (0,0) → (1,1) → bridge → (1.5,1.5) → v
    corner, far = np.array([1.0, 1.0, 0.0]), np.array([1.5, 1.5, 0.0])
    expect = np.where(
        np.arange(len(V)) < 36,
        np.linalg.norm(V, axis=1),
        np.linalg.norm(corner) + np.linalg.norm(far - corner) + np.linalg.norm(V - far, axis=1),
    )
    tol = 1e-9 if method == "exact" else 0.05 * expect.max()
    assert np.abs(D - expect).max() <= tol


def test_surface_backend_falls_back_on_soup():
    V, F = _soup(*icosphere(2))
    with pytest.warns(UserWarning, match="structural graph"):
        solver = GeodesicSolver(V, F, "heat", max_portals=16)
    assert solver.method == "graph"
    assert np.isfinite(solver.distances([3])).all()


def test_all_pairs_symmetric_and_guarded():
    V, F = icosphere(1)
    D = all_pairs_geodesics(V, F, "heat")
    assert D.shape == (len(V), len(V)) and np.allclose(D, D.T)
    Dg = all_pairs_geodesics(V, F, "graph")
    assert np.allclose(Dg, Dg.T) and np.allclose(np.diag(Dg), 0)
    with pytest.raises(ResourceLimitError, match="Nystrom"):
        all_pairs_geodesics(V, F, max_bytes=1000)


def test_bad_input():
    V, F = icosphere(1)
    Vn = V.copy()
    Vn[3, 1] = np.nan
    with pytest.raises(InvalidMeshError, match="NaN"):
        geodesic_distances(Vn, F, [0])
    with pytest.raises(InvalidMeshError, match="face indices"):
        geodesic_distances(V, F + len(V), [0])
    with pytest.raises(InvalidOptionError, match="'graph'"):
        geodesic_distances(V, F, [0], method="fast")
    with pytest.raises(InvalidOptionError, match="sources"):
        geodesic_distances(V, F, [len(V)])
    with pytest.raises(GeoshapeError):
        farthest_point_sampling(V, F, len(V) + 1)


def test_farthest_point_sampling():
    # an elongated box: the first sample (after farthest jumps) lies at an end
    import trimesh

    box = trimesh.creation.box(extents=[10.0, 1.0, 1.0])
    box = box.subdivide().subdivide()
    V, F = np.asarray(box.vertices), np.asarray(box.faces)
    samples, D = farthest_point_sampling(V, F, 6, seed=3)
    assert len(set(samples.tolist())) == 6
    assert abs(V[samples[0], 0]) == pytest.approx(5.0)
    assert abs(V[samples[1], 0]) == pytest.approx(5.0) and V[samples[1], 0] == -V[samples[0], 0]
    assert np.allclose(D, geodesic_distances(V, F, samples))
    again, _ = farthest_point_sampling(V, F, 6, seed=3)
    assert np.array_equal(samples, again)


def test_geodesic_voronoi_sampling_matches_farthest_point_sampling():
    from geoshape.geometry.graph import structural_graph

    V, F = bumpy_sphere_for_sampling()
    samples, D = farthest_point_sampling(V, F, 40, seed=5)
    fast, owner, dist = geodesic_voronoi_sampling(structural_graph(V, F, 1), 40, seed=5)
    assert np.array_equal(fast, samples)
    assert np.allclose(dist, D.min(axis=0))
    assert np.allclose(D[owner, np.arange(len(V))], D.min(axis=0))
    with pytest.raises(InvalidOptionError, match="n_samples"):
        geodesic_voronoi_sampling(structural_graph(V, F, 1), 0)


def bumpy_sphere_for_sampling():
    import trimesh

    m = trimesh.creation.icosphere(3)
    V = m.vertices * (1.0 + 0.2 * np.sin(3 * m.vertices[:, :1]))
    return V, m.faces
