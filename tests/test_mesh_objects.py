"""Library entry points take other libraries' mesh objects and give the same results as arrays."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geoshape.correspondence.mesh_matching import correspond
from geoshape.errors import InvalidMeshError
from geoshape.retrieval.descriptors import descriptor_params
from geoshape.spectral.embedding import spectral_embedding


def _pair():
    m = trimesh.creation.icosphere(subdivisions=2)
    V1 = np.asarray(m.vertices) * [1.0, 0.8, 0.6]
    rng = np.random.default_rng(0)
    perm = rng.permutation(len(V1))
    V2 = V1[perm] @ np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    inv = np.argsort(perm)
    return V1, np.asarray(m.faces), V2, inv[np.asarray(m.faces)]


def _as(kind, V, F):
    if kind == "tuple":
        return (V, F)
    if kind == "trimesh":
        return trimesh.Trimesh(V, F, process=False)
    if kind == "open3d":
        o3d = pytest.importorskip("open3d", reason="the open3d extra is not installed")
        return o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F))
    pymeshlab = pytest.importorskip("pymeshlab")
    mesh = pymeshlab.Mesh(vertex_matrix=V, face_matrix=F)
    if kind == "meshset":
        ms = pymeshlab.MeshSet()
        ms.add_mesh(mesh)
        return ms
    return mesh


KINDS = ["tuple", "trimesh", "open3d", "pymeshlab", "meshset"]
#: the type each kind comes back as
TYPE_NAMES = {"tuple": "tuple", "trimesh": "Trimesh", "open3d": "TriangleMesh", "pymeshlab": "Mesh",
              "meshset": "MeshSet"}


@pytest.mark.parametrize("kind", ["tuple", "trimesh", "open3d", "pymeshlab"])
def test_correspond_takes_mesh_objects_and_gives_the_array_map(kind):
    V1, F1, V2, F2 = _pair()
    expected = correspond(V1, F1, V2, F2, method="rigid-icp").p2p_12
    got = correspond(_as(kind, V1, F1), _as(kind, V2, F2), method="rigid-icp").p2p_12
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("kind", ["tuple", "trimesh", "open3d", "pymeshlab"])
def test_spectral_embedding_takes_mesh_objects(kind):
    V, F, _, _ = _pair()
    expected = spectral_embedding(V, F, k=4).coords
    np.testing.assert_allclose(spectral_embedding(_as(kind, V, F), k=4).coords, expected, atol=1e-12)


def test_an_unknown_object_is_named_in_the_error():
    V1, F1, _, _ = _pair()
    with pytest.raises(InvalidMeshError, match="source mesh: expected .V, F. arrays, a trimesh.*got dict"):
        correspond({"v": 1}, trimesh.Trimesh(V1, F1, process=False))


# ---------------------------------------------------------------- every (V, F) entry point


def _mesh():
    """A small mesh whose vertex order is not trimesh's (a permutation), so order counts."""
    V, F, _, _ = _pair()
    perm = np.random.default_rng(1).permutation(len(V))
    return V[perm], np.argsort(perm)[F]


@pytest.mark.parametrize("kind", KINDS)
def test_descriptors_give_the_array_vector(kind):
    from geoshape.retrieval.descriptors import MESH_DESCRIPTORS, compute_descriptor, d2_descriptor
    from geoshape.retrieval.descriptors.evd import evd_descriptor

    V, F = _mesh()
    obj = _as(kind, V, F)
    for name in ("d2", "shapedna", "evd_heat"):
        np.testing.assert_array_equal(compute_descriptor(obj, name), compute_descriptor(V, F, name))
    np.testing.assert_array_equal(MESH_DESCRIPTORS["shd"].compute(obj), MESH_DESCRIPTORS["shd"].compute(V, F))
    np.testing.assert_array_equal(evd_descriptor(obj, config="heat"), evd_descriptor(V, F, config="heat"))
    np.testing.assert_array_equal(d2_descriptor(V=obj, bins=8), d2_descriptor(V, F, bins=8))


@pytest.mark.parametrize("kind", KINDS)
def test_geodesics_report_and_basis_take_mesh_objects(kind):
    from geoshape.geometry.geodesics import GeodesicSolver, all_pairs_geodesics, geodesic_distances
    from geoshape.geometry.report import mesh_report
    from geoshape.geometry.sampling import farthest_point_sampling
    from geoshape.spectral.laplacian import laplacian_basis

    V, F = _mesh()
    obj = _as(kind, V, F)
    np.testing.assert_array_equal(geodesic_distances(obj, [0, 7]), geodesic_distances(V, F, [0, 7]))
    np.testing.assert_array_equal(all_pairs_geodesics(obj), all_pairs_geodesics(V, F))
    np.testing.assert_array_equal(GeodesicSolver(obj, "heat").distances([3]),
                                  GeodesicSolver(V, F, "heat").distances([3]))
    assert mesh_report(obj, name="x") == mesh_report(V, F, name="x")
    np.testing.assert_array_equal(farthest_point_sampling(obj, 5)[0], farthest_point_sampling(V, F, 5)[0])
    np.testing.assert_array_equal(laplacian_basis(obj, 6).evecs, laplacian_basis(V, F, 6).evecs)


def test_plain_arrays_and_lists_of_vertices_are_not_taken_for_a_mesh():
    from geoshape.io.interop import is_mesh_object

    V, F = _mesh()
    assert is_mesh_object((V, F)) and is_mesh_object([V.tolist(), F.tolist()])
    assert not is_mesh_object(V) and not is_mesh_object(V[:2].tolist()) and not is_mesh_object(F[:2].tolist())
    assert not is_mesh_object([(V, F), (V, F)]) and not is_mesh_object(["a.off", "b.off"])
    with pytest.raises(InvalidMeshError, match="F is given with a mesh object"):
        from geoshape.geometry.report import mesh_report

        mesh_report(trimesh.Trimesh(V, F, process=False), F=F)


# ---------------------------------------------------------------- generators: the caller's kind back


@pytest.mark.parametrize("kind", KINDS)
def test_generators_return_the_callers_kind_with_the_array_results(kind):
    from geoshape_datasets_gen.decimate import decimate_exact, decimation_ladder
    from geoshape_datasets_gen.spikes import add_spikes
    from geoshape_datasets_gen.stretch import stretch_axes, stretch_part

    from geoshape.io.interop import as_arrays

    V, F = _mesh()
    obj = _as(kind, V, F)

    def same(mesh, V_expected, F_expected):
        assert type(mesh).__name__ == TYPE_NAMES[kind]
        V_got, F_got = as_arrays(mesh)
        np.testing.assert_array_equal(V_got, V_expected)
        np.testing.assert_array_equal(F_got, F_expected)

    s, s0 = add_spikes(obj, 5, 0.1, seed=3), add_spikes(V, F, 5, 0.1, seed=3)
    np.testing.assert_array_equal(s.faces, s0.faces)
    same(s.mesh, s0.V, s0.F)
    same(stretch_axes(obj, [2.0, 1.0, 0.5]), stretch_axes(V, F, [2.0, 1.0, 0.5]), F)
    p = stretch_part(obj, radius=0.3, factor=1.5, center=0)
    same(p.mesh, stretch_part(V, F, radius=0.3, factor=1.5, center=0).V, F)
    d, d0 = decimate_exact(obj, 0.5), decimate_exact(V, F, 0.5)
    np.testing.assert_array_equal(d.orig_ids, d0.orig_ids)
    same(d.mesh, d0.V, d0.F)
    ladder = decimation_ladder(obj, (0.75, 0.5))
    same(ladder[1].mesh, d0.V, d0.F)


def test_generators_given_arrays_keep_returning_arrays():
    from geoshape_datasets_gen.spikes import add_spikes
    from geoshape_datasets_gen.stretch import stretch_axes

    V, F = _mesh()
    assert isinstance(stretch_axes(V, F, [2, 1, 1]), np.ndarray)
    s = add_spikes(V, F, 3, 0.1)
    assert isinstance(s.mesh, tuple) and s.mesh[0] is s.V and s.mesh[1] is s.F


# ---------------------------------------------------------------- the index and the all-pairs matrix


def _files(tmp_path, n=3):
    """``n`` mesh files and the arrays read back from them (what a file gives the index)."""
    from geoshape.io.mesh_io import load_mesh, save_mesh

    out = []
    for k in range(n):
        m = trimesh.creation.icosphere(2) if k % 2 == 0 else trimesh.creation.capsule(1.0, 0.4)
        path = tmp_path / "m" / f"shape{k}.off"
        path.parent.mkdir(exist_ok=True)
        save_mesh(path, np.asarray(m.vertices) * [1.0, 1.0 + 0.3 * k, 1.0], m.faces)
        out.append((path, *load_mesh(path)))
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_index_add_of_mesh_objects_stores_and_finds_what_files_give(tmp_path, kind):
    from geoshape.retrieval.index import ShapeIndex

    files = _files(tmp_path)
    names = [f"obj{k}" for k in range(len(files))]
    params = descriptor_params("d2")
    with ShapeIndex(tmp_path / "files.db") as a, ShapeIndex(tmp_path / "objs.db") as b:
        assert a.add([tmp_path / "m"], ["d2"], backend="serial").added == 3
        rep = b.add([_as(kind, V, F) for _, V, F in files], ["d2"], names=names, backend="serial")
        assert (rep.added, rep.failed) == (3, [])
        paths, X = a.load("d2", params)
        keys, Y = b.load("d2", params)
        assert keys == names
        by_path = dict(zip(paths, X, strict=True))
        for (path, _, _), y in zip(files, Y, strict=True):
            np.testing.assert_array_equal(y, by_path[str(path.resolve())])
        _, V, F = files[1]
        hits_a, _ = a.query_mesh(V, F, "d2", top=3)
        hits_b, _ = b.query_mesh(_as(kind, V, F), "d2", top=3)
        name_of = {str(path.resolve()): nm for (path, _, _), nm in zip(files, names, strict=True)}
        assert [h.path for h in hits_b] == [name_of[h.path] for h in hits_a]
        assert [h.distance for h in hits_b] == [h.distance for h in hits_a]
        # unchanged geometry is skipped, like an unchanged file
        again = b.add([_as(kind, V, F) for _, V, F in files], ["d2"], names=names, backend="serial")
        assert (again.added, again.skipped) == (0, 3)


def test_index_names_unnamed_meshes_by_content_and_keeps_them_on_prune(tmp_path):
    from geoshape.io.interop import mesh_content_sha256
    from geoshape.retrieval.index import ShapeIndex

    (path, V, F), (_, V1, F1) = _files(tmp_path, 2)
    tm = trimesh.Trimesh(V1, F1, process=False)
    with ShapeIndex(tmp_path / "idx.db") as idx:
        rep = idx.add([path, tm, (V1, F1)], ["d2"], backend="serial")
        assert (rep.added, rep.skipped) == (2, 0)  # the two objects are one geometry
        key = f"mesh-{mesh_content_sha256(V1, F1)[:16]}"
        assert sorted(idx.load("d2", descriptor_params("d2"))[0]) == sorted([str(path.resolve()), key])
        assert idx.add({"cat": tm}, ["d2"], backend="serial").added == 1
        assert idx.add(tm, ["d2"], backend="serial").skipped == 1
        path.unlink()
        assert idx.prune() == [str(path.resolve())]
        hits, _ = idx.query_mesh(tm, "d2", top=5)
        assert sorted(h.path for h in hits) == sorted([key, "cat"]) and hits[0].distance == 0.0


def test_index_add_refuses_bad_names_and_reports_bad_meshes(tmp_path):
    from geoshape.errors import InvalidOptionError
    from geoshape.retrieval.index import ShapeIndex

    V, F = _mesh()
    tm = trimesh.Trimesh(V, F, process=False)
    with ShapeIndex(tmp_path / "idx.db") as idx:
        for inputs, names, match in [([tm, tm], ["a", "a"], "given twice"), ([tm], ["/abs/x"], "absolute"),
                                     ([tm], ["a", "b"], "one entry per input"),
                                     ([tmp_path], ["a"], "is a path")]:
            with pytest.raises(InvalidOptionError, match=match):
                idx.add(inputs, ["d2"], names=names, backend="serial")
        with pytest.raises(InvalidMeshError, match="input 0: expected"):
            idx.add([{"v": 1}], ["d2"], backend="serial")
        bad = (np.zeros((3, 3)), np.zeros((0, 3), int))
        rep = idx.add([bad, tm], ["d2"], names=["flat", "ok"], backend="serial")
        assert rep.added == 1 and rep.failed[0][0] == "flat" and "no faces" in rep.failed[0][1]


def test_all_pairs_retrieval_takes_mesh_objects(tmp_path):
    from geoshape.retrieval.meshes import retrieval3d_matrix

    files = _files(tmp_path)
    D_files = retrieval3d_matrix([p for p, _, _ in files], "d2", backend="serial", progress=False)["D"]
    objs = [trimesh.Trimesh(V, F, process=False) for _, V, F in files[:2]] + [files[2][0]]
    np.testing.assert_array_equal(retrieval3d_matrix(objs, "d2", backend="serial", progress=False)["D"],
                                  D_files)


# ---------------------------------------------------------------- the plugins' MeshSet


@pytest.mark.parametrize("kind", KINDS)
def test_meshset_takes_each_kind_and_gives_each_kind_back(kind):
    from geoshape_plugins import MeshSet

    from geoshape.io.interop import as_arrays

    V, F = _mesh()
    ms = MeshSet()
    assert ms.add_mesh(_as(kind, V, F), name="m") == 0
    np.testing.assert_array_equal(ms.current_mesh().V, V)
    np.testing.assert_array_equal(ms.current_mesh().F, F)
    assert ms.current_mesh().name == "m"
    ref = MeshSet()
    ref.add_mesh(V, F)
    out = ms.geodesic_distance_from_selection(sources=[0])
    assert out == ref.geodesic_distance_from_selection(sources=[0])
    back_kind = {"tuple": "arrays", "meshset": "pymeshlab_meshset"}.get(kind, kind)
    back = ms.current_mesh_as(back_kind)
    assert type(back).__name__ == TYPE_NAMES[kind]
    V2, F2 = as_arrays(back)
    np.testing.assert_array_equal(V2, V)
    np.testing.assert_array_equal(F2, F)
