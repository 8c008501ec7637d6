"""Mesh I/O, validation, reports, interop, nearest neighbours, datasets, atomic writes."""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from conftest import grid_mesh, icosphere, shared_dataset

from geoshape.errors import DatasetError, InvalidMeshError, InvalidOptionError
from geoshape.geometry.report import mesh_report, report_problems
from geoshape.io.atomic import atomic_path
from geoshape.io.datasets import mesh_stem, read_labels, read_pairs
from geoshape.io.mesh_io import load_mesh, save_mesh
from geoshape.io.validate import check_mesh

# ---------------------------------------------------------------- validation


@pytest.mark.parametrize(
    "V, F, match",
    [
        (np.zeros((4, 2)), [[0, 1, 2]], r"shape \(n, 3\)"),
        ([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], [[0, 1, 2]], "NaN or infinite"),
        ([[0, 0, 0], [1, 0, np.inf], [0, 1, 0]], [[0, 1, 2]], "NaN or infinite"),
        (np.eye(3), [[0, 1, 3]], r"face indices must lie in \[0, 2\]"),
        (np.eye(3), [[0, -1, 2]], r"face indices must lie in \[0, 2\]"),
        (np.eye(3), [[0, 1]], r"shape \(m, 3\)"),
        (np.eye(3), [[0.5, 1, 2]], "faces must be integers"),
        (np.eye(3), np.zeros((0, 3), int), "has no faces"),
        (np.eye(3)[:2], [[0, 1, 1]], "at least 3 vertices"),
        ([["a", "b", "c"]] * 3, [[0, 1, 2]], "not numeric"),
    ],
)
def test_check_mesh_rejects_bad_input(V, F, match):
    with pytest.raises(InvalidMeshError, match=match):
        check_mesh(V, F, name="probe")


def test_check_mesh_names_the_input_and_coerces():
    V, F = check_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.array([[0, 1, 2]], np.int32))
    assert V.dtype == np.float64 and F.dtype == np.int64 and V.flags.c_contiguous
    with pytest.raises(InvalidMeshError, match="^left.off: "):
        check_mesh(np.full((3, 3), np.nan), [[0, 1, 2]], name="left.off")


# ---------------------------------------------------------------- I/O round trips


@pytest.mark.parametrize("ext", ["off", "obj", "ply", "off.gz", "obj.gz", "ply.gz"])
def test_round_trip_keeps_vertex_order_exactly(tmp_path, rng, ext):
    V, F = icosphere(2)
    perm = rng.permutation(len(V))  # an order no loader would produce by itself
    V = V[perm] * 3.14159 + 1e-7
    F = np.argsort(perm)[F]
    V = np.vstack([V, [[9.0, 9.0, 9.0]]])  # an unreferenced vertex must survive
    path = save_mesh(tmp_path / f"m.{ext}", V, F, colors=rng.random((len(V), 3)))
    V2, F2 = load_mesh(path)
    assert np.array_equal(V, V2)
    assert np.array_equal(F, F2)


def test_stl_round_trip_is_a_triangle_soup(tmp_path):
    V, F = icosphere(1)
    V2, F2 = load_mesh(save_mesh(tmp_path / "m.stl", V, F))
    assert len(V2) == 3 * len(F)
    np.testing.assert_allclose(V2[F2], V[F], atol=1e-6)  # float32 storage


def test_off_polygons_are_fan_triangulated(tmp_path):
    (tmp_path / "q.off").write_text("OFF\n# a quad\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    V, F = load_mesh(tmp_path / "q.off")
    assert F.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_obj_negative_and_slashed_indices(tmp_path):
    (tmp_path / "t.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf -3/1 -2/1 -1/1\n")
    _, F = load_mesh(tmp_path / "t.obj")
    assert F.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize(
    "name, content, match",
    [
        ("trunc.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n", "truncated OFF"),
        ("badface.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "face indices"),
        ("nan.off", "OFF\n3 1 0\n0 0 nan\n1 0 0\n0 1 0\n3 0 1 2\n", "NaN"),
        ("head.off", "PFF\n3 1 0\n", "not an OFF file"),
        ("empty.off", "", "empty file"),
        ("bad.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 100\n"
         "property float x\nproperty float y\nproperty float z\nelement face 10\n"
         "property list uchar int vertex_indices\nend_header\n\x00\x01garbage", "PLY"),
        ("junk.obj", "v 0 0\nf 1 2 3\n", "3 coordinates"),
        ("mesh.xyz", "1 2 3\n", "unsupported mesh extension"),
    ],
)
def test_malformed_files_raise_clear_errors(tmp_path, name, content, match):
    path = tmp_path / name
    path.write_bytes(content.encode("latin-1"))
    with pytest.raises(InvalidMeshError, match=match) as info:
        load_mesh(path)
    assert name in str(info.value)


def test_corrupt_gzip_and_missing_file(tmp_path):
    (tmp_path / "c.off.gz").write_bytes(b"\x1f\x8b\x08\x00garbage")
    with pytest.raises(InvalidMeshError, match="corrupt gzip"):
        load_mesh(tmp_path / "c.off.gz")
    with pytest.raises(InvalidMeshError, match="no such file"):
        load_mesh(tmp_path / "nothere.off")
    good = gzip.compress(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    (tmp_path / "g.off.gz").write_bytes(good[: len(good) // 2])
    with pytest.raises(InvalidMeshError, match="gzip"):
        load_mesh(tmp_path / "g.off.gz")


def test_save_is_atomic_and_loses_nothing_on_failure(tmp_path):
    V, F = icosphere(1)
    target = save_mesh(tmp_path / "keep.off", V, F)
    before = target.read_bytes()
    with pytest.raises(InvalidMeshError):
        save_mesh(target, V, F + 1000)  # invalid: raises before touching the file
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.off"]


# ---------------------------------------------------------------- mesh_report


def test_report_of_a_closed_sphere():
    V, F = icosphere(2)
    rep = mesh_report(V, F)
    assert rep["closed"] and rep["components"] == 1 and rep["euler_characteristic"] == 2
    assert rep["boundary_edges"] == 0 and report_problems(rep) == []
    assert rep["area"] == pytest.approx(4 * np.pi, rel=0.02)


def test_report_finds_each_defect():
    V, F = grid_mesh(4, 4)  # open square: boundary of 4 * 3 edges
    rep = mesh_report(V, F)
    assert rep["boundary_edges"] == 12 and rep["components"] == 1
    # two squares touching at one corner: a pinched (non-manifold) vertex, one component
    V2 = np.vstack([V, V + [3, 3, 0]])
    F2 = np.vstack([F, F + 16])
    F2[F2 == 16] = 15
    rep2 = mesh_report(V2, F2)
    assert rep2["nonmanifold_vertices"] == [15] and rep2["components"] == 1
    assert rep2["unreferenced_vertices"] == 1
    # a fin: three faces on one edge, a duplicate face, a degenerate face, two components
    V3 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1],
                   [5, 5, 5], [6, 5, 5], [7, 5, 5]], float)
    F3 = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [0, 1, 2], [5, 6, 7]])
    rep3 = mesh_report(V3, F3)
    assert rep3["nonmanifold_edges"] == 1
    assert rep3["duplicate_faces"] == 1
    assert rep3["degenerate_faces"] == 1  # collinear 5, 6, 7
    assert rep3["components"] == 2


# ---------------------------------------------------------------- interop and k-NN


def test_interop_round_trips():
    import pymeshlab
    import trimesh

    from geoshape.io.interop import as_arrays, like

    V, F = icosphere(1)
    tm = trimesh.Trimesh(V, F, process=False)
    V1, F1 = as_arrays(tm)
    assert np.array_equal(V1, V) and np.array_equal(F1, F)
    pm = pymeshlab.Mesh(vertex_matrix=V, face_matrix=F)
    V2, F2 = as_arrays(pm)
    assert np.allclose(V2, V) and np.array_equal(F2, F)
    back = like(tm, V, F, colors=np.ones((len(V), 3)))
    assert isinstance(back, trimesh.Trimesh) and back.visual.vertex_colors[0, 0] == 255
    with pytest.raises(InvalidMeshError, match="expected"):
        as_arrays("not a mesh")


def test_interop_open3d():
    o3d = pytest.importorskip("open3d", reason="open3d extra not installed")
    from geoshape.io.interop import as_arrays, like

    V, F = icosphere(1)
    mesh = like(o3d.geometry.TriangleMesh(), V, F, colors=np.zeros((len(V), 3)))
    assert isinstance(mesh, o3d.geometry.TriangleMesh) and mesh.has_vertex_colors()
    V2, F2 = as_arrays(mesh)
    assert np.allclose(V2, V) and np.array_equal(F2, F)


def test_knn_backends_agree(rng):
    from geoshape.geometry.knn import KNNIndex, available_backends

    P, Q = rng.random((300, 5)), rng.random((40, 5))
    d_ref, i_ref = KNNIndex(P, "scipy").query(Q, k=4)
    brute = np.argsort(np.linalg.norm(Q[:, None] - P[None], axis=2), axis=1)[:, :4]
    assert np.array_equal(i_ref, brute)
    if "open3d" in available_backends():
        d, i = KNNIndex(P, "open3d").query(Q, k=4)
        assert np.array_equal(i, i_ref) and np.allclose(d, d_ref)
    with pytest.raises(InvalidOptionError, match="'scipy'"):
        KNNIndex(P, "flann")


# ---------------------------------------------------------------- datasets


def test_labels_and_pairs_readers(tmp_path):
    for name in ("a.off", "b.off"):
        (tmp_path / name).write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    (tmp_path / "labels.csv").write_text("file,label\na.off,x\nb.off,y\n")
    items = read_labels(tmp_path)
    assert [i.label for i in items] == ["x", "y"] and items[0].path.name == "a.off"
    (tmp_path / "a.vts").write_text("1\n3\n")
    (tmp_path / "b.vts").write_text("2\n1\n")
    (tmp_path / "pairs.csv").write_text(
        "source,target,source_landmarks,target_landmarks,target_symmetric_landmarks\n"
        "a.off,b.off,a.vts,b.vts,\na.off,b.off,,,\n"
    )
    pairs = read_pairs(tmp_path)
    assert pairs[0].source_landmarks.tolist() == [0, 2] and pairs[0].target_landmarks.tolist() == [1, 0]
    assert pairs[1].identity and not pairs[0].identity
    (tmp_path / "labels.csv").write_text("file,label\nmissing.off,x\n")
    with pytest.raises(DatasetError, match="missing.off"):
        read_labels(tmp_path)
    with pytest.raises(DatasetError, match="no such pairs file"):
        read_pairs(tmp_path / "nowhere")
    assert mesh_stem("dir/cat0.off.gz") == "cat0" and mesh_stem("x.PLY") == "x"


# ---------------------------------------------------------------- CLI


def test_cli_info_text_json_and_errors(tmp_path, capsys):
    import json

    from geoshape.__main__ import main

    V, F = icosphere(1)
    save_mesh(tmp_path / "s.off", V, F)
    assert main(["info", str(tmp_path / "s.off")]) == 0
    assert "none (closed 2-manifold)" in capsys.readouterr().out
    assert main(["info", "--json", str(tmp_path / "s.off")]) == 0
    rep = json.loads(capsys.readouterr().out)[0]
    assert rep["vertices"] == len(V) and rep["closed"]
    (tmp_path / "bad.off").write_text("OFF\n9 9 0\n")
    assert main(["info", str(tmp_path / "bad.off")]) == 2
    err = capsys.readouterr().err
    assert "bad.off" in err and "Traceback" not in err


# ---------------------------------------------------------------- real data


@pytest.mark.slow
@pytest.mark.data
@pytest.mark.parametrize("dataset", ["tosca_r5k", "tosca_hires", "scape"])
def test_info_over_real_sets_reports_manifest_defects(dataset):
    folder = shared_dataset(dataset)
    reports = {}
    for path in sorted(folder.rglob("*.off.gz")):
        V, F = load_mesh(path)
        reports[mesh_stem(path)] = mesh_report(V, F, name=str(path))
    assert reports, f"no meshes found in {folder}"
    if dataset == "tosca_hires":
        assert all(reports[f"cat{i}"]["boundary_edges"] == 76 for i in range(11))
        assert all(reports[k]["boundary_edges"] == 52 for k in reports if k.startswith("dog"))
        assert reports["gorilla1"]["boundary_edges"] == 6
        assert reports["horse0"]["closed"] and reports["centaur0"]["closed"]
    elif dataset == "scape":
        assert len(reports) == 71
        assert all(r["nonmanifold_vertices"] == [419] for r in reports.values())
        assert all(r["euler_characteristic"] == 1 and r["boundary_edges"] == 0 for r in reports.values())
    else:
        assert len(reports) == 76
        assert reports["victoria10"]["boundary_edges"] == 20
        assert sum(r["boundary_edges"] > 0 for r in reports.values()) == 1
        assert all(r["components"] == 1 and r["n_nonmanifold_vertices"] == 0 for r in reports.values())
