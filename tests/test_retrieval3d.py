"""3D retrieval: descriptor invariances, re-posed copies, distances, re-ranking, CLI contract."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import icosphere

from geoshape.errors import InvalidOptionError
from geoshape.retrieval.descriptors import (
    MESH_DESCRIPTORS,
    compute_descriptor,
    descriptor_distance_matrix,
    descriptor_distances,
    descriptor_params,
    rerank,
)


def _rotation(seed: int) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=seed).as_matrix()


@pytest.fixture(scope="module")
def figures():
    """Two poses each of a biped and a quadruped (~800 vertices), generated once."""
    from geoshape_datasets_gen.articulated3d import generate_figure

    out = {}
    for cls in ("biped", "quadruped"):
        fig = generate_figure(cls, poses=2, seed=3, target_vertices=800, resolution=64)
        out[cls] = [(np.asarray(V), np.asarray(fig.F)) for V in fig.poses]
    return out


def _dist(name, a, b):
    return float(descriptor_distances(name, [a], [b])[0, 0])


# Tolerances of the rigid-motion invariance: relative to the distance to another class.
# SHD and D2 sample the surface with a fixed seed on the same triangles: exact up to
# rounding. LFD is invariant only up to the discrete view set (a rotation that is not a
# dodecahedron symmetry changes the silhouettes); spectral ones up to solver tolerances.
INVARIANCE_RATIO = {"lfd": 0.6, "lfd_emb": 0.6}


@pytest.mark.parametrize("name", [n for n in MESH_DESCRIPTORS if n != "ccd"])
def test_rigid_and_scale_invariance(name, figures):
    spec = MESH_DESCRIPTORS[name]
    V, F = figures["biped"][0]
    Vo, Fo = figures["quadruped"][0]
    moved = 2.5 * V @ _rotation(7).T + np.array([3.0, -1.0, 0.5])
    a = compute_descriptor(V, F, name)
    b = compute_descriptor(moved, F, name)
    c = compute_descriptor(Vo, Fo, name)
    assert {"translation", "rotation", "scale"} <= set(spec.invariances)
    d_self, d_other = _dist(name, a, b), _dist(name, a, c)
    assert d_other > 0
    assert d_self <= INVARIANCE_RATIO.get(name, 0.05) * d_other, (name, d_self, d_other)


def _ellipsoid(axes, subdivisions=3):
    V, F = icosphere(subdivisions)
    return V * np.asarray(axes, dtype=float), F


def test_shared_eigensolve_gives_the_separate_descriptors(figures):
    """compute_descriptor_set: evd_heat, shapedna and wks read one eigen-solve; same numbers."""
    from geoshape.retrieval.descriptors import compute_descriptor_set

    V, F = figures["biped"][0]
    names = ("evd_heat", "shapedna", "lfd", "wks")
    got, sec = compute_descriptor_set(V, F, names)
    assert set(got) == set(sec) == set(names) and all(t >= 0 for t in sec.values())
    for n in names:
        np.testing.assert_allclose(got[n], compute_descriptor(V, F, n), rtol=1e-7, atol=1e-12, err_msg=n)


def test_fused_rigid_and_scale_invariance(figures):
    """The fused default: a rotated, translated, uniformly scaled copy is (nearly) at
    distance 0, far nearer than the other class, and ranks first."""
    from geoshape.retrieval.meshes import retrieval3d_matrix

    (V, F), (V1, F1) = figures["biped"]
    (W, G), (W1, G1) = figures["quadruped"]
    moved = 2.5 * V @ _rotation(7).T + np.array([3.0, -1.0, 0.5])
    meshes = [(V, F), (moved, F), (V1, F1), (W, G), (W1, G1)]
    D = retrieval3d_matrix(meshes, "fused", backend="serial", progress=False)["D"]
    assert D[0, 1] <= 0.2 * min(D[0, 3], D[0, 4]), D
    assert np.argsort(D[0])[1] == 1 and np.argsort(D[1])[1] == 0


def test_fused_separates_rigid_and_articulated_classes(figures):
    """A tiny planted collection: one rigid class (an ellipsoid moved and scaled), two
    articulated classes (two poses each): every item's nearest neighbours are its class."""
    from geoshape.metrics.retrieval import retrieval_metrics
    from geoshape.retrieval.meshes import retrieval3d_matrix

    E, EF = _ellipsoid((1.0, 0.6, 0.35))
    meshes = [(E, EF), (0.5 * E @ _rotation(2).T + 1.0, EF), (3.0 * E @ _rotation(5).T, EF),
              *figures["biped"], *figures["quadruped"]]
    labels = ["rigid"] * 3 + ["biped"] * 2 + ["quadruped"] * 2
    D = retrieval3d_matrix(meshes, "fused", backend="serial", progress=False)["D"]
    m = retrieval_metrics(D, labels)
    assert m["nearest_neighbor"] == 1.0 and m["first_tier"] == 1.0, m


def test_ccd_invariance_and_discrimination(figures):
    V, F = figures["biped"][0]
    a = compute_descriptor(V, F, "ccd")
    b = compute_descriptor(2.0 * V @ _rotation(3).T + 1.0, F, "ccd")
    Vo, Fo = figures["quadruped"][0]
    c = compute_descriptor(Vo, Fo, "ccd")
    assert a.shape == (100, 5)
    assert _dist("ccd", a, b) < 0.2 * _dist("ccd", a, c)


@pytest.mark.parametrize("name", ["evd", "evd_heat", "shapedna", "wks", "gsv", "d2_emb", "shd_emb",
                                  "lfd_emb", "ccd"])
def test_reposed_copy_closer_than_other_class(name, figures):
    """Bending-invariant descriptors: a re-posed copy is nearer than another class."""
    (V0, F0), (V1, F1) = figures["biped"]
    (W0, G0), (W1, G1) = figures["quadruped"]
    X = [compute_descriptor(V, F, name) for V, F in [(V0, F0), (V1, F1), (W0, G0), (W1, G1)]]
    D = descriptor_distances(name, X, X)
    assert D[0, 1] < min(D[0, 2], D[0, 3]), D
    assert D[2, 3] < min(D[2, 0], D[2, 1]), D


def test_wks_vertex_order_and_reposing(figures):
    """WKS quantiles: a vertex permutation changes nothing (up to the eigensolver), a re-posed copy
    is much nearer than another class, and the descriptor is sorted per band."""
    (V0, F0), (V1, F1) = figures["biped"]
    W, G = figures["quadruped"][0]
    perm = np.random.default_rng(5).permutation(len(V0))
    inv = np.argsort(perm)
    a = compute_descriptor(V0, F0, "wks")
    assert a.shape == (16, 16) and np.all(np.diff(a, axis=1) >= 0)
    shuffled = compute_descriptor(V0[perm], inv[F0], "wks")
    other = _dist("wks", a, compute_descriptor(W, G, "wks"))
    assert _dist("wks", a, shuffled) <= 1e-4 * other
    assert _dist("wks", a, compute_descriptor(V1, F1, "wks")) <= 0.5 * other


def test_wave_kernel_bands_and_weighted_quantiles():
    from geoshape.retrieval.descriptors.wks import weighted_quantiles
    from geoshape.spectral.laplacian import laplacian_basis, wave_kernel_bands

    V, F = icosphere(3)
    basis = laplacian_basis(V, F, k=30)
    W = wave_kernel_bands(basis, np.log([30.0, 100.0, 300.0]), 0.5)
    assert W.shape == (len(V), 3) and np.all(W >= 0)
    np.testing.assert_allclose(basis.mass @ W, 1.0, rtol=1e-6)  # unit area-mean per band
    # a band no eigenvalue reaches is all zero, not NaN
    assert np.all(wave_kernel_bands(basis, [np.log(1e9)], 0.1) == 0)
    with pytest.raises(InvalidOptionError):
        wave_kernel_bands(basis, [1.0], 0.0)
    x = np.array([[3.0], [1.0], [2.0], [4.0]])
    # equal weights: midpoints at 1/8, 3/8, 5/8, 7/8 of the sorted values
    np.testing.assert_allclose(weighted_quantiles(x, np.ones(4), [0.125, 0.5, 0.875]), [[1.0, 2.5, 4.0]])
    # a heavy value pulls the median
    assert weighted_quantiles(x, [1.0, 1.0, 1.0, 10.0], [0.5])[0, 0] > 3.5


def test_descriptor_shapes_and_metrics():
    V, F = icosphere(2)
    assert compute_descriptor(V, F, "d2").shape == (64,)
    assert np.isclose(compute_descriptor(V, F, "d2").sum(), 1.0)
    assert compute_descriptor(V, F, "shd").shape == (16 * 17,)
    assert compute_descriptor(V, F, "lfd").shape == (4, 10, 46)
    assert compute_descriptor(V, F, "shapedna").shape == (20,)
    assert compute_descriptor(V, F, "evd").shape == (20,)
    for name, spec in MESH_DESCRIPTORS.items():
        assert spec.metric in ("chi2", "l1", "l2", "lfd", "pcavox", "ccd"), name


def test_distance_matrix_symmetric_zero_diagonal():
    rng = np.random.default_rng(0)
    X = rng.random((6, 20))
    for name in ("evd", "gsv", "shapedna"):
        D = descriptor_distance_matrix(name, X)
        assert np.allclose(D, D.T) and np.allclose(np.diag(D), 0)
    # chi2 by hand: 0.5 * (1 - 3)^2 / 4 = 0.5
    assert np.isclose(descriptor_distances("evd", [[1.0, 0.0]], [[3.0, 0.0]])[0, 0], 0.5)


def test_lfd_view_permutations_form_the_rotation_group():
    from geoshape.retrieval.descriptors.lfd import dodecahedron_axes, dodecahedron_view_permutations

    P = dodecahedron_view_permutations()
    assert P.shape == (60, 10)
    assert (P[0] == np.arange(10)).all()
    assert all(sorted(p) == list(range(10)) for p in P.tolist())
    assert len({tuple(p) for p in P.tolist()}) == 60
    assert np.allclose(np.linalg.norm(dodecahedron_axes(), axis=1), 1.0)


def test_rasterizer_fills_a_square():
    from geoshape.retrieval.descriptors.lfd import rasterize_triangles

    P = np.array([[2.0, 2.0], [12.0, 2.0], [12.0, 12.0], [2.0, 12.0]])
    mask = rasterize_triangles(P, np.array([[0, 1, 2], [0, 2, 3]]), 16)
    assert mask[2:12, 2:12].all()
    assert mask.sum() <= 11 * 11 + 4


def test_rerank_reorders_the_shortlist_only():
    D0 = np.array([[0, 1, 2, 3], [1, 0, 2, 3], [2, 2, 0, 1], [3, 3, 1, 0]], dtype=float)
    # 1-D "embeddings": item 2 is nearest to item 0 in the second stage
    descs = [np.array([[0.0, 0, 0, 0, 0]]), np.array([[5.0, 0, 0, 0, 0]]),
             np.array([[0.1, 0, 0, 0, 0]]), np.array([[9.0, 0, 0, 0, 0]])]
    D = rerank(D0, descs, k=2)
    order = np.argsort(D[0])
    assert order.tolist()[:3] == [0, 2, 1]  # shortlist {1, 2} re-ranked by CCD
    assert order[-1] == 3  # outside the shortlist: after it, first-stage order


def test_bad_options():
    V, F = icosphere(1)
    with pytest.raises(InvalidOptionError, match="descriptor must be one of"):
        compute_descriptor(V, F, "nope")
    with pytest.raises(InvalidOptionError, match="takes no affinity.*shd_emb"):
        descriptor_params("shd", "euclidean")
    with pytest.raises(InvalidOptionError, match="affinity must be one of"):
        descriptor_params("evd", "manhattan")


def test_affinities_change_the_embedding(figures):
    V, F = figures["biped"][0]
    g = compute_descriptor(V, F, "evd", affinity="geodesic")
    e = compute_descriptor(V, F, "evd", affinity="euclidean")
    c = compute_descriptor(V, F, "evd", affinity="combined")
    assert not np.allclose(g, e) and not np.allclose(g, c)


@pytest.fixture(scope="module")
def small_collection(tmp_path_factory, figures):
    from geoshape.io.mesh_io import save_mesh

    d = tmp_path_factory.mktemp("coll")
    rows = ["file,label"]
    for cls, meshes in figures.items():
        for k, (V, F) in enumerate(meshes):
            save_mesh(d / f"{cls}{k}.off", V, F)
            rows.append(f"{cls}{k}.off,{cls}")
    (d / "labels.csv").write_text("\n".join(rows) + "\n")
    return d


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "geoshape", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=300)


@pytest.mark.slow
def test_cli_contract(small_collection, tmp_path):
    out, js, pr, mat = (tmp_path / "D.npy", tmp_path / "m.json", tmp_path / "pr.png",
                        tmp_path / "m.png")
    r = _cli("retrieval3d", small_collection, "--descriptor", "evd", "--affinity", "geodesic",
             "--matrix", out, "--json", js, "--plot-pr", pr, "--plot-matrix", mat, "--jobs", "1")
    assert r.returncode == 0, r.stderr
    D = np.load(out)
    assert D.shape == (4, 4)
    meta = json.loads(js.read_text())
    for key in ("NN", "FT", "ST", "E", "DCG", "mAP", "seconds"):
        assert key in meta
    assert meta["NN"] == 1.0
    assert meta["files"] == ["biped0.off", "biped1.off", "quadruped0.off", "quadruped1.off"]
    assert pr.stat().st_size > 0 and mat.stat().st_size > 0


@pytest.mark.slow
def test_cli_default_is_the_fused_method(small_collection, tmp_path):
    """Without --descriptor, retrieval3d runs the fused default: the matrix of --descriptor fused."""
    from geoshape.retrieval.descriptors import DEFAULT_RETRIEVAL_METHOD

    assert DEFAULT_RETRIEVAL_METHOD == "fused"
    default, fused, js = tmp_path / "default.npy", tmp_path / "fused.npy", tmp_path / "m.json"
    r = _cli("retrieval3d", small_collection, "--matrix", default, "--json", js, "--jobs", "1")
    assert r.returncode == 0, r.stderr
    r = _cli("retrieval3d", small_collection, "--descriptor", "fused", "--matrix", fused, "--jobs", "1")
    assert r.returncode == 0, r.stderr
    np.testing.assert_array_equal(np.load(default), np.load(fused))
    meta = json.loads(js.read_text())
    assert meta["descriptor"] == "fused" and meta["NN"] == 1.0
    r = _cli("retrieval3d", "--help")
    assert "default fused" in " ".join(r.stdout.split())


@pytest.mark.slow
def test_cli_bad_mesh_named_and_nothing_written(small_collection, tmp_path):
    import shutil

    d = tmp_path / "coll"
    shutil.copytree(small_collection, d)
    (d / "broken.off").write_text("OFF\n3 1 0\n0 0 0\n1 0\n")
    (d / "labels.csv").write_text((d / "labels.csv").read_text() + "broken.off,biped\n")
    out = tmp_path / "D.npy"
    r = _cli("retrieval3d", d, "--descriptor", "d2", "--matrix", out, "--jobs", "1")
    assert r.returncode == 2
    assert "broken.off" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()
    r = _cli("retrieval3d", d, "--descriptor", "nope", "--matrix", out)
    assert r.returncode == 2 and "evd_ccd" in r.stderr


@pytest.fixture(autouse=True)
def _one_blas_thread():
    """Small dense eigenproblems: BLAS threads only spin on a shared machine."""
    from geoshape.parallel import single_thread_blas

    with single_thread_blas():
        yield
