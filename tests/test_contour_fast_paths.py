"""The compiled fast paths of 2D retrieval equal the NumPy reference implementations, bit for bit.

The references below are the NumPy formulations the compiled kernels replaced (cyclic DP with
its start ranking, the cost matrices of the default method, the chord-crossing and
on-boundary tests of the visibility graph); the kernels repeat their floating-point
operations, so the results are compared with ``==``, not a tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.contour.matching import batch_match_costs, cyclic_dp_gram_costs, cyclic_dp_variants
from geoshape.contour.methods import (
    contour_signature,
    method_spec,
    pair_costs,
    signature_cost_matrices,
    stack_signatures,
)
from geoshape.contour.retrieval import _block_costs, shape_distance_matrix

# --- NumPy references ------------------------------------------------------------------------


def reference_start_offsets(C: np.ndarray, n_starts: int) -> np.ndarray:
    """``(B, k)`` starts ``v·M + s`` with the smallest sums along the cyclic diagonals."""
    B, V, N, M = C.shape
    i = np.arange(N)
    base = np.round(i * M / N).astype(np.int64)
    cols = (base[None, :] + np.arange(M)[:, None]) % M
    diag = C[:, :, i[None, :], cols].sum(axis=3).reshape(B, V * M)
    k = min(n_starts, V * M)
    if k == V * M:
        return np.tile(np.arange(V * M), (B, 1))
    return np.argpartition(diag, k - 1, axis=1)[:, :k]


def reference_dp_costs(Cr: np.ndarray, skip: float) -> np.ndarray:
    """Order-preserving DP totals of rotated matrices ``(B, N, M)``, one row at a time."""
    B, N, M = Cr.shape
    jl = skip * np.arange(M + 1)
    D = np.broadcast_to(jl, (B, M + 1)).copy()
    E = np.empty((B, M + 1))
    for i in range(N):
        E[:, 0] = D[:, 0] + skip
        np.minimum(D[:, :-1] + Cr[:, i, :], D[:, 1:] + skip, out=E[:, 1:])
        E -= jl
        np.minimum.accumulate(E, axis=1, out=D)
        D += jl
    return D[:, M]


def reference_dp_variants(C: np.ndarray, skip_cost: float, n_starts: int):
    B, V, N, M = C.shape
    starts = reference_start_offsets(C, n_starts)
    k = starts.shape[1]
    v, off = np.divmod(starts, M)
    cols = (np.arange(M)[None, None, :] + off[:, :, None]) % M
    b = np.arange(B)[:, None, None, None]
    Cr = C[b, v[:, :, None, None], np.arange(N)[None, None, :, None], cols[:, :, None, :]]
    return reference_dp_costs(Cr.reshape(B * k, N, M), skip_cost).reshape(B, k), starts


def reference_blocked_chords(P: np.ndarray, eps: float) -> np.ndarray:
    """Chords ``(i < j)`` properly crossing a non-incident edge, in ``triu_indices`` order."""
    N = len(P)
    A, Bp = P, np.roll(P, -1, axis=0)
    iu, ju = np.triu_indices(N, k=1)
    s0, s1 = P[iu][:, None, :], P[ju][:, None, :]
    a, b = A[None], Bp[None]

    def cross(o, p, q):
        return (p[..., 0] - o[..., 0]) * (q[..., 1] - o[..., 1]) - (p[..., 1] - o[..., 1]) * (
            q[..., 0] - o[..., 0])

    d1, d2, d3, d4 = cross(s0, s1, a), cross(s0, s1, b), cross(a, b, s0), cross(a, b, s1)
    t1 = eps * np.linalg.norm(s1 - s0, axis=2)
    t2 = eps * np.linalg.norm(b - a, axis=2)
    proper = (((d1 > t1) & (d2 < -t1)) | ((d1 < -t1) & (d2 > t1))) & (
        ((d3 > t2) & (d4 < -t2)) | ((d3 < -t2) & (d4 > t2)))
    ek = np.arange(N)[None, :]
    incident = (ek == iu[:, None]) | ((ek + 1) % N == iu[:, None]) | (ek == ju[:, None]) | (
        (ek + 1) % N == ju[:, None])
    return (proper & ~incident).any(axis=1)


def reference_distance_to_polygon(X: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Distance from each point of ``X (M, 2)`` to the nearest edge of the closed polygon ``P``."""
    A, B = P, np.roll(P, -1, axis=0)
    AB = B - A
    denom = np.maximum((AB**2).sum(axis=1), 1e-300)
    x = X[:, None, :]
    t = np.clip(((x - A[None]) * AB[None]).sum(axis=2) / denom[None], 0.0, 1.0)
    proj = A[None] + t[..., None] * AB[None]
    return np.sqrt(((x - proj) ** 2).sum(axis=2)).min(axis=1)


# --- inputs ------------------------------------------------------------------------------------


def wobbly_contour(n: int, seed: int) -> np.ndarray:
    """A star-shaped closed contour of ``n`` points, counter-clockwise, with random lobes."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1.0 + sum(rng.uniform(0.05, 0.35) * np.cos(k * t + rng.uniform(0, 2 * np.pi))
                  for k in (2, 3, 5))
    return np.c_[r * np.cos(t), r * np.sin(t)] * rng.uniform(20, 60)


@pytest.fixture(scope="module")
def silhouette_contours():
    from geoshape_datasets_gen.silhouettes2d import articulated_silhouette

    from geoshape.geometry.contour import extract_contour

    return [extract_contour(articulated_silhouette(cls, seed=s), n_points=60)
            for cls, s in (("quadruped", 1), ("quadruped", 2), ("person", 3), ("crab", 4))]


# --- tests -------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(3, 1, 7, 9), (2, 2, 12, 10), (4, 1, 5, 3), (2, 2, 33, 30),
                                   (1, 1, 140, 40), (2, 1, 17, 1)])
@pytest.mark.parametrize("n_starts", [1, 4, 1000])
def test_cyclic_dp_equals_numpy_reference(shape, n_starts):
    rng = np.random.default_rng(sum(shape) + n_starts)
    C = rng.random(shape) * 0.7
    totals, starts = cyclic_dp_variants(C, skip_cost=0.3, n_starts=n_starts)
    ref_totals, ref_starts = reference_dp_variants(C, 0.3, n_starts)
    assert [set(s) for s in starts] == [set(s) for s in ref_starts]
    assert np.array_equal(totals.min(axis=1), ref_totals.min(axis=1))
    order, ref_order = np.argsort(starts, axis=1), np.argsort(ref_starts, axis=1)
    assert np.array_equal(np.take_along_axis(totals, order, 1),
                          np.take_along_axis(ref_totals, ref_order, 1))


@pytest.mark.parametrize("mirror", [False, True])
def test_pair_costs_equal_cost_matrices_then_dp(silhouette_contours, mirror):
    spec = method_spec("default_144pt", mirror=mirror)  # the main term alone
    sigs = [contour_signature(P, spec=spec) for P in silhouette_contours]
    sigs += [contour_signature(wobbly_contour(60, seed), spec=spec) for seed in range(3)]
    stack = stack_signatures(sigs)
    for sig in sigs:
        C = signature_cost_matrices(sig.X, stack.X, "sqeuclidean")
        if mirror:
            C = np.stack([C, signature_cost_matrices(sig.X, stack.X_mirror, "sqeuclidean")], 1)
        per_orientation = spec["matcher_options"]["n_starts"]
        starts = 2 * per_orientation if mirror else per_orientation
        ref = batch_match_costs(C, "dp", skip_cost=0.3, n_starts=starts)
        ref_totals, _ = reference_dp_variants(C if mirror else C[:, None], 0.3, starts)
        assert np.array_equal(ref, ref_totals.min(axis=1) / 60.0)
        assert np.array_equal(pair_costs(sig, stack, spec), ref)
        assert np.array_equal(pair_costs(sig, sigs, spec), ref)


def test_gram_kernel_abandons_hopeless_starts_and_keeps_the_minimum():
    """With only the best total wanted, starts that cannot beat it stop early: their entries
    are lower bounds above the minimum, which is the same bits as matching every start."""
    from geoshape.contour._kernels import cyclic_dp_gram_kernel, cyclic_dp_kernel
    from geoshape.contour.matching import _diagonal_base

    rng = np.random.default_rng(3)
    X1 = rng.random((64, 6))
    X2s = np.stack([np.roll(X1, 11 * b, axis=0) + rng.normal(0, 0.01, X1.shape) for b in range(3)])[:, None]
    n1, n2, G = (X1**2).sum(1), (X2s**2).sum(3), np.matmul(X2s, np.ascontiguousarray(X1.T))
    C = signature_cost_matrices(X1, X2s[:, 0], "sqeuclidean")[:, None]
    base, k = _diagonal_base(64, 64), 16
    pruned, full = np.empty((3, k)), np.empty((3, k))
    starts_p, starts_f = np.empty((3, k), dtype=np.int64), np.empty((3, k), dtype=np.int64)
    cyclic_dp_gram_kernel(G, n1, n2, base, 0.3, pruned, starts_p)
    cyclic_dp_kernel(C, base, 0.3, full, starts_f)
    assert np.array_equal(starts_p, starts_f)
    assert np.array_equal(pruned.min(axis=1), full.min(axis=1))
    abandoned = pruned != full
    assert abandoned.any()
    assert (pruned[abandoned] > full.min(axis=1, keepdims=True).repeat(k, 1)[abandoned]).all()
    assert (pruned <= full).all()  # lower bounds


@pytest.mark.parametrize("mirror", [False, True])
def test_pair_costs_chunks_and_stack_views(mirror):
    """The Gram matrices are made by chunks of pairs into a reused buffer; stacks of any size,
    their tails and one-signature stacks give the same bits, and ``X``/``X_mirror`` are the
    orientations of the stacked ``XV``."""
    from geoshape.contour import methods

    spec = method_spec("default", mirror=mirror)
    n = 2 * methods._GRAM_CHUNK + 3
    sigs = [contour_signature(wobbly_contour(40, seed), spec=spec) for seed in range(n)]
    stack = stack_signatures(sigs)
    assert stack.XV.shape == (len(sigs), 2 if mirror else 1, 40, sigs[0].X.shape[1])
    for b, sig in enumerate(sigs):
        assert np.array_equal(stack.X[b], sig.X)
        assert (stack.X_mirror is None) if not mirror else np.array_equal(stack.X_mirror[b], sig.X_mirror)
    for sig in sigs[:3]:
        full = pair_costs(sig, stack, spec)
        single = np.concatenate([pair_costs(sig, stack_signatures([s]), spec) for s in sigs])
        assert np.array_equal(full, single)
        assert np.array_equal(pair_costs(sig, stack.tail(5), spec), full[5:])


def test_gram_costs_reject_bad_options():
    from geoshape.errors import InvalidOptionError

    G = np.zeros((1, 1, 4, 4))
    with pytest.raises(InvalidOptionError, match="n_starts"):
        cyclic_dp_gram_costs(G, np.zeros(4), np.zeros((1, 1, 4)), n_starts=0)
    with pytest.raises(InvalidOptionError, match="skip_cost"):
        cyclic_dp_variants(np.zeros((1, 1, 4, 4)), skip_cost=0.0)


def test_block_costs_diagonal_block_matches_full_block(silhouette_contours):
    spec = method_spec("default")
    sigs = [contour_signature(P, spec=spec) for P in silhouette_contours]
    full = _block_costs(sigs, list(sigs), spec)  # distinct lists of the same objects: diagonal
    rows = np.array([pair_costs(s, sigs, spec) for s in sigs])
    assert np.array_equal(np.triu(full, 1), np.triu(rows, 1))
    assert np.all(np.tril(full) == 0.0)
    D = shape_distance_matrix(silhouette_contours, backend="serial")
    assert np.array_equal(np.triu(D, 1), np.triu(rows, 1)) and np.array_equal(D, D.T)


@pytest.mark.parametrize("seed", range(4))
def test_visibility_chords_equal_numpy_reference(seed, silhouette_contours):
    from geoshape.contour._kernels import blocked_chords

    rng = np.random.default_rng(seed)
    for P in (silhouette_contours[seed], wobbly_contour(45, seed) + rng.normal(0, 2.0, (45, 2))):
        eps = 1e-6 * float(np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1).sum())
        iu, ju = np.triu_indices(len(P), k=1)
        assert np.array_equal(blocked_chords(P, iu, ju, eps), reference_blocked_chords(P, eps))


@pytest.mark.parametrize("seed", range(3))
def test_near_polygon_equals_numpy_reference(seed, silhouette_contours):
    from geoshape.contour._kernels import near_polygon

    rng = np.random.default_rng(seed)
    P = silhouette_contours[seed]
    # chord midpoints (some on straight runs of the boundary), random points, the vertices
    i, j = rng.integers(0, len(P), (2, 400))
    X = np.vstack([0.5 * (P[i] + P[j]), rng.uniform(P.min(0), P.max(0), (400, 2)), P])
    dist = reference_distance_to_polygon(X, P)
    for tol in (1e-9, 0.5, float(np.median(dist))):
        assert np.array_equal(near_polygon(X, P, tol), dist <= tol)
    assert near_polygon(P, P, 0.0).all()  # every vertex is on the boundary


def test_mirror_signature_reuses_inner_distances_exactly(silhouette_contours):
    """The mirror image's inner distances are the shape's re-indexed: the default's signature
    of a shape carries the same mirror embedding as the mirror image computed from scratch."""
    from geoshape.contour.inner_distance import inner_distances, mirrored_inner_distances
    from geoshape.contour.methods import _embed
    from geoshape.geometry.contour import mirror_contour

    spec = method_spec("default")
    for P in silhouette_contours:
        M = mirror_contour(P)
        D, hop = mirrored_inner_distances(*inner_distances(P))
        D_ref, hop_ref = inner_distances(M)
        assert np.array_equal(D, D_ref) and np.array_equal(hop, hop_ref)
        sig = contour_signature(P, spec=spec)
        assert np.array_equal(sig.X_mirror, _embed(M, spec))
        assert np.array_equal(sig.X, _embed(P, spec))


def test_pairwise_sum_is_numpys():
    from geoshape.contour._kernels import _pairwise_sum

    rng = np.random.default_rng(0)
    for n in (1, 7, 8, 9, 100, 128, 129, 257, 1000):
        a = rng.standard_normal(n) * 10.0 ** rng.uniform(-4, 4, n)
        assert _pairwise_sum(a) == a.sum()
