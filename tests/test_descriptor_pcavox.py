"""pcavox: PCA-aligned occupancy grid (geoshape.retrieval.descriptors.pcavox)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import trimesh

from geoshape.errors import InvalidOptionError
from geoshape.metrics.retrieval import retrieval_metrics
from geoshape.retrieval.descriptors import compute_descriptor, descriptor_distance_matrix, get_descriptor
from geoshape.retrieval.descriptors.pcavox import (
    _symmetries,
    pcavox_descriptor,
    pcavox_distance_matrix,
    scaled_principal_axes,
)


def _rotation(seed: int) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=seed).as_matrix()


def _table(rng) -> trimesh.Trimesh:
    """A top on four legs, proportions drawn at random (separate, intersecting shells)."""
    w, d, h = rng.uniform(1.0, 2.0), rng.uniform(0.6, 1.1), rng.uniform(0.6, 0.9)
    t, s = rng.uniform(0.04, 0.1), rng.uniform(0.04, 0.08)
    parts = [trimesh.creation.box((w, t, d), trimesh.transformations.translation_matrix((0, h, 0)))]
    for x in (-1, 1):
        for z in (-1, 1):
            T = trimesh.transformations.translation_matrix((x * (w / 2 - s), h / 2, z * (d / 2 - s)))
            parts.append(trimesh.creation.box((s, h, s), T))
    return trimesh.util.concatenate(parts)


def _ring(rng) -> trimesh.Trimesh:
    r = rng.uniform(0.3, 0.6)
    inner, height = r * rng.uniform(0.2, 0.5), r * rng.uniform(0.2, 0.5)
    return trimesh.creation.annulus(r_min=inner, r_max=r, height=height)


def _bottle(rng) -> trimesh.Trimesh:
    R, H = rng.uniform(0.15, 0.3), rng.uniform(0.5, 1.0)
    body = trimesh.creation.cylinder(radius=R, height=H)
    neck = trimesh.creation.cylinder(radius=R * rng.uniform(0.25, 0.45), height=H * 0.4,
                                     transform=trimesh.transformations.translation_matrix((0, 0, 0.65 * H)))
    return trimesh.util.concatenate([body, neck])


def _moved(V, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.5, 2.0) * V @ _rotation(seed).T + rng.uniform(-3, 3, 3)


def test_registered_with_its_metric():
    spec = get_descriptor("pcavox")
    assert spec.metric == "pcavox" and spec.domain == "original"
    assert set(spec.invariances) == {"translation", "rotation", "scale"}
    m = trimesh.creation.icosphere(2)
    d = compute_descriptor(m.vertices, m.faces, "pcavox")
    assert d.shape == (16**3 + 3,)
    assert np.isclose((d[:-3] ** 2).sum(), 1.0)  # square root of a distribution
    assert d[-3] == 1.0 and 0 < d[-1] <= d[-2] <= 1.0


def test_invariant_to_rotation_translation_scale_and_reflection():
    rng = np.random.default_rng(0)
    a, b = _table(rng), _bottle(rng)
    Va = np.asarray(a.vertices)
    X = [pcavox_descriptor(Va, a.faces)]
    for seed in (1, 2, 3):
        X.append(pcavox_descriptor(_moved(Va, seed), a.faces))
    mirrored = Va * np.array([-1.0, 1.0, 1.0])
    X.append(pcavox_descriptor(mirrored, a.faces))  # same faces: the mirrored samples
    X.append(pcavox_descriptor(b.vertices, b.faces))
    D = pcavox_distance_matrix(np.array(X))
    # the same area-weighted samples, transformed: equal grids up to a cube symmetry (and
    # rounding at cell borders)
    assert D[0, 1:5].max() <= 0.02 * D[0, 5], D[0]


def test_symmetries_are_the_cube_group_acting_on_cells():
    axes, cells = _symmetries(4)
    assert len(axes) == 48 and len({c.tobytes() for c in cells}) == 48
    for c in cells:  # each is a permutation of the 64 cells
        assert np.array_equal(np.sort(c), np.arange(64))
    # grid of points transformed by a signed axis permutation = permuted grid
    rng = np.random.default_rng(1)
    Y = rng.uniform(-1, 1, (500, 3)) * [1.0, 0.7, 0.4]

    def grid(P):
        idx = np.minimum(((P + 1) * 0.5 * 4).astype(int), 3)
        return np.bincount((idx[:, 0] * 4 + idx[:, 1]) * 4 + idx[:, 2], minlength=64)

    seen = set()
    for p, c in zip(axes, cells, strict=True):
        # which signs does this cell permutation carry? the one whose transform it matches
        match = []
        for s in itertools.product((1.0, -1.0), repeat=3):
            S = np.zeros((3, 3))
            S[np.arange(3), p] = s
            if np.array_equal(grid(Y @ S.T), grid(Y)[c]):
                match.append(s)
        assert len(match) == 1
        seen.add((tuple(p), match[0]))
    assert len(seen) == 48


def test_distance_symmetric_zero_diagonal_and_rejects_bad_shapes():
    rng = np.random.default_rng(2)
    X = np.array([pcavox_descriptor(m.vertices, m.faces, resolution=8)
                  for m in (_table(rng), _ring(rng), _bottle(rng), _table(rng))])
    D = descriptor_distance_matrix("pcavox", X)
    assert np.allclose(D, D.T) and np.allclose(np.diag(D), 0)
    # a shape to (a copy of) itself: exactly 0, not the ~1e-8 of |a|² + |b|² − 2 a·b
    # (the index ranks a stored copy of the query first with distance < 1e-9)
    R = pcavox_distance_matrix(X[:2], X.copy())
    assert R[0, 0] == 0.0 and R[1, 1] == 0.0 and R[0, 1] > 0
    np.testing.assert_allclose(R, pcavox_distance_matrix(X)[:2], rtol=1e-9)
    with pytest.raises(InvalidOptionError):
        pcavox_distance_matrix(np.zeros((2, 10)))
    with pytest.raises(InvalidOptionError):
        pcavox_distance_matrix(X, np.zeros((2, 16**3 + 3)))
    with pytest.raises(InvalidOptionError):
        pcavox_descriptor(np.zeros((3, 3)), np.array([[0, 1, 2]]))


def test_axis_swaps_only_for_near_equal_spreads():
    """A long bar and a flat plate: swapping their principal axes is not tried."""
    bar = trimesh.creation.box((3.0, 0.6, 0.3))
    plate = trimesh.creation.box((3.0, 2.8, 0.3))
    X = np.array([pcavox_descriptor(m.vertices, m.faces, resolution=8) for m in (bar, plate)])
    restricted = pcavox_distance_matrix(X)[0, 1]
    everything = pcavox_distance_matrix(X, degenerate=0.0)[0, 1]
    signs_only = pcavox_distance_matrix(X, degenerate=1.0)[0, 1]
    assert everything <= restricted <= signs_only
    # the plate's two long axes are near-equal: a swap is allowed for that pair
    _, spreads = scaled_principal_axes(plate.sample(5000, seed=0))
    assert spreads[1] > 0.8


def test_separates_planted_rigid_classes_with_varied_proportions():
    """Tables, rings and bottles with proportions drawn at random, randomly moved: every
    nearest neighbour in its class and most of the first tier."""
    rng = np.random.default_rng(3)
    X, labels = [], []
    for k in range(6):
        for cls, make in (("table", _table), ("ring", _ring), ("bottle", _bottle)):
            m = make(rng)
            X.append(pcavox_descriptor(_moved(np.asarray(m.vertices), 10 * k + len(labels)), m.faces,
                                       n_points=5000))
            labels.append(cls)
    m = retrieval_metrics(descriptor_distance_matrix("pcavox", np.array(X)), labels)
    assert m["nearest_neighbor"] == 1.0
    assert m["first_tier"] >= 0.9, m


def _random_pcavox(rng, n: int, R: int = 8) -> np.ndarray:
    """Random unit grids (sparse, like surface occupancy) with random spreads, some
    near-degenerate so that axis swaps are allowed."""
    G = np.abs(rng.standard_normal((n, R**3))) * (rng.random((n, R**3)) < 0.3)
    G /= np.linalg.norm(G, axis=1, keepdims=True)
    s1 = rng.uniform(0.5, 1.0, n)
    S = np.c_[np.ones(n), s1, s1 * rng.uniform(0.5, 1.0, n)]
    return np.c_[G, S]


def test_projection_bounds_bound_every_symmetry_and_the_embedding_is_invariant():
    """The projection bound never exceeds the pcavox distance (any allowed symmetries), the
    invariant embedding never exceeds the projection bound, and both are informative."""
    from geoshape.retrieval.descriptors.pcavox import (
        pcavox_projection,
        pcavox_projection_distance,
        pcavox_projection_embedding,
    )

    rng = np.random.default_rng(4)
    X = _random_pcavox(rng, 30)
    P = pcavox_projection(X, frequencies=4)
    assert P.shape == (30, 65)
    L = np.array([pcavox_projection_distance(P[i], P) for i in range(30)])
    assert np.allclose(L, pcavox_projection_distance(P[:, None], P[None]), atol=1e-6)  # broadcast form
    E = pcavox_projection_embedding(P, frequencies=3)
    assert E.shape == (30, 27)
    LE = np.sqrt(((E[:, None] - E[None]) ** 2).sum(-1))
    assert np.all(LE <= L + 1e-7)
    for degenerate in (0.0, 0.8, 1.0):  # all 48 symmetries, the default rule, sign flips only
        assert np.all(L <= pcavox_distance_matrix(X, degenerate=degenerate) + 1e-7)  # (rounding at 0)
    # the same bound and embedding for a grid transformed by any of the 48 symmetries
    _, cells = _symmetries(8)
    for perm in cells:
        Y = X.copy()
        Y[:, :-3] = X[:, :-3][:, perm]
        PY = pcavox_projection(Y, frequencies=4)
        assert np.allclose(pcavox_projection_embedding(PY, frequencies=3), E, atol=1e-12)
        assert np.allclose([pcavox_projection_distance(PY[i], P[i]) for i in range(30)], 0.0, atol=1e-6)
    # informative on real shapes: most of the distance between tables and rings
    meshes = [f(np.random.default_rng(k)) for k in range(3) for f in (_table, _ring)]
    Xm = np.array([pcavox_descriptor(m.vertices, m.faces, resolution=8) for m in meshes])
    Pm = pcavox_projection(Xm, frequencies=4)
    Lm = np.array([pcavox_projection_distance(Pm[i], Pm) for i in range(len(meshes))])
    iu = np.triu_indices(len(meshes), 1)
    assert np.median(Lm[iu] / pcavox_distance_matrix(Xm)[iu]) > 0.6
    with pytest.raises(InvalidOptionError, match="frequencies"):
        pcavox_projection(X, frequencies=9)


def test_few_queries_against_many_rows_give_the_same_matrix():
    """A query block of at most 8 rows permutes the query side in one product; the other
    orientation loops over the symmetries: the same distances."""
    rng = np.random.default_rng(5)
    A, B = _random_pcavox(rng, 5), _random_pcavox(rng, 40)
    assert np.allclose(pcavox_distance_matrix(A, B), pcavox_distance_matrix(B, A).T, atol=1e-12)
    assert np.allclose(pcavox_distance_matrix(A[:1], A)[0, 0], 0.0)
