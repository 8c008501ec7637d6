"""Mean curvature of a mesh (geoshape.geometry.curvature) and the curvature disagreement of a
map (geoshape.correspondence.pipeline): known answers and invariances."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.geometry.curvature import mean_curvature
from tests.conftest import icosphere


def torus(R: float = 3.0, r: float = 1.0, nu: int = 120, nv: int = 48):
    """A torus of radii ``R`` > ``r`` about the z axis, ``(V, F)``; row ``i * nv + j`` is at angle
    ``2π j / nv`` round the tube, 0 on the outer equator."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False),
                       np.linspace(0, 2 * np.pi, nv, endpoint=False), indexing="ij")
    V = np.column_stack([((R + r * np.cos(v)) * np.cos(u)).ravel(),
                         ((R + r * np.cos(v)) * np.sin(u)).ravel(), (r * np.sin(v)).ravel()])
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b = idx, np.roll(idx, -1, 0)
    c, d = np.roll(b, -1, 1), np.roll(idx, -1, 1)
    F = np.concatenate([np.column_stack([a.ravel(), b.ravel(), c.ravel()]),
                        np.column_stack([a.ravel(), c.ravel(), d.ravel()])])
    return V, F


@pytest.mark.parametrize("radius", [0.01, 1.0, 300.0])
def test_a_sphere_has_mean_curvature_times_root_area_two_root_pi(radius):
    V, F = icosphere(4, radius)
    H = mean_curvature(V, F)
    assert np.median(H) == pytest.approx(2 * np.sqrt(np.pi), rel=2e-3)
    # the 12 vertices of valence 5 (the icosahedron's corners) come out 15 % high, their
    # neighbours a little: 95 % of the vertices within 1 %
    assert np.mean(np.abs(H / (2 * np.sqrt(np.pi)) - 1) < 0.01) > 0.95


def test_winding_does_not_change_the_sign():
    V, F = icosphere(3)
    assert np.allclose(mean_curvature(V, F[:, ::-1]), mean_curvature(V, F))


def test_a_torus_is_convex_outside_and_saddle_shaped_inside():
    """H = (R + 2 r cos v) / (2 r (R + r cos v)): 5/8 on the outer equator, 1/4 on the inner
    one for R = 3, r = 1; with R = 1.5 the inner equator is a saddle, H = −1/2."""
    V, F = torus(3.0, 1.0)
    H = mean_curvature(V, F).reshape(120, 48) / np.sqrt(4 * np.pi**2 * 3.0)
    assert H[:, 0].mean() == pytest.approx(5 / 8, rel=0.01)
    assert H[:, 24].mean() == pytest.approx(1 / 4, rel=0.02)
    V, F = torus(1.5, 1.0)
    H = mean_curvature(V, F).reshape(120, 48) / np.sqrt(4 * np.pi**2 * 1.5)
    assert H[:, 24].mean() == pytest.approx((1.5 - 2) / (2 * (1.5 - 1)), rel=0.03)  # −1/2


def test_curvature_disagreement_sees_a_half_turn_but_not_a_mirror():
    """A sphere with a bump on its front (+x): the identity carries the smoothed curvature
    field exactly; the half-turn about the vertical axis (front↔back composed with left↔right,
    orientation kept) puts the bump on the back and disagrees; the left↔right mirror (y → −y)
    keeps the bump where it is, so curvature cannot see it (the orientation share does)."""
    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.correspondence.pipeline import curvature_disagreement
    from geoshape.geometry.knn import nearest

    V, F = icosphere(4)
    V = V * (1 + 0.4 * np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2 + V[:, 2] ** 2) / 0.1))[:, None]
    m = PreparedMesh(V, F)
    h = m.curvature_field(40)
    maps = {"identity": np.arange(len(V)),
            "half-turn": nearest(V, V * [-1.0, -1.0, 1.0])[1],
            "mirror": nearest(V, V * [1.0, -1.0, 1.0])[1]}
    score = {name: curvature_disagreement(h, h[p2p], h) for name, p2p in maps.items()}
    assert score["identity"] == 0.0
    assert score["mirror"] < 0.01
    assert score["half-turn"] > 0.3  # the bump on the back: a third of the way to random pairs
    # the field is cached per basis size, and has no unit: scaling the mesh changes nothing
    assert m.curvature_field(40) is h
    assert np.allclose(PreparedMesh(V * 7.0, F).curvature_field(40), h, atol=1e-6 * np.abs(h).max())


def _bumped_sphere():
    V, F = icosphere(4)
    return V * (1 + 0.4 * np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2 + V[:, 2] ** 2) / 0.1))[:, None], F


@pytest.mark.parametrize("large", [False, True])
def test_measure_distortion_fills_the_curvature_disagreement_on_samples(large):
    """The pipeline reads the field at mesh 1's refinement samples and at their images (a
    per-vertex map, or in large-mesh mode a map aligned with the samples): the same value
    either way, 0 for the identity, more for the half-turn; a candidate already measured is
    left alone."""
    from types import SimpleNamespace

    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.correspondence.pipeline import Candidate, GeoshapeOptions, measure_distortion
    from geoshape.geometry.knn import nearest

    V, F = _bumped_sphere()
    m = PreparedMesh(V, F)
    samples = m.samples(400)
    ctx = SimpleNamespace(m1=m, m2=m, s1=samples, s2=samples, lb_k=40, large=large)
    half_turn_ids = nearest(V[samples], V * [-1.0, -1.0, 1.0])[1]
    half_turn_ids = samples[half_turn_ids]  # every vertex → the sample nearest its half-turn
    identity_ids = samples[nearest(V[samples], V)[1]]
    rows = slice(None) if not large else samples
    cands = [Candidate(refined_map=ids[rows], distortion=1.0) for ids in (identity_ids, half_turn_ids)]
    done = Candidate(refined_map=half_turn_ids[rows], distortion=1.0, curvature_disagreement=0.5)
    timings = {}
    measure_distortion(ctx, [*cands, done], GeoshapeOptions(), timings)
    identity, half_turn = cands
    assert identity.curvature_disagreement == 0.0 and half_turn.curvature_disagreement > 0.3
    assert done.curvature_disagreement == 0.5 and "curvature" in timings
    if large:  # the value a per-vertex map gives
        per_vertex = Candidate(refined_map=half_turn_ids, distortion=1.0)
        per_vertex_ctx = SimpleNamespace(**{**vars(ctx), "large": False})
        measure_distortion(per_vertex_ctx, [per_vertex], GeoshapeOptions(), {})
        assert half_turn.curvature_disagreement == pytest.approx(per_vertex.curvature_disagreement)


def test_a_flat_field_ranks_no_map_above_another():
    """At one eigenfunction the field is a constant: every map scores 1 (the factor then
    changes no decision) instead of a ratio of rounding errors."""
    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.correspondence.pipeline import curvature_disagreement

    V, F = _bumped_sphere()
    h = PreparedMesh(V, F).curvature_field(1)
    rng = np.random.default_rng(0)
    assert {curvature_disagreement(h, h[rng.permutation(len(h))], h) for _ in range(3)} == {1.0}
    assert curvature_disagreement(h, np.full_like(h, np.nan), h) == 1.0


def test_a_prepared_mesh_builds_its_laplacian_once_for_the_basis_and_the_curvature(monkeypatch):
    import robust_laplacian

    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.spectral.laplacian import laplacian_basis

    V, F = icosphere(3)
    builds = []
    real = robust_laplacian.mesh_laplacian
    monkeypatch.setattr(robust_laplacian, "mesh_laplacian", lambda *a: builds.append(1) or real(*a))
    m = PreparedMesh(V, F)
    field = m.curvature_field(10)
    basis = m.laplacian(10)
    assert len(builds) == 1
    # the shared build changes nothing: the same basis and field as built apart
    alone = laplacian_basis(V, F, 10)
    assert np.allclose(basis.evals, alone.evals) and np.allclose(basis.evecs, alone.evecs)
    H = mean_curvature(V, F)
    assert np.allclose(field, alone.evecs @ (alone.evecs.T @ (alone.mass * H)))


def test_laplacian_matrices_of_another_mesh_are_rejected():
    from geoshape.errors import InvalidOptionError
    from geoshape.geometry.mesh import laplacian_matrices
    from geoshape.spectral.laplacian import laplacian_basis

    V, F = icosphere(3)
    other = laplacian_matrices(*icosphere(2))
    with pytest.raises(InvalidOptionError, match="Laplacian matrices of shape"):
        laplacian_basis(V, F, 5, matrices=other)
    with pytest.raises(InvalidOptionError, match="Laplacian matrices of shape"):
        mean_curvature(V, F, matrices=other)


def test_ranked_curvature_compares_kind_not_amount():
    """By rank, a target that curves like the source but by another amount (any increasing
    transformation of its field) carries it exactly, while by value it pays for the amount; the
    half-turn is still seen either way, and a flat field still ranks no map above another
    (ranks must not turn its rounding noise into a field)."""
    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.correspondence.pipeline import curvature_disagreement, within_quantiles
    from geoshape.geometry.knn import nearest

    V, F = _bumped_sphere()
    m = PreparedMesh(V, F)
    h = m.curvature_field(40)
    heavier = np.sinh(3.0 * h) + 2.0  # same order of the points, other amounts
    half_turn = nearest(V, V * [-1.0, -1.0, 1.0])[1]
    identity = np.arange(len(V))
    assert curvature_disagreement(h, heavier[identity], heavier) > 0.05
    # (up to ties the transformation's rounding breaks)
    assert curvature_disagreement(h, heavier[identity], heavier, ranks=True) < 1e-6
    by_rank = curvature_disagreement(h, heavier[half_turn], heavier, ranks=True)
    same_kind = curvature_disagreement(h, h[half_turn], h, ranks=True)
    assert by_rank > 0.2 and by_rank == pytest.approx(same_kind, abs=1e-6)
    flat = m.curvature_field(1)
    rng = np.random.default_rng(0)
    assert {curvature_disagreement(flat, flat[rng.permutation(len(h))], flat, ranks=True)
            for _ in range(3)} == {1.0}
    assert curvature_disagreement(h, np.full_like(h, np.nan), h, ranks=True) == 1.0
    q = within_quantiles(h, h)
    assert q.min() > 0 and q.max() < 1 and abs(q.mean() - 0.5) < 1e-12  # uniform on itself


def test_screening_measures_the_coarse_maps_curvature_disagreement():
    """Screening reads the field at mesh 1's screening samples and their coarse images: 0 for
    the identity, more for the half-turn, so the screening score refines the right map first
    where stress and energy tie."""
    from types import SimpleNamespace

    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.correspondence.pipeline import (
        Candidate,
        GeoshapeOptions,
        measure_coarse_distortion,
        screening_score,
    )
    from geoshape.geometry.knn import nearest

    V, F = _bumped_sphere()
    m = PreparedMesh(V, F)
    samples = m.samples(300)
    ctx = SimpleNamespace(m1=m, m2=m, c1=samples, c2=samples, s1=samples, s2=samples, lb_k=40, large=False)
    identity = samples[nearest(V[samples], V)[1]]
    half_turn = samples[nearest(V[samples], V * [-1.0, -1.0, 1.0])[1]]
    cands = [Candidate(coarse_map=ids, zoomout_energy=0.1) for ids in (identity, half_turn)]
    measure_coarse_distortion(ctx, cands, GeoshapeOptions())
    right, turned = cands
    assert right.coarse_curvature == 0.0 and turned.coarse_curvature > 0.3
    assert right.coarse_distortion == pytest.approx(0.0, abs=1e-9)
    assert screening_score(turned) > 0.0 == screening_score(right)
