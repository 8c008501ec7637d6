"""Generators of ground-truth benchmarks: decimation, spikes, stretching, articulated figures.

Each generator promises a ground truth by construction; these tests check the promise
exactly (bitwise positions, id maps, offsets) and the refusal of bad parameters.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import grid_mesh, icosphere, shared_dataset
from geoshape_datasets_gen._topology import topology_report
from geoshape_datasets_gen.articulated3d import (
    CLASSES,
    generate_figure,
    make_skeleton,
    pose_vertices,
    write_collection,
)
from geoshape_datasets_gen.decimate import decimate_exact, decimation_ladder
from geoshape_datasets_gen.spikes import add_spikes
from geoshape_datasets_gen.stretch import MAX_PART_FACTOR, graph_distances, stretch_axes, stretch_part

from geoshape.errors import GeoshapeError, InvalidOptionError
from geoshape.geometry.report import mesh_report

# ----------------------------------------------------------------------------- topology


def test_topology_report_hand_cases():
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    r = topology_report(tet)
    assert r.watertight and r.n_components == 1 and r.genus == 0
    flipped = tet.copy()
    flipped[0] = flipped[0, ::-1]
    assert topology_report(flipped).n_inconsistent_edges == 3
    assert not topology_report(tet[:3]).watertight  # open: 3 boundary edges
    assert topology_report(tet[:3]).n_boundary_edges == 3
    # two tetrahedra sharing only vertex 0: a pinch (non-manifold vertex)
    pinch = np.concatenate([tet, np.where(tet == 0, 0, tet + 3)])
    r = topology_report(pinch)
    assert r.n_nonmanifold_vertices == 1 and r.n_nonmanifold_edges == 0 and not r.manifold
    # a fin: three faces on one edge
    fin = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert topology_report(fin).n_nonmanifold_edges == 1


# ----------------------------------------------------------------------------- decimation


@pytest.mark.parametrize("ratio", [0.9, 0.5, 0.25, 0.1])
def test_decimation_keeps_positions_bitwise(ratio):
    V, F = icosphere(4)  # 2562 vertices
    d = decimate_exact(V, F, ratio)
    assert abs(d.fraction - ratio) < 0.01
    assert d.orig_ids.dtype == np.int64 and len(d.orig_ids) == len(d.V)
    assert len(np.unique(d.orig_ids)) == len(d.orig_ids)
    # bitwise: same bytes, not just close
    assert V[d.orig_ids].tobytes() == np.ascontiguousarray(d.V).tobytes()
    r = topology_report(d.F)
    assert r.watertight and r.n_components == 1 and r.genus == 0


def test_decimation_open_mesh_keeps_boundary():
    V, F = grid_mesh(20, 20)
    boundary = np.flatnonzero(
        (V[:, 0] == 0) | (V[:, 0] == V[:, 0].max()) | (V[:, 1] == 0) | (V[:, 1] == V[:, 1].max())
    )
    d = decimate_exact(V, F, 0.5)
    assert np.array_equal(V[d.orig_ids], d.V)
    assert set(boundary.tolist()) <= set(d.orig_ids.tolist())
    assert topology_report(d.F).manifold
    # more boundary vertices than asked for: the achieved fraction says so
    d = decimate_exact(V, F, 0.05)
    assert d.fraction >= len(boundary) / len(V) > 0.05


def test_decimation_ladder_deterministic_and_ratio_one():
    V, F = icosphere(3)
    a = decimation_ladder(V, F, (1.0, 0.5, 0.2))
    b = decimation_ladder(V, F, (1.0, 0.5, 0.2))
    assert np.array_equal(a[0].orig_ids, np.arange(len(V))) and a[0].fraction == 1.0
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.F, y.F) and np.array_equal(x.orig_ids, y.orig_ids)


@pytest.mark.parametrize("bad", [0, -0.1, 1.5, float("nan"), "half"])
def test_decimation_refuses_bad_ratio(bad):
    V, F = icosphere(1)
    with pytest.raises(InvalidOptionError, match=r"ratio"):
        decimate_exact(V, F, bad)
    with pytest.raises(InvalidOptionError):
        decimation_ladder(V, F, [0.5, bad])


@pytest.mark.data
def test_decimation_tosca_mesh_exact():
    from geoshape.io.mesh_io import load_mesh

    V, F = load_mesh(shared_dataset("tosca_r5k") / "vtx_5k" / "cat0.off.gz")
    for d in decimation_ladder(V, F, (0.75, 0.1)):
        assert np.array_equal(V[d.orig_ids], d.V)
        assert topology_report(d.F).manifold


# ----------------------------------------------------------------------------- spikes


def _face_planes(V, F):
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_spikes_counts_ids_and_offsets():
    V, F = icosphere(2)
    count, height = 25, 0.07
    s = add_spikes(V, F, count, height, seed=3)
    n, m = len(V), len(F)
    assert s.V.shape == (n + count, 3) and s.F.shape == (m + 2 * count, 3)
    assert np.array_equal(s.V[:n], V)  # originals untouched, ids 0..n-1
    assert len(np.unique(s.faces)) == count
    diag = np.linalg.norm(V.max(0) - V.min(0))
    normals = _face_planes(V, F[s.faces])
    tips = s.V[n:]
    # each tip lies over its face centroid, at the stated height along the face normal
    dist = np.einsum("ij,ij->i", tips - V[F[s.faces, 0]], normals)
    np.testing.assert_allclose(dist, height * diag, rtol=1e-12)
    np.testing.assert_allclose(tips - height * diag * normals, V[F[s.faces]].mean(1), atol=1e-12)
    np.testing.assert_allclose(s.offsets, height * diag)
    # each tip has exactly three faces, and the surface stays closed and oriented
    assert np.array_equal(np.bincount(s.F.ravel())[n:], np.full(count, 3))
    r = topology_report(s.F)
    assert r.watertight and r.genus == 0
    # outward: the tips of a sphere leave it
    assert np.all(np.linalg.norm(tips, axis=1) > 1.0)


def test_spikes_deterministic_under_seed():
    V, F = icosphere(2)
    a, b = add_spikes(V, F, 10, 0.05, seed=7), add_spikes(V, F, 10, 0.05, seed=7)
    c = add_spikes(V, F, 10, 0.05, seed=8)
    assert np.array_equal(a.V, b.V) and np.array_equal(a.F, b.F)
    assert not np.array_equal(a.faces, c.faces)


def test_spikes_refuse_bad_parameters():
    V, F = icosphere(0)  # 20 faces
    with pytest.raises(InvalidOptionError, match="21 spikes.*20 faces"):
        add_spikes(V, F, 21, 0.1)
    with pytest.raises(InvalidOptionError, match="height"):
        add_spikes(V, F, 5, -0.1)
    with pytest.raises(InvalidOptionError, match="count"):
        add_spikes(V, F, -1, 0.1)
    with pytest.raises(InvalidOptionError, match="count"):
        add_spikes(V, F, 2.5, 0.1)
    assert add_spikes(V, F, 0, 0.1).V.shape == V.shape


# ----------------------------------------------------------------------------- stretching


def test_stretch_axes():
    V, F = icosphere(2)
    Vs = stretch_axes(V, F, [2.0, 1.0, 0.5])
    ext = (Vs.max(0) - Vs.min(0)) / (V.max(0) - V.min(0))
    np.testing.assert_allclose(ext, [2.0, 1.0, 0.5], rtol=1e-12)
    np.testing.assert_allclose(Vs.mean(0), V.mean(0), atol=1e-12)
    for bad in ([1, 1], [1, 0, 1], [1, -2, 1], [np.nan, 1, 1]):
        with pytest.raises(InvalidOptionError, match="scale"):
            stretch_axes(V, F, bad)


def test_stretch_part_is_local_and_smooth():
    V, F = icosphere(4)
    radius = 0.3
    res = stretch_part(V, F, radius=radius, factor=1.8, center=0)
    R = radius * np.linalg.norm(V.max(0) - V.min(0))
    d = graph_distances(V, F, 0)
    outside = d >= R
    assert outside.any() and (~outside).sum() > 50
    assert np.array_equal(res.V[outside], V[outside])  # untouched beyond the ball
    assert np.all(res.weights[outside] == 0) and res.weights[0] == 1.0
    moved = np.linalg.norm(res.V - V, axis=1)
    assert moved[~outside].max() > 0.05
    # displacement along the direction only
    off = res.V - V
    np.testing.assert_allclose(off - np.outer(off @ res.direction, res.direction), 0, atol=1e-12)
    # no face flips on the sphere (fold-free stretch)
    n0, n1 = _face_planes(V, F), _face_planes(res.V, F)
    assert np.all(np.einsum("ij,ij->i", n0, n1) > 0)
    # same inputs and seed: same output; the random centre follows the seed
    a = stretch_part(V, F, radius=0.2, factor=0.7, seed=4)
    b = stretch_part(V, F, radius=0.2, factor=0.7, seed=4)
    assert a.center == b.center and np.array_equal(a.V, b.V)


def test_stretch_part_refuses_bad_parameters():
    V, F = icosphere(2)
    with pytest.raises(InvalidOptionError, match="radius"):
        stretch_part(V, F, radius=-0.1, factor=1.5)
    with pytest.raises(InvalidOptionError, match="factor"):
        stretch_part(V, F, radius=0.2, factor=MAX_PART_FACTOR + 0.1)
    with pytest.raises(InvalidOptionError, match="factor"):
        stretch_part(V, F, radius=0.2, factor=0.0)
    with pytest.raises(InvalidOptionError, match="center"):
        stretch_part(V, F, radius=0.2, factor=1.5, center=len(V))
    with pytest.raises(InvalidOptionError, match="direction"):
        stretch_part(V, F, radius=0.2, factor=1.5, direction=[0, 0, 0])


# ----------------------------------------------------------------------------- figures


@pytest.fixture(scope="module")
def figures():
    return {
        c: generate_figure(c, poses=3, seed=11, target_vertices=900, resolution=72)
        for c in CLASSES
    }


@pytest.mark.parametrize("cls", CLASSES)
def test_figures_watertight_single_component_manifold(figures, cls):
    fig = figures[cls]
    r = topology_report(fig.F)
    assert r.watertight and r.n_components == 1 and r.genus == 0
    assert r.n_vertices == fig.poses.shape[1]
    rep = mesh_report(fig.poses[1], fig.F)  # the library's own report agrees
    assert rep["closed"] and rep["components"] == 1 and rep["n_nonmanifold_vertices"] == 0
    assert rep["unreferenced_vertices"] == 0 and rep["degenerate_faces"] == 0
    assert 800 <= fig.poses.shape[1] <= 1000


@pytest.mark.parametrize("cls", CLASSES)
def test_poses_share_connectivity_and_differ(figures, cls):
    fig = figures[cls]
    tpl = fig.template
    assert np.array_equal(fig.F, tpl.F)
    P = fig.poses
    assert P.shape[0] == 3 and np.all(np.isfinite(P))
    for k in range(1, 3):
        assert np.abs(P[k] - P[0]).max() > 0.02  # really a different pose
    # posing is skinning of one template: zero angles give the rest mesh back
    rest = pose_vertices(tpl, np.zeros_like(fig.angles[0]))
    np.testing.assert_allclose(rest, tpl.V, atol=1e-12)
    np.testing.assert_allclose(tpl.weights.sum(1), 1.0)
    # articulation roughly preserves edge lengths (near-isometric poses)
    E = np.concatenate([fig.F[:, [0, 1]], fig.F[:, [1, 2]], fig.F[:, [2, 0]]])
    L0 = np.linalg.norm(P[0][E[:, 0]] - P[0][E[:, 1]], axis=1)
    L1 = np.linalg.norm(P[1][E[:, 0]] - P[1][E[:, 1]], axis=1)
    assert np.median(np.abs(L1 / L0 - 1)) < 0.05
    assert np.max(np.abs(L1 - L0)) < L0.mean()  # no edge torn open by skinning


def test_figures_deterministic_and_instances_vary():
    a = generate_figure("snake", poses=2, seed=2, target_vertices=600, resolution=64)
    b = generate_figure("snake", poses=2, seed=2, target_vertices=600, resolution=64)
    assert np.array_equal(a.poses, b.poses) and np.array_equal(a.F, b.F)
    c = generate_figure("snake", poses=2, seed=2, instance=1, target_vertices=600, resolution=64)
    assert not np.allclose(a.template.skeleton.positions, c.template.skeleton.positions)
    canon = make_skeleton("hand")
    assert np.array_equal(canon.positions, make_skeleton("hand", variation=0.0, seed=5).positions)


def test_figures_refuse_bad_parameters(tmp_path):
    with pytest.raises(InvalidOptionError, match="'biped'"):
        generate_figure("dragon")
    with pytest.raises(InvalidOptionError, match="poses"):
        generate_figure("snake", poses=0)
    with pytest.raises(InvalidOptionError, match="resolution"):
        generate_figure("snake", resolution=8)
    with pytest.raises(InvalidOptionError, match="variation"):
        make_skeleton("snake", seed=1, variation=2.0)
    with pytest.raises(InvalidOptionError, match="repeat"):
        write_collection(tmp_path, classes=["snake", "snake"])


def test_write_collection_layout(tmp_path):
    from geoshape.io.datasets import read_labels, read_pairs
    from geoshape.io.mesh_io import load_mesh

    res = write_collection(tmp_path, classes=["snake", "quadruped"], instances=2, poses=2,
                           seed=1, target_vertices=600, resolution=64)
    labels = read_labels(tmp_path)
    assert [i.label for i in labels] == ["snake"] * 4 + ["quadruped"] * 4
    pairs = read_pairs(tmp_path)
    assert len(pairs) == 4 == len(res["pairs"])  # one pose pair per instance
    for p in pairs:
        assert p.identity
        Vs, Fs = load_mesh(p.source)
        Vt, Ft = load_mesh(p.target)
        assert np.array_equal(Fs, Ft) and Vs.shape == Vt.shape
    assert not list(tmp_path.glob(".*tmp*"))  # atomic writes left nothing behind


# ----------------------------------------------------------------------------- CLI


def _main(argv):
    from geoshape.__main__ import main

    return main(argv)


def test_cli_decimate_contract(tmp_path):
    from geoshape.io.mesh_io import load_mesh, save_mesh

    V, F = icosphere(3)
    src = save_mesh(tmp_path / "ball.off.gz", V, F)
    out = tmp_path / "dec"
    assert _main(["gen", "decimate", str(src), "--ratios", "0.9,0.5,0.1", "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(f"ball_{p}.{e}" for p in ("090", "050", "010") for e in ("off", "ids"))
    for pct in ("090", "050", "010"):
        Vd, _ = load_mesh(out / f"ball_{pct}.off")
        ids = np.loadtxt(out / f"ball_{pct}.ids", dtype=np.int64, ndmin=1)
        assert len(ids) == len(Vd)
        assert np.array_equal(V[ids], Vd)  # exact through the text round trip
    assert _main(["gen", "decimate", str(src), "--ratios", "0.5,1.2", "--out", str(out)]) == 2
    assert _main(["gen", "decimate", str(src), "--ratios", "0.5,x", "--out", str(out)]) == 2


def test_cli_spikes_and_stretch(tmp_path, capsys):
    from geoshape.io.mesh_io import load_mesh, save_mesh

    V, F = icosphere(2)
    src = save_mesh(tmp_path / "ball.off", V, F)
    out = tmp_path / "spiky.off"
    argv = ["gen", "spikes", str(src), "--count", "12", "--height", "0.1", "--seed", "4"]
    assert _main([*argv, "--out", str(out)]) == 0
    Vs, Fs = load_mesh(out)
    assert len(Vs) == len(V) + 12 and np.array_equal(Vs[: len(V)], V)
    assert _main([*argv, "--out", str(tmp_path / "again.off")]) == 0
    assert (tmp_path / "again.off").read_bytes() == out.read_bytes()
    assert _main(["gen", "spikes", str(src), "--count", "1000", "--height", "0.1",
                  "--out", str(tmp_path / "x.off")]) == 2
    assert _main(["gen", "spikes", str(src), "--count", "3", "--height", "-1",
                  "--out", str(tmp_path / "x.off")]) == 2
    assert "height" in capsys.readouterr().err
    assert not (tmp_path / "x.off").exists()

    st = tmp_path / "long.ply"
    assert _main(["gen", "stretch", str(src), "--scale", "1.5,1,1", "--out", str(st)]) == 0
    Vt, Ft = load_mesh(st)
    assert np.array_equal(Ft, F)
    np.testing.assert_allclose(np.ptp(Vt, 0) / np.ptp(V, 0), [1.5, 1, 1], rtol=1e-9)
    part = tmp_path / "part.off"
    assert _main(["gen", "stretch", str(src), "--radius", "0.3", "--factor", "1.5",
                  "--center", "3", "--out", str(part)]) == 0
    assert load_mesh(part)[0].shape == V.shape
    assert _main(["gen", "stretch", str(src), "--out", str(part)]) == 2
    assert _main(["gen", "stretch", str(src), "--scale", "1,1", "--out", str(part)]) == 2


def test_cli_articulated(tmp_path):
    out = tmp_path / "figs"
    argv = ["gen", "articulated", "--out", str(out), "--classes", "snake,hand", "--poses", "2",
            "--seed", "3", "--vertices", "600", "--resolution", "64"]
    assert _main(argv) == 0
    with open(out / "labels.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["file"] for r in rows] == ["snake0_00.off", "snake0_01.off", "hand0_00.off", "hand0_01.off"]
    with open(out / "pairs.csv", newline="") as fh:
        pairs = list(csv.DictReader(fh))
    assert [(p["source"], p["target"]) for p in pairs] == [
        ("snake0_00.off", "snake0_01.off"), ("hand0_00.off", "hand0_01.off")
    ]
    assert all(p["source_landmarks"] == "" for p in pairs)
    assert _main(["gen", "articulated", "--out", str(out), "--classes", "dragon"]) == 2


def test_errors_are_geoshape_errors():
    assert issubclass(InvalidOptionError, GeoshapeError)


def test_fast_simplification_backend_maps_every_original_vertex_nearby(tmp_path):
    """The collapse map sends each original vertex to a decimated vertex close to it (the
    collapses are local), reaches every decimated vertex, and the CLI writes it as .map."""
    from geoshape_datasets_gen.decimate import decimate_fast

    from geoshape.__main__ import main
    from geoshape.io.mesh_io import load_mesh, save_mesh

    V, F = icosphere(4)
    col = decimate_fast(V, F, 0.25)
    assert abs(col.fraction - 0.25) < 0.02
    assert col.collapsed_to.shape == (len(V),) and set(np.unique(col.collapsed_to)) == set(range(len(col.V)))
    edge = np.mean(np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1))
    assert np.max(np.linalg.norm(V - col.V[col.collapsed_to], axis=1)) < 4 * edge
    assert decimate_fast(V, F, 1.0).collapsed_to.tolist() == list(range(len(V)))
    src = save_mesh(tmp_path / "ball.off", V, F)
    assert main(["gen", "decimate", str(src), "--ratios", "0.5", "--backend", "fast-simplification",
                 "--out", str(tmp_path / "out")]) == 0
    Vd, _ = load_mesh(tmp_path / "out" / "ball_050.off")
    mapping = np.loadtxt(tmp_path / "out" / "ball_050.map", dtype=np.int64)
    assert mapping.shape == (len(V),) and mapping.max() == len(Vd) - 1
