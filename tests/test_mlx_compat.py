"""MeshLab .mlx compatibility: scripts as users wrote them run through geoshape as in PyMeshLab.

tests/data/mlx holds scripts in the styles people have: MeshLab 2023 exports (documentation
attributes, escaped entities, XML names PyMeshLab renames such as ``lambda``), MeshLab
1.3.4 / 2016.12 / 2020 exports with old filter and parameter names, MeshLab 2016's
``<xmlfilter>``, hand-written partial lists, every Rich* type, two-mesh filters, and
geoshape filters mixed with PyMeshLab's. Each must run; where PyMeshLab's own
``load_filter_script`` + ``apply_filter_script`` runs the script, the result must be the
same mesh; where it cannot (old names, ``<xmlfilter>``), PyMeshLab replaying the script
geoshape saved (current names, every value) must give geoshape's mesh.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

pymeshlab = pytest.importorskip("pymeshlab")

from geoshape_plugins.meshlab_legacy import LEGACY_FILTER_NAMES, LEGACY_PARAM_NAMES  # noqa: E402
from geoshape_plugins.meshset import MeshSet  # noqa: E402
from geoshape_plugins.mlx import FilterScriptError, parse_mlx, read_mlx  # noqa: E402
from geoshape_plugins.mlx_compat import compare_with_pymeshlab, same_mesh  # noqa: E402
from geoshape_plugins.pymeshlab_bridge import resolve_pymeshlab_name  # noqa: E402
from geoshape_plugins.pymeshlab_names import python_param_name, recorded_filters  # noqa: E402

from geoshape.io.mesh_io import save_mesh  # noqa: E402

SCRIPTS = sorted((Path(__file__).parent / "data" / "mlx").glob("*.mlx"))


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """A sphere with a hole and a duplicate face, and a second, coarser sphere."""
    import trimesh

    folder = tmp_path_factory.mktemp("mlx")
    s = trimesh.creation.icosphere(4)
    F = np.vstack([s.faces[10:], s.faces[:1]])
    save_mesh(folder / "a.ply", s.vertices, F)
    t = trimesh.creation.icosphere(3)
    save_mesh(folder / "b.ply", t.vertices * 1.05 + [0.02, 0.0, 0.0], t.faces)
    return folder / "a.ply", folder / "b.ply"


def _inputs(script: Path, meshes) -> list[Path]:
    return list(meshes) if "two_mesh" in script.name else [meshes[0]]


def _geoshape(script, inputs) -> MeshSet:
    ms = MeshSet()
    for path in inputs:
        ms.load_new_mesh(path)
    ms.set_current_mesh(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ms.apply_filter_script(script)
    return ms


def test_there_are_at_least_twelve_scripts():
    assert len(SCRIPTS) >= 12


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.stem for s in SCRIPTS])
def test_script_runs_as_in_pymeshlab(script, meshes):
    result = compare_with_pymeshlab(script, _inputs(script, meshes))
    assert not result.error and result.filters > 0
    if result.reference != "none (geoshape filters)":
        assert result.same, result
    if script.stem.startswith(("meshlab134", "meshlab2016_quadric")):
        assert result.pymeshlab.startswith("refuses")  # old names: geoshape runs what PyMeshLab cannot


def test_same_mesh_ignores_face_order_but_not_orientation():
    V = np.eye(4)[:, :3]
    F = np.array([[0, 1, 2], [1, 3, 2]])
    assert same_mesh(V, F, V, F[::-1]) and same_mesh(V, F, V, np.roll(F, 1, axis=1))
    assert not same_mesh(V, F, V, F[:, ::-1]) and not same_mesh(V, F, V + 1e-6, F)


def test_mixed_script_runs_geoshape_and_pymeshlab_filters(meshes):
    script = next(s for s in SCRIPTS if s.stem == "mixed_geoshape_pymeshlab")
    ms = _geoshape(script, [meshes[0]])
    origins = [a.origin for a in ms.history]
    assert origins == ["geoshape", "pymeshlab", "geoshape", "pymeshlab", "pymeshlab", "geoshape"]
    before, after = ms.history[0].outputs, ms.history[-1].outputs
    assert before["faces"] == 5111 and after["faces"] < 1000 and ms.history[2].outputs["n_sources"] == 1
    # PyMeshLab selected by the geodesic distance geoshape stored as quality: a hole opened
    assert before["boundary_edges"] < after["boundary_edges"]


def test_left_out_parameters_take_defaults_not_earlier_values(meshes):
    script = next(s for s in SCRIPTS if s.stem == "hand_partial_params")
    ms = _geoshape(script, [meshes[0]])
    recorded = [{p.name: p.attrs["value"] for p in a.script.params} for a in ms.history]
    assert recorded[0]["PreserveNormal"] == "true" and recorded[0]["TargetFaceNum"] == "1500"
    assert recorded[1]["PreserveNormal"] == "false"  # MeshLab's default, not the value of call 1
    assert recorded[2]["stepSmoothNum"] == "2" and recorded[3]["stepSmoothNum"] == "3"


def test_xml_names_pymeshlab_renames_are_translated():
    # MeshLab writes <Param name="lambda">; PyMeshLab's Python name is lambda_
    script = parse_mlx('<FilterScript><filter name="Taubin Smooth"><Param name="lambda" value="0.6" '
                       'type="RichFloat"/><Param name="stepSmoothNum" value="1" type="RichInt"/></filter>'
                       '</FilterScript>')
    import trimesh

    s = trimesh.creation.icosphere(2)
    ms = MeshSet()
    ms.add_mesh(s.vertices, s.faces)
    ms.apply_filter_script(script)
    values = {p.name: p.attrs["value"] for p in ms.history[0].script.params}
    assert float(values["lambda"]) == pytest.approx(0.6) and values["stepSmoothNum"] == "1"


def test_old_parameter_names_are_renamed_and_dropped_ones_warned(meshes):
    pose = next(s for s in SCRIPTS if s.stem == "meshlab201612_normalize_pose")
    ms = _geoshape(pose, [meshes[0]])
    translate = {p.name: p.attrs.get("value") for p in ms.history[2].script.params}
    assert ms.history[2].script.id == "compute_matrix_from_translation"
    assert translate["traslMethod"] == "1"  # centerFlag=true -> "Center on Scene BBox"
    V = ms.current_mesh().V
    np.testing.assert_allclose((V.max(0) + V.min(0)) / 2, 0, atol=1e-6)
    np.testing.assert_allclose(V.max(0) - V.min(0), [4, 4, 2], atol=0.05)  # scaled 2x, z halved
    cluster = next(s for s in SCRIPTS if s.stem == "meshlab134_select_cluster")
    ms = MeshSet()
    ms.load_new_mesh(meshes[0])
    with pytest.warns(UserWarning, match=r"meshlab134_select_cluster.mlx:\d+: .*ignores 'strictSelect' "
                      r"\(a parameter of older MeshLab versions"):
        ms.apply_filter_script(cluster)


def test_unknown_filter_names_the_line_and_the_closest_names(meshes):
    script = parse_mlx("<FilterScript>\n <filter name='Remove Duplicate Faces'/>\n"
                       " <filter name='Quadric Edge Colapse Decimation'/>\n</FilterScript>", "s.mlx")
    ms = MeshSet()
    ms.load_new_mesh(meshes[0])
    with pytest.raises(FilterScriptError, match=r"s.mlx:3: unknown filter 'Quadric Edge Colapse "
                       r"Decimation'.*closest known names: 'Quadric Edge Collapse Decimation'"):
        ms.apply_filter_script(script, source="s.mlx")
    assert ms.history == []  # checked before anything ran


def test_documentation_attributes_and_entities_are_read(meshes):
    script = read_mlx(next(s for s in SCRIPTS if s.stem == "meshlab2016_xmlfilter"))
    assert script[1].params[0].attrs["value"] == "(x0 > 0) && (y0 < 0.5)"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # MeshLab's own attributes pass silently
        read_mlx(next(s for s in SCRIPTS if s.stem == "meshlab2023_taubin_decimate"))


def test_recorded_display_names_match_the_installed_pymeshlab():
    table = recorded_filters()
    if not table:
        pytest.skip("no recorded PyMeshLab filter table")
    names = set(pymeshlab.filter_list())
    missing = sorted(set(table) - names)
    assert not missing, f"recorded filters PyMeshLab no longer has (re-record the table): {missing}"
    for pyname, entry in table.items():
        assert resolve_pymeshlab_name(entry["name"]) == pyname, entry["name"]


def test_xml_parameter_rule_holds_for_every_recorded_filter():
    ms = pymeshlab.MeshSet()
    ms.create_sphere(subdiv=1)
    ms.create_sphere(subdiv=1)
    checked = 0
    for pyname, entry in recorded_filters().items():
        try:
            python = list(ms.filter_parameter_values(pyname))
        except pymeshlab.PyMeshLabException:
            continue
        assert python == [python_param_name(x) for x in entry["params"]], pyname
        checked += 1
    assert checked > 150


def test_legacy_names_resolve_to_existing_filters_and_parameters():
    names = set(pymeshlab.filter_list())
    for old, new in LEGACY_FILTER_NAMES.items():
        assert new in names and resolve_pymeshlab_name(old) == new, old
    for pyname, renames in LEGACY_PARAM_NAMES.items():
        xml = recorded_filters().get(pyname, {}).get("params")
        if xml:
            assert set(renames.values()) <= set(xml), pyname


def test_run_command_runs_an_old_meshlab_script(meshes, tmp_path, capsys):
    from geoshape.__main__ import main

    script = next(s for s in SCRIPTS if s.stem == "meshlab134_cleanup_chain")
    out = tmp_path / "out.ply"
    code = main(["run", "-i", str(meshes[0]), "-o", str(out), "-s", str(script),
                 "--save-script", str(tmp_path / "used.mlx")])
    assert code == 0 and out.exists()
    assert "meshing_decimation_quadric_edge_collapse (pymeshlab)" in capsys.readouterr().out
    assert 'name="Simplification: Quadric Edge Collapse Decimation"' in (tmp_path / "used.mlx").read_text()
