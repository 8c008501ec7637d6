"""Independent remeshing with ground truth (``geoshape gen remesh``, ``gen remesh-set``)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import icosphere, shared_dataset
from geoshape_datasets_gen.remesh import compose_ground_truth, nearest_surface_vertex, remesh

from geoshape.errors import InvalidOptionError
from geoshape.io.datasets import Pair


def _faces_by_position(V, F, decimals=6):
    """The triangulation as a set of vertex-position triples: independent of vertex ids."""
    P = np.round(V, decimals)
    return {frozenset(map(tuple, P[f])) for f in F}


def _jaccard(a, b):
    return len(a & b) / len(a | b)


def _max_edge(V, F):
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).max())


def _cylinder(radius=0.5, height=2.0, around=48, rings=41):
    """A closed cylinder along z: a grid of ``rings`` circles plus two fan caps."""
    th = 2 * np.pi * np.arange(around) / around
    z = np.linspace(-height / 2, height / 2, rings)
    V = np.column_stack([np.tile(radius * np.cos(th), rings), np.tile(radius * np.sin(th), rings),
                         np.repeat(z, around)])
    idx = np.arange(rings * around).reshape(rings, around)
    a, b = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = idx[1:], np.roll(idx[1:], -1, axis=1)
    F = [np.column_stack([a.ravel(), b.ravel(), d.ravel()]),
         np.column_stack([a.ravel(), d.ravel(), c.ravel()])]
    bottom, top = len(V), len(V) + 1
    V = np.vstack([V, [0, 0, -height / 2], [0, 0, height / 2]])
    ring0, ring1 = idx[0], idx[-1]
    F.append(np.column_stack([np.full(around, bottom), np.roll(ring0, -1), ring0]))
    F.append(np.column_stack([np.full(around, top), ring1, np.roll(ring1, -1)]))
    return V, np.concatenate(F).astype(np.int64)


@pytest.fixture(scope="module")
def sphere_remeshed():
    V, F = icosphere(4)
    return V, F, remesh(V, F, 800, seed=0)


def test_sphere_remesh_lies_on_sphere_with_new_connectivity(sphere_remeshed):
    V, F, r = sphere_remeshed
    assert len(r.V) == 800 and r.F.shape[1] == 3 and r.F.max() == 799
    # on the original polyhedron, hence on the sphere up to its chord error (< 0.002 at 4 subdivisions)
    np.testing.assert_allclose(np.linalg.norm(r.V, axis=1), 1.0, atol=0.003)
    assert _jaccard(_faces_by_position(V, F), _faces_by_position(r.V, r.F)) < 0.01
    # the ground truth is a corner of the original face holding the point: within one edge length
    d = np.linalg.norm(r.V - V[r.to_original], axis=1)
    np.testing.assert_allclose(d, r.distance)
    assert d.max() <= _max_edge(V, F)
    from geoshape_datasets_gen._topology import topology_report

    rep = topology_report(r.F)
    assert rep.manifold and rep.watertight and rep.euler == 2


def test_seeds_change_connectivity_and_same_seed_is_identical(sphere_remeshed):
    V, F, r0 = sphere_remeshed
    again = remesh(V, F, 800, seed=0)
    assert np.array_equal(again.V, r0.V) and np.array_equal(again.F, r0.F)
    assert np.array_equal(again.to_original, r0.to_original)
    r1 = remesh(V, F, 800, seed=1)
    assert _jaccard(_faces_by_position(r0.V, r0.F), _faces_by_position(r1.V, r1.F)) < 0.05


def test_cylinder_remesh_analytic():
    radius, height, around, rings = 0.5, 2.0, 48, 41
    V, F = _cylinder(radius, height, around, rings)
    r = remesh(V, F, 1500, seed=3)
    assert len(r.V) == 1500
    z = r.V[:, 2]
    lateral = np.abs(z) < height / 2 - 1e-9
    rad = np.linalg.norm(r.V[lateral, :2], axis=1)
    assert lateral.sum() > 1000
    chord = radius * np.cos(np.pi / around)  # the polygon's inradius
    assert rad.min() >= chord - 1e-9 and rad.max() <= radius + 1e-9
    caps = ~lateral
    np.testing.assert_allclose(np.abs(z[caps]), height / 2, atol=1e-9)
    # ground truth: same height within one ring, same angle within one sector
    g = V[r.to_original[lateral]]
    dz = height / (rings - 1)
    assert np.abs(g[:, 2] - z[lateral]).max() <= dz + 1e-9
    dth = np.angle(np.exp(1j * (np.arctan2(g[:, 1], g[:, 0]) - np.arctan2(r.V[lateral, 1], r.V[lateral, 0]))))
    assert np.abs(dth).max() <= 2 * np.pi / around + 1e-9
    assert np.median(np.abs(g[:, 2] - z[lateral])) < dz / 2 + 1e-9


def test_nearest_surface_vertex_and_bad_arguments():
    V, F = icosphere(2)
    ids = nearest_surface_vertex(V * 1.05, V, F)
    assert np.array_equal(ids, np.arange(len(V)))
    for bad in (0, 10, 2.5, "x", True):
        with pytest.raises(InvalidOptionError):
            remesh(V, F, bad)
    with pytest.raises(InvalidOptionError):
        remesh(V, F, 100, seed=-1)


def test_compose_ground_truth_identity_and_landmarks(tmp_path):
    to_src = np.array([0, 2, 2, 4])  # remeshed source vertex -> original source vertex
    from_tgt = np.array([10, 11, 12, 13, 14])  # original target vertex -> remeshed target vertex
    gt = compose_ground_truth(Pair(tmp_path, tmp_path), to_src, from_tgt, 5, 5)
    assert gt.source.tolist() == [0, 1, 2, 3] and gt.target.tolist() == [10, 12, 12, 14]
    assert gt.target_symmetric is None
    # landmarks: source ids 2 (twice: first wins) and 0; original vertex 4 is no landmark
    pair = Pair(tmp_path, tmp_path, np.array([2, 0, 2]), np.array([3, 1, 4]), np.array([0, 4, 1]))
    gt = compose_ground_truth(pair, to_src, from_tgt, 5, 5)
    assert gt.source.tolist() == [0, 1, 2]
    assert gt.target.tolist() == [11, 13, 13] and gt.target_original.tolist() == [1, 3, 3]
    assert gt.target_symmetric.tolist() == [14, 10, 10]


def _main(argv):
    from geoshape.__main__ import main

    return main(argv)


def test_cli_remesh_writes_mesh_and_maps(tmp_path, capsys):
    from geoshape.io.datasets import read_vts
    from geoshape.io.mesh_io import load_mesh, save_mesh

    V, F = icosphere(3)
    src = save_mesh(tmp_path / "ball.off.gz", V, F)
    out = tmp_path / "re"
    assert _main(["gen", "remesh", str(src), "--vertices", "300", "--seed", "2", "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["ball.from_original.vts", "ball.off", "ball.to_original.vts"]
    Vr, Fr = load_mesh(out / "ball.off")
    to = read_vts(out / "ball.to_original.vts")
    frm = read_vts(out / "ball.from_original.vts")
    assert len(Vr) == len(to) == 300 and len(frm) == len(V)
    assert np.linalg.norm(Vr - V[to], axis=1).max() <= _max_edge(V, F)
    assert np.linalg.norm(V - Vr[frm], axis=1).max() <= _max_edge(Vr, Fr)
    capsys.readouterr()
    for argv in (["--vertices", "3"], ["--seed", "-1"], ["--iterations", "0"]):
        assert _main(["gen", "remesh", str(src), *argv, "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "error" in err
    assert not (tmp_path / "bad").exists()


def _toy_dataset(folder, landmarks: bool):
    """Three deformed spheres: identity ids, or shuffled ids with .vts landmarks."""
    from geoshape.io.mesh_io import save_mesh

    V, F = icosphere(3)
    rng = np.random.default_rng(0)
    names, perms = [], []
    for k, s in enumerate((1.0, 1.3, 0.8)):
        W = V * (1.0, s, 1.0 / s)  # a smooth deformation, known in closed form
        perm = rng.permutation(len(V)) if landmarks else np.arange(len(V))
        inv = np.argsort(perm)
        save_mesh(folder / f"m{k}.off", W[perm], inv[F])
        names.append(f"m{k}.off")
        perms.append(inv)  # inv[i] = new id of template vertex i
    rows = []
    for a, b in ((0, 1), (1, 2)):
        if landmarks:
            sel = np.arange(0, len(V), 2)  # every other template vertex is a landmark
            for k in (a, b):
                (folder / f"m{k}.vts").write_text("".join(f"{i + 1}\n" for i in perms[k][sel]))
            rows.append(f"m{a}.off,m{b}.off,m{a}.vts,m{b}.vts,\n")
        else:
            rows.append(f"m{a}.off,m{b}.off,,,\n")
    if not landmarks:  # SCAPE-like feature points with left/right partners
        (folder / "Corrs").mkdir()
        left, right = int(np.argmax(V[:, 0])), int(np.argmin(V[:, 0]))
        (folder / "Corrs" / "1.pid").write_text(f"{left} 0 0 0\n{right} 0 0 0\n")
        (folder / "Corrs" / "1.sym.info").write_text("0 1\n")
    (folder / "pairs.csv").write_text("source,target,source_landmarks,target_landmarks,"
                                      "target_symmetric_landmarks\n" + "".join(rows))
    return (1.0, 1.3, 0.8)


@pytest.mark.parametrize("landmarks", [False, True])
def test_cli_remesh_set_composes_ground_truth(tmp_path, landmarks):
    import json

    from geoshape.io.datasets import read_pairs
    from geoshape.io.mesh_io import load_mesh

    data = tmp_path / "data"
    data.mkdir()
    scales = _toy_dataset(data, landmarks)
    out = tmp_path / "set"
    argv = ["gen", "remesh-set", "--dataset", str(data), "--vertices", "250", "--out", str(out)]
    assert _main(argv) == 0
    pairs = read_pairs(out)
    assert len(pairs) == 2 and not pairs[0].identity
    meta = json.loads((out / "generator.json").read_text())
    assert meta["ground_truth"] and len(meta["meshes"]) == 3
    for (a, b), pair in zip(((0, 1), (1, 2)), pairs, strict=True):
        Vs, Fs = load_mesh(pair.source)
        Vt, Ft = load_mesh(pair.target)
        assert len(Vs) == len(Vt) == 250
        # the target position of each landmark is the source position mapped by the deformation
        want = Vs[pair.source_landmarks] * (1.0, scales[b] / scales[a], scales[a] / scales[b])
        err = np.linalg.norm(Vt[pair.target_landmarks] - want, axis=1)
        assert np.median(err) < 0.5 * _max_edge(Vt, Ft) and err.max() < 3 * _max_edge(Vt, Ft)
        expected = 250 if not landmarks else (100, 160)
        n = len(pair.source_landmarks)
        assert n == expected if not landmarks else expected[0] < n < expected[1]
    assert (out / "pairs_features.csv").is_file() == (not landmarks)
    if not landmarks:
        for pair in read_pairs(out, "pairs_features.csv"):
            Vt, _ = load_mesh(pair.target)
            assert len(pair.source_landmarks) == 2
            # the mirrored partner of the +x feature point lies at -x, and vice versa
            assert np.all(Vt[pair.target_landmarks, 0] * Vt[pair.target_symmetric_landmarks, 0] < 0)
    # more pairs than listed: seeded extra pairs (identity sets only)
    more = tmp_path / "more"
    rc = _main(["gen", "remesh-set", "--dataset", str(data), "--vertices", "200", "--pairs", "3",
                "--out", str(more)])
    assert rc == (2 if landmarks else 0)


@pytest.mark.data
def test_remesh_set_tosca_pair(tmp_path):
    from geoshape_datasets_gen.remesh import write_remeshed_set

    from geoshape.io.datasets import read_pairs

    folder = shared_dataset("tosca_r5k")
    res = write_remeshed_set(folder, tmp_path / "t", n_pairs=1, n_vertices=600, seed=0)
    (pair,) = read_pairs(tmp_path / "t")
    assert res["pairs"][0][2] == len(pair.source_landmarks) > 300
    assert pair.target_symmetric_landmarks is not None
    assert (tmp_path / "t" / "labels.csv").is_file()
    assert not any(p.is_relative_to(folder) for p in (pair.source, pair.target))
