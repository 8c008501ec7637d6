"""Native code is never handed a mesh it cannot take: preconditions refused or repaired."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geoshape.errors import InvalidMeshError
from geoshape.geometry.geodesics import GeodesicSolver, exact_geodesic_problems


def _sphere():
    m = trimesh.creation.icosphere(subdivisions=2)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_exact_geodesic_problems_counts_each_defect():
    V, F = _sphere()
    assert exact_geodesic_problems(V, F) == []
    assert exact_geodesic_problems(V, np.vstack([F, F[:3]]))[0] == "3 duplicate faces"
    repeated = np.vstack([F, [[F[0, 0], F[0, 0], F[0, 1]]]])
    assert exact_geodesic_problems(V, repeated)[0] == "1 degenerate face"
    pinned = np.vstack([V, [[3.0, 3.0, 3.0]]])
    assert exact_geodesic_problems(pinned, np.vstack([F, [[F[0, 0], F[0, 1], len(V)]]])) == [
        "1 non-manifold edge"
    ]


def test_exact_geodesics_refuse_a_defective_mesh_before_calling_libigl():
    V, F = _sphere()
    with pytest.raises(InvalidMeshError, match="exact geodesics need a manifold mesh.*2 duplicate faces"):
        GeodesicSolver(V, np.vstack([F, F[:2]]), "exact").distances([0])
    # the heat method (intrinsic, robust Laplacian) takes the same mesh
    d = GeodesicSolver(V, np.vstack([F, F[:2]]), "heat").distances([0])
    assert np.all(np.isfinite(d))


def test_a_zero_area_face_does_not_poison_the_descriptor_map():
    from geoshape.correspondence.mesh_matching import correspond

    V, F = _sphere()
    Vz = np.vstack([V, V[F[0, 0]], V[F[0, 0]]])
    Fz = np.vstack([F, [[len(V), len(V) + 1, F[0, 0]]]])
    c = correspond(Vz, Fz, V, F)
    assert c.p2p_12.shape == (len(Vz),)
    # the sphere's own vertices keep a sensible map: an isometry of the sphere (any rotation
    # is one, so not necessarily the identity), which keeps orientation; a scrambled map
    # changes the distances by about 0.5 on average
    p2p = c.p2p_12[: len(V)]
    D, D_mapped = (np.linalg.norm(X[:, None] - X[None], axis=2) for X in (V, V[p2p]))
    assert np.mean(np.abs(D - D_mapped)) < 0.05
    assert c.details["orientation"] > 0.5


def test_a_folder_given_as_a_mesh_is_named_as_such(tmp_path):
    from geoshape.io.mesh_io import load_mesh

    with pytest.raises(InvalidMeshError, match="is a folder, expected a mesh file"):
        load_mesh(tmp_path)


def test_correspond_names_the_meshes_it_refuses(capsys, tmp_path):
    from geoshape.__main__ import main

    (tmp_path / "tri.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    V, F = _sphere()
    from geoshape.io.mesh_io import save_mesh

    save_mesh(tmp_path / "ok.off", V, F)
    assert (
        main(
            ["correspond", str(tmp_path / "tri.off"), str(tmp_path / "ok.off"), "-o", str(tmp_path / "m.txt")]
        )
        == 2
    )
    assert f"{tmp_path / 'tri.off'}: 3 vertices is too few" in capsys.readouterr().err


def test_a_corrupt_stl_is_named_as_such_even_without_optional_text_decoders(tmp_path, monkeypatch):
    import builtins
    import struct

    from geoshape.io.mesh_io import load_mesh

    real_import = builtins.__import__

    def no_charset_normalizer(name, *args, **kwargs):
        if name.startswith("charset_normalizer"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_charset_normalizer)
    path = tmp_path / "cut.stl"
    path.write_bytes(b"solid " + b"\xff" * 74 + struct.pack("<I", 10) + b"\0" * 50)
    with pytest.raises(InvalidMeshError, match="cut.stl: cannot parse STL file: truncated or corrupt"):
        load_mesh(path)
