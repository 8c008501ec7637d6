"""The one Procrustes home: rotations recovered, never a reflection, batched = one by one."""
import numpy as np
import pytest

from geoshape.geometry.procrustes import kabsch, similarity_procrustes


def _rotation(rng, d=3):
    Q, _ = np.linalg.qr(rng.normal(size=(d, d)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1  # det +1 in any dimension
    return Q


def _centred(rng, shape):
    X = rng.normal(size=shape)
    return X - X.mean(axis=-2, keepdims=True)


def test_kabsch_recovers_a_rotation_and_its_trace():
    rng = np.random.default_rng(0)
    P, R0 = _centred(rng, (30, 3)), _rotation(rng)
    R, trace = kabsch(P, P @ R0)
    np.testing.assert_allclose(R, R0, atol=1e-12)
    np.testing.assert_allclose(trace, (P**2).sum(), rtol=1e-12)


def test_kabsch_never_returns_a_reflection():
    rng = np.random.default_rng(1)
    P = _centred(rng, (30, 3))
    Q = P * [1, 1, -1]  # a mirror image: the best orthogonal map is a reflection
    R, trace = kabsch(P, Q)
    assert np.linalg.det(R) == pytest.approx(1.0)
    residual = (P**2).sum() + (Q**2).sum() - 2 * trace
    assert residual == pytest.approx(((P @ R - Q) ** 2).sum())
    assert residual > 0.1 * (P**2).sum()


def test_kabsch_residual_is_the_least_over_rotations():
    rng = np.random.default_rng(2)
    P, Q = _centred(rng, (25, 3)), _centred(rng, (25, 3))
    R, trace = kabsch(P, Q)
    best = ((P @ R - Q) ** 2).sum()
    assert best == pytest.approx((P**2).sum() + (Q**2).sum() - 2 * trace)
    for _ in range(50):  # no random rotation does better
        assert ((P @ _rotation(rng) - Q) ** 2).sum() >= best - 1e-9


def test_kabsch_batched_equals_one_by_one():
    rng = np.random.default_rng(3)
    P, Q = _centred(rng, (7, 12, 3)), _centred(rng, (7, 12, 3))
    R, trace = kabsch(P, Q)
    assert R.shape == (7, 3, 3) and trace.shape == (7,)
    for b in range(7):
        Rb, tb = kabsch(P[b], Q[b])
        np.testing.assert_allclose(R[b], Rb, atol=1e-12)
        assert trace[b] == pytest.approx(tb)


@pytest.mark.parametrize("d", [2, 3])
def test_similarity_procrustes_recovers_scale_rotation_translation(d):
    rng = np.random.default_rng(4)
    X, R0, t0 = rng.normal(size=(40, d)), _rotation(rng, d), rng.normal(size=d)
    s, R, t = similarity_procrustes(X, 2.5 * X @ R0 + t0)
    assert s == pytest.approx(2.5)
    np.testing.assert_allclose(R, R0, atol=1e-12)
    np.testing.assert_allclose(t, t0, atol=1e-12)


def test_similarity_procrustes_of_a_single_point_is_a_translation():
    s, R, t = similarity_procrustes(np.array([[1.0, 2, 3]]), np.array([[0.0, 0, 1]]))
    assert s == 0.0 and np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(t, [0, 0, 1])
