"""Affinities, spectral embeddings (exact and Nyström), EVD, the embed CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import grid_mesh, icosphere
from scipy.linalg import subspace_angles

from geoshape.distances import chi2_distance
from geoshape.errors import GeoshapeError, InvalidMeshError, InvalidOptionError
from geoshape.retrieval.descriptors.evd import evd_descriptor, evd_distance_matrix
from geoshape.spectral.affinity import gaussian_affinity, parse_sigma, resolve_sigma
from geoshape.spectral.embedding import (
    embedding_from_affinity,
    fix_signs,
    scale_eigenvectors,
    spectral_embedding,
)
from geoshape.spectral.nystrom import nystrom_eigenpairs


def bumpy_ellipsoid(subdivisions: int = 3):
    """An ellipsoid with distinct axes and one bump: no symmetry, distinct eigenvalues."""
    V, F = icosphere(subdivisions)
    bump = 0.3 * np.exp(-np.sum((V - [0.6, 0.6, 0.5]) ** 2, axis=1) / 0.1)
    V = V * (1.0 + bump)[:, None] * [1.0, 1.5, 2.3]
    return V, F


def tube(bend_deg: float = 0.0, rings: int = 61, per_ring: int = 10):
    """An open elliptic tube of length 4 along z, bent in the y-z plane by ``bend_deg``.

    The bend is a circular arc of the centre line over z in [1.6, 2.4] (the "joint");
    the centre line keeps its length, the surface stretches by at most r / R there.
    """
    t = np.linspace(0, 2 * np.pi, per_ring, endpoint=False)
    h = np.repeat(np.linspace(0, 4.0, rings), per_ring)
    x = np.tile(0.1 * np.cos(t), rings)
    y = np.tile(0.06 * np.sin(t), rings)
    r, j = np.divmod(np.arange((rings - 1) * per_ring), per_ring)
    a, b = r * per_ring + j, r * per_ring + (j + 1) % per_ring
    F = np.concatenate([np.column_stack([a, b, b + per_ring]),
                        np.column_stack([a, b + per_ring, a + per_ring])])
    th = np.radians(bend_deg)
    if th == 0:
        return np.column_stack([x, y, h]), F
    z0, z1 = 1.6, 2.4
    R = (z1 - z0) / th
    s = np.clip(h, z0, z1) - z0
    phi = s / R
    extra = h - np.clip(h, z0, z1)
    centre = np.column_stack([np.zeros_like(h), R - R * np.cos(phi), z0 + R * np.sin(phi)])
    tangent = np.column_stack([np.zeros_like(h), np.sin(phi), np.cos(phi)])
    normal = np.column_stack([np.zeros_like(h), np.cos(phi), -np.sin(phi)])
    V = centre + x[:, None] * [1.0, 0, 0] + y[:, None] * normal + extra[:, None] * tangent
    return V, F


def folded_strip(angle_deg: float):
    """A 4 x 1 grid strip folded by ``angle_deg`` along the grid line x = 2: an isometry."""
    V, F = grid_mesh(41, 11, 1.0)
    V = V * [4.0, 1.0, 1.0]
    th = np.radians(angle_deg)
    right = V[:, 0] > 2.0 + 1e-12
    d = V[right, 0] - 2.0
    V[right, 0] = 2.0 + d * np.cos(th)
    V[right, 2] = d * np.sin(th)
    return V, F


def align_signs(X, Y):
    """``Y`` with each column's sign flipped to best match ``X``."""
    s = np.sign(np.sum(X * Y, axis=0))
    s[s == 0] = 1
    return Y * s


def test_gaussian_affinity_and_sigma_rules():
    D = np.array([[0.0, 1.0, 3.0], [1.0, 0.0, 2.0], [3.0, 2.0, 0.0]])
    A, s = gaussian_affinity(D)
    assert s == 3.0 and np.allclose(np.diag(A), 1.0)
    assert A[0, 2] == pytest.approx(np.exp(-0.5))
    assert resolve_sigma(D, "mean") == pytest.approx(D.mean())
    assert resolve_sigma(D, 0.5) == pytest.approx(0.5 * D.mean())
    assert parse_sigma("2") == 2.0
    with pytest.raises(InvalidOptionError, match="sigma"):
        parse_sigma("widest")
    for too_small in (-1.0, 0.0, 1e-300):
        with pytest.raises(InvalidOptionError, match="≥ 1e-06"):
            parse_sigma(too_small)
    assert parse_sigma(1e-6) == 1e-6
    with pytest.raises(InvalidOptionError, match="zero"):
        resolve_sigma(np.zeros((3, 3)))


def test_signs_and_scalings():
    U = np.array([[0.6, -0.8], [-0.8, 0.6]])
    fix_signs(U)
    assert U[np.argmax(np.abs(U[:, 0])), 0] > 0 and U[np.argmax(np.abs(U[:, 1])), 1] > 0
    lam = np.array([4.0, 1.0])
    assert np.allclose(scale_eigenvectors(U, lam, "sqrt"), U * [2.0, 1.0])
    assert np.allclose(scale_eigenvectors(U, lam, "eigenvalue"), U * lam)
    assert np.allclose(scale_eigenvectors(U, lam, "none"), U)
    S = scale_eigenvectors(U, lam, "squared_sphere")
    assert np.allclose(np.linalg.norm(S, axis=1), 1.0)
    with pytest.raises(InvalidOptionError, match="'sqrt'"):
        scale_eigenvectors(U, lam, "log")


def test_embedding_from_affinity_matches_eigh():
    rng = np.random.default_rng(1)
    X = rng.standard_normal((60, 3))
    A, _ = gaussian_affinity(np.linalg.norm(X[:, None] - X[None], axis=2))
    lam_all, U_all = np.linalg.eigh(A)
    emb = embedding_from_affinity(A, 3)
    assert np.allclose(emb.eigenvalues, lam_all[::-1][1:4])
    assert emb.params["first_eigenvalue"] == pytest.approx(lam_all[-1])
    ref = U_all[:, ::-1][:, 1:4] * np.sqrt(lam_all[::-1][1:4])
    assert np.allclose(emb.coords, align_signs(emb.coords, ref), atol=1e-8)
    centred = embedding_from_affinity(A, 3, first="center")
    assert centred.coords.shape == (60, 3)
    assert np.allclose(centred.coords.mean(axis=0), 0.0, atol=1e-10)


def test_permutation_equivariance():
    V, F = bumpy_ellipsoid(2)
    perm = np.random.default_rng(7).permutation(len(V))
    inv = np.argsort(perm)
    Vp, Fp = V[perm], inv[F]
    a = spectral_embedding(V, F, k=5, method="exact")
    b = spectral_embedding(Vp, Fp, k=5, method="exact")
    assert np.allclose(a.eigenvalues, b.eigenvalues, rtol=1e-9)
    assert np.allclose(a.coords[perm], b.coords, atol=1e-8)


def test_rigid_and_scale_invariance():
    V, F = bumpy_ellipsoid(2)
    a = spectral_embedding(V, F, k=4, method="exact")
    q, _ = np.linalg.qr(np.random.default_rng(3).standard_normal((3, 3)))
    W = 3.7 * V @ q.T + [10.0, -4.0, 2.5]
    b = spectral_embedding(W, F, k=4, method="exact")
    assert np.allclose(a.eigenvalues, b.eigenvalues, rtol=1e-8)
    assert np.allclose(a.coords, align_signs(a.coords, b.coords), atol=1e-7)


@pytest.mark.parametrize("geodesics", ["graph", "heat"])
def test_folding_a_strip_changes_nothing(geodesics):
    """Folding keeps every edge length, so graph and heat geodesics, hence embeddings, agree."""
    V0, F = folded_strip(0.0)
    V1, _ = folded_strip(100.0)
    a = spectral_embedding(V0, F, k=4, method="exact", geodesics=geodesics)
    b = spectral_embedding(V1, F, k=4, method="exact", geodesics=geodesics)
    assert np.allclose(a.eigenvalues, b.eigenvalues, rtol=1e-6)
    # the strip is symmetric: an eigenvector's largest entries tie in magnitude, so its
    # sign is decided by rounding (it changed with the BLAS thread count)
    assert np.allclose(a.coords, align_signs(a.coords, b.coords), atol=1e-6 * np.abs(a.coords).max())


@pytest.mark.slow
def test_bending_invariance():
    V0, F = tube(0.0)
    V1, _ = tube(90.0)
    assert np.linalg.norm(V1[0] - V1[-1]) < 3.1  # really bent (4 when straight)

    def rel(a, b):
        return np.linalg.norm(a.coords - align_signs(a.coords, b.coords)) / np.linalg.norm(a.coords)

    geo = rel(*(spectral_embedding(W, F, k=2, method="exact") for W in (V0, V1)))
    euc = rel(*(spectral_embedding(W, F, k=2, method="exact", affinity="euclidean")
                for W in (V0, V1)))
    assert geo < 0.08
    assert euc > 3 * geo  # the Euclidean affinity does see the bend


def test_nystrom_close_to_exact():
    V, F = bumpy_ellipsoid()
    # k = 3: the next eigenvalues are 10x smaller (a clear gap; 4 and 5 nearly coincide)
    ex = spectral_embedding(V, F, k=3, method="exact")
    ny = spectral_embedding(V, F, k=3, method="nystrom", n_samples=50)
    assert ny.params["n_samples"] == 50 and len(ny.params["samples"]) == 50
    assert np.cos(subspace_angles(ex.coords, ny.coords)).min() >= 0.98
    assert np.allclose(ny.eigenvalues, ex.eigenvalues, rtol=0.05)
    raw = spectral_embedding(V, F, k=3, method="nystrom", n_samples=50, orthogonalize=False)
    assert np.allclose(np.linalg.norm(raw.coords, axis=0) ** 2, raw.eigenvalues)
    # same seed, same result; the auto method picks Nyström when samples are given
    again = spectral_embedding(V, F, k=3, n_samples=50)
    assert np.array_equal(again.coords, ny.coords)


def test_nystrom_eigenpairs_reproduce_low_rank_matrix():
    rng = np.random.default_rng(0)
    B = rng.standard_normal((200, 4))
    W = B @ B.T  # rank 4, positive semi-definite
    samples = np.arange(0, 200, 10)
    lam, U = nystrom_eigenpairs(W[samples], samples, 4)
    ref = np.linalg.eigvalsh(W)[::-1][:4]
    assert np.allclose(lam, ref, rtol=1e-8)
    assert np.allclose(U.T @ U, np.eye(4), atol=1e-10)
    with pytest.raises(InvalidOptionError, match="m <= l"):
        nystrom_eigenpairs(W[samples], samples, 30)


@pytest.mark.parametrize("affinity", ["euclidean", "combined"])
def test_other_affinities(affinity):
    V, F = bumpy_ellipsoid(2)
    emb = spectral_embedding(V, F, k=3, affinity=affinity, sigma="mean")
    assert emb.coords.shape == (len(V), 3) and np.isfinite(emb.coords).all()
    assert emb.params["affinity"] == affinity


def test_disconnected_and_soup_meshes_embed():
    V, F = icosphere(1)
    two_V = np.vstack([V, V + [3.0, 0, 0]])
    two_F = np.vstack([F, F + len(V)])
    emb = spectral_embedding(two_V, two_F, k=3)
    assert np.isfinite(emb.coords).all()
    # the first non-trivial coordinate separates the two parts
    assert np.sign(emb.coords[: len(V), 0]).std() == 0 and np.sign(emb.coords[len(V):, 0]).std() == 0
    soup_V, soup_F = V[F.ravel()], np.arange(3 * len(F)).reshape(-1, 3)
    assert np.isfinite(spectral_embedding(soup_V, soup_F, k=3).coords).all()


def test_evd_retriangulated_copy_close_other_class_far():
    import trimesh

    cap_a = trimesh.creation.capsule(height=3.0, radius=0.5, count=[14, 14])
    cap_b = trimesh.creation.capsule(height=3.0, radius=0.5, count=[28, 28])
    plate = trimesh.creation.box(extents=[3.0, 2.0, 0.3]).subdivide().subdivide().subdivide()
    for config in ("quadrature", "thesis"):
        d = [evd_descriptor(m.vertices, m.faces, config=config, n_samples=40) for m in (cap_a, cap_b, plate)]
        assert d[0].shape == (20,) and np.all(np.diff(d[0]) <= 1e-12)
        same, other = chi2_distance(d[0], d[1]), chi2_distance(d[0], d[2])
        assert same < 0.2 * other, config
        M = evd_distance_matrix(d)
        assert np.allclose(M, M.T) and M[0, 1] == pytest.approx(same)


def test_quadrature_evd_is_invariant_to_scale_rigid_motion_and_sampling_density():
    """Area weights make the eigenvalues those of the surface operator, not of the samples."""
    import trimesh
    from scipy.spatial.transform import Rotation

    cap = trimesh.creation.capsule(height=3.0, radius=0.5, count=[24, 24])
    ref = evd_descriptor(cap.vertices, cap.faces, n_samples=150)
    R = Rotation.from_euler("xyz", [0.3, -1.1, 2.0]).as_matrix()
    moved = evd_descriptor(2.5 * cap.vertices @ R.T + [1.0, -4.0, 2.0], cap.faces, n_samples=150)
    # equal up to the order in which exactly tied farthest points are taken (round-off)
    assert np.allclose(moved, ref, rtol=1e-2)
    # twice the samples: the unweighted block's eigenvalues double, the weighted ones stay
    denser = evd_descriptor(cap.vertices, cap.faces, n_samples=300)
    assert chi2_distance(ref, denser) < 0.05 * chi2_distance(
        evd_descriptor(cap.vertices, cap.faces, config="thesis", n_samples=150),
        evd_descriptor(cap.vertices, cap.faces, config="thesis", n_samples=300))


def test_quadrature_evd_on_the_sphere_has_spherical_harmonic_multiplicities():
    """Funk–Hecke: a rotation-invariant kernel on the sphere has eigenvalue multiplicities 1, 3, 5."""
    V, F = icosphere(4)
    lam = evd_descriptor(V, F, n_samples=300) ** 2
    assert lam[0] > 1.05 * lam[1]
    # (graph geodesics are slightly anisotropic: the multiplets split by a few percent)
    assert np.ptp(lam[1:4]) < 0.03 * lam[1] and lam[3] > 1.15 * lam[4]
    assert np.ptp(lam[4:9]) < 0.05 * lam[4] and lam[8] > 1.15 * lam[9]
    # the operator's eigenvalues, not the sample block's: the same with 100 or 600 samples
    for n_samples in (100, 600):
        assert np.allclose(evd_descriptor(V, F, n_samples=n_samples)[:9] ** 2, lam[:9], rtol=0.05)


def test_heat_evd_on_the_sphere_is_the_analytic_heat_spectrum():
    """Known answer: on the unit-area sphere μ = 4π l(l + 1) with multiplicity 2l + 1, and
    the heat EVD is sqrt(2π) ρ exp(-ρ² μ / 4), ρ = 0.1; it does not depend on size."""
    V, F = icosphere(4)
    heat = evd_descriptor(V, F, config="heat")
    mu = np.repeat([4 * np.pi * l * (l + 1) for l in range(5)], [1, 3, 5, 7, 9])[:20]
    analytic = np.sqrt(2 * np.pi) * 0.1 * np.exp(-0.01 * mu / 4)
    # discretisation error grows with the frequency: 0.2 % up to l = 3, 0.5 % at l = 4
    assert np.allclose(heat[:16], analytic[:16], rtol=3e-3)
    assert np.allclose(heat, analytic, rtol=1e-2)
    assert np.allclose(evd_descriptor(3.7 * V + 1.0, F, config="heat"), heat, atol=1e-9)


def test_heat_limit_is_the_narrow_gaussian_operator_on_the_sphere():
    """Independent check of the formula: on the unit-area sphere the Gaussian-of-geodesic
    operator's eigenvalues follow from Funk–Hecke; their square roots equal the heat limit
    times sqrt(1 − Kσ²/3) (the curvature term, K = 4π) up to O(σ⁴)."""
    from scipy.integrate import quad
    from scipy.special import eval_legendre

    from geoshape.retrieval.descriptors.evd import heat_limit_evd

    R, rho = 1 / np.sqrt(4 * np.pi), 0.05
    exact = []
    for l in range(5):
        def integrand(t, l=l):
            return np.exp(-(R * np.arccos(t)) ** 2 / (2 * rho**2)) * eval_legendre(l, t)

        value, _ = quad(integrand, -1, 1, limit=200, points=[np.cos(8 * rho / R)])
        exact.append(np.sqrt(2 * np.pi * R**2 * value))
    heat = heat_limit_evd([4 * np.pi * l * (l + 1) for l in range(5)], rho)
    assert np.allclose(np.array(exact) / heat, np.sqrt(1 - 4 * np.pi * rho**2 / 3), atol=1.5e-3)


def test_heat_evd_retriangulated_copy_close_other_class_far():
    import trimesh

    cap_a = trimesh.creation.capsule(height=3.0, radius=0.5, count=[14, 14])
    cap_b = trimesh.creation.capsule(height=3.0, radius=0.5, count=[28, 28])
    plate = trimesh.creation.box(extents=[3.0, 2.0, 0.3]).subdivide().subdivide().subdivide()
    d = [evd_descriptor(m.vertices, m.faces, config="heat") for m in (cap_a, cap_b, plate)]
    assert np.all(np.diff(d[0]) <= 1e-12)
    assert chi2_distance(d[0], d[1]) < 0.05 * chi2_distance(d[0], d[2])


def test_heat_evd_rejects_sampling_options():
    V, F = icosphere(2)
    for bad in ({"n_samples": 100}, {"sigma": "max"}, {"weighting": "none"}, {"geodesics": "heat"},
                {"p": 2}, {"affinity": "euclidean"}):
        with pytest.raises(InvalidOptionError, match="'heat' EVD samples nothing"):
            evd_descriptor(V, F, config="heat", **bad)
    tetra = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tetra_faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    for k in (20, 0, 2.5):
        with pytest.raises(InvalidOptionError, match="integer n_eigenvalues in \\[1, 3\\]"):
            evd_descriptor(tetra, tetra_faces, config="heat", n_eigenvalues=k)
    # a point cloud has no area to weigh samples by, but a point-cloud Laplacian
    assert evd_descriptor(V, np.zeros((0, 3), int), config="heat").shape == (20,)


def test_evd_configurations_and_errors():
    V, F = icosphere(2)
    thesis = evd_descriptor(V, F, config="thesis")
    explicit = evd_descriptor(V, F, config="quadrature", n_samples=60, sigma="max", weighting="none")
    assert np.array_equal(thesis, explicit)
    with pytest.raises(GeoshapeError, match="point cloud"):
        evd_descriptor(V, np.zeros((0, 3), int), n_samples=60)
    assert evd_descriptor(V, np.zeros((0, 3), int), config="thesis").shape == (20,)
    with pytest.raises(InvalidOptionError, match="EVD configuration"):
        evd_descriptor(V, F, config="fast")


def test_bad_input():
    V, F = bumpy_ellipsoid(1)
    Vn = V.copy()
    Vn[0, 0] = np.nan
    with pytest.raises(InvalidMeshError, match="NaN"):
        spectral_embedding(Vn, F)
    with pytest.raises(InvalidMeshError, match="face indices"):
        spectral_embedding(V, F + 1000)
    with pytest.raises(GeoshapeError, match="k \\+ 1"):
        spectral_embedding([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(GeoshapeError, match="k \\+ 1"):
        spectral_embedding(V, F, k=len(V))
    two_V = np.vstack([V, V + 5])
    two_F = np.vstack([F, F + len(V)])
    with pytest.raises(InvalidOptionError, match="p = 0"):
        spectral_embedding(two_V, two_F, k=2, p=0)
    with pytest.raises(InvalidOptionError, match="'geodesic'"):
        spectral_embedding(V, F, affinity="diffusion")
    with pytest.raises(InvalidOptionError, match="n_samples"):
        spectral_embedding(V, F, method="nystrom", n_samples=len(V) + 1)
    with pytest.raises(InvalidOptionError, match="chi|shape"):
        chi2_distance([1.0, 2.0], [1.0])


def test_embed_cli(tmp_path, capsys):
    from geoshape.__main__ import main
    from geoshape.io.mesh_io import load_mesh, save_mesh

    V, F = bumpy_ellipsoid(2)
    src = tmp_path / "blob.off"
    save_mesh(src, V, F)
    out = tmp_path / "emb.ply"
    assert main(["embed", str(src), "-o", str(out), "--dims", "4", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["n_vertices"] == len(V) and len(res["eigenvalues"]) == 4 and res["seconds"] >= 0
    coords = np.load(tmp_path / "emb.npy")
    Ve, Fe = load_mesh(out)
    assert coords.shape == (len(V), 4) and np.array_equal(Fe, F)
    assert np.allclose(Ve, coords[:, :3])
    assert main(["embed", str(src), "-o", str(out), "--samples", "30", "--sigma", "0.5"]) == 0
    text = capsys.readouterr().out
    assert "eigenvalues" in text and "n_samples=30" in text and "time" in text
    assert main(["embed", str(src), "-o", str(out), "--dims", "1000"]) == 2


def test_laplacian_basis_of_a_unit_area_sphere_has_the_analytic_spectrum():
    """Unit area: radius 1/√(4π), eigenvalues 4π l(l + 1) with multiplicity 2l + 1. The
    solve asks for more pairs than it checks: Lanczos can miss copies of a multiple eigenvalue
    when k cuts through its cluster (l = 4 here), a case only exact symmetry produces."""
    from geoshape.spectral.laplacian import laplacian_basis

    V, F = icosphere(4)
    basis = laplacian_basis(V * 7.0, F, k=20)  # any scale: the basis is of the unit-area mesh
    expected = 4 * np.pi * np.repeat([0.0, 2.0, 6.0, 12.0], [1, 3, 5, 7])  # l = 0 … 3
    assert basis.evals[0] == pytest.approx(0, abs=1e-6)
    assert basis.evals[1:16] == pytest.approx(expected[1:], rel=0.01)
    gram = basis.evecs.T @ (basis.mass[:, None] * basis.evecs)
    assert gram == pytest.approx(np.eye(20), abs=1e-8)


def test_shift_invert_solves_the_shifted_system_and_keeps_the_plain_eigenpairs():
    from scipy.sparse.linalg import eigsh

    from geoshape.geometry.mesh import laplacian_matrices
    from geoshape.spectral.laplacian import shift_invert

    V, F = bumpy_ellipsoid(3)
    L, M = laplacian_matrices(V, F)
    L, M = L.tocsc(), M.tocsc()
    b = np.random.default_rng(0).standard_normal(len(V))
    assert (L + 1e-3 * M) @ shift_invert(L, M, -1e-3).matvec(b) == pytest.approx(b, abs=1e-8)
    v0 = np.ones(len(V))
    plain = eigsh(L, k=8, M=M, sigma=-1e-6, which="LM", v0=v0)[0]
    ours = eigsh(L, k=8, M=M, sigma=-1e-6, which="LM", v0=v0, OPinv=shift_invert(L, M, -1e-6))[0]
    assert np.sort(ours) == pytest.approx(np.sort(plain), rel=1e-9, abs=1e-9)
