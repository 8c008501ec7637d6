"""MeshLab-style filters: registry, generated MeshSet methods, .mlx scripts, runner, docs."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import icosphere, shared_dataset
from geoshape_plugins.meshset import MeshSet
from geoshape_plugins.mlx import FilterScriptError, mlx_text, parse_mlx, read_mlx
from geoshape_plugins.params import AbsoluteValue, FilterError, FilterParameterError
from geoshape_plugins.registry import list_filters

REPO = Path(__file__).resolve().parents[1]


def _rotation(seed=0):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _two_spheres(subdivisions=2):
    V, F = icosphere(subdivisions)
    ms = MeshSet()
    ms.add_mesh(V, F, name="a")
    ms.add_mesh(1.3 * V @ _rotation().T, F, name="b")
    ms.set_current_mesh(0)
    sel = np.zeros(len(V), bool)
    sel[[0, 7]] = True
    ms.current_mesh().selection = sel
    return ms


# ---- every filter with its defaults --------------------------------------------------
CHECKS = {
    "geodesic_distance_from_selection": lambda ms, out: (
        ms.current_mesh().quality[[0, 7]].tolist() == [0.0, 0.0] and out["n_sources"] == 2
    ),
    "spectral_embedding": lambda ms, out: (
        ms.current_mesh().attributes["spectral_embedding"].shape == (162, 5)
        and np.allclose(ms.current_mesh().V, ms.current_mesh().attributes["spectral_embedding"][:, :3])
    ),
    "eigenvector_colormap": lambda ms, out: ms.current_mesh().colors.shape == (162, 4),
    "spectral_correspondence": lambda ms, out: (
        ms.current_mesh().attributes["correspondence"].shape == (42,)
        and ms.current_mesh().colors.shape == (42, 4) and out["colored_target"]
    ),
    "decimate_with_ground_truth": lambda ms, out: np.array_equal(
        ms.current_mesh().V, icosphere(2)[0][ms.current_mesh().attributes["original_ids"]]
    ),
    "outlier_spikes": lambda ms, out: int(ms.current_mesh().attributes["is_spike"].sum()) == 20,
    "evd_descriptor": lambda ms, out: out["evd"].shape == (20,) and np.all(np.diff(out["evd"]) <= 0),
    "mesh_report": lambda ms, out: out["vertices"] == 162 and out["closed"],
    "change_current_mesh": lambda ms, out: ms.current_index == 0,
}


def test_every_filter_has_a_check():
    assert sorted(CHECKS) == sorted(f.id for f in list_filters())


@pytest.mark.parametrize("filter_id", sorted(CHECKS))
def test_filter_runs_with_defaults(filter_id):
    # the default correspondence method is the slowest: a smaller sphere for it
    ms = _two_spheres(1 if filter_id == "spectral_correspondence" else 2)
    out = getattr(ms, filter_id)()
    assert isinstance(out, dict)
    assert CHECKS[filter_id](ms, out)
    assert ms.history[-1].script.id == filter_id


def test_generated_methods_have_signature_and_doc():
    import inspect

    sig = inspect.signature(MeshSet.outlier_spikes)
    assert list(sig.parameters)[1:] == ["count", "height", "seed"]
    assert "Jain and Zhang" in MeshSet.outlier_spikes.__doc__


def test_meshset_is_exposed_lazily_by_the_plugin_package_not_the_core():
    import geoshape_plugins

    import geoshape

    assert geoshape_plugins.MeshSet is MeshSet
    assert not hasattr(geoshape, "MeshSet")


# ---- parameter validation ----------------------------------------------------------
@pytest.mark.parametrize(
    "params, match",
    [
        ({"cout": 3}, r"parameter 'cout' not found for filter 'outlier_spikes'; valid parameters: "
                      r"count, height, seed"),
        ({"count": "5"}, r"'count': expected an int, got '5'"),
        ({"count": 2.0}, r"'count': expected an int, got 2.0"),
        ({"count": True}, r"'count': expected an int, got True"),
        ({"count": -1}, r"'count': must lie in \[0, inf\], got -1"),
        ({"height": 150.0}, r"'height': must lie in \[0, 100\], got 150.0"),
        ({"height": -2}, r"'height': must lie in \[0, 100\], got -2"),
        ({"height": float("nan")}, r"'height': must be finite"),
        ({"height": AbsoluteValue(-1.0)}, r"absolute length must be finite and >= 0"),
    ],
)
def test_bad_parameters_are_rejected(params, match):
    ms = _two_spheres()
    with pytest.raises(FilterParameterError, match=match):
        ms.outlier_spikes(**params)
    assert ms.history == []


def test_enum_and_bool_errors_list_what_is_allowed():
    ms = _two_spheres()
    with pytest.raises(FilterParameterError, match=r"must be one of 'graph', 'heat', 'exact'; got 'fast'"):
        ms.geodesic_distance_from_selection(method="fast")
    with pytest.raises(FilterParameterError, match=r"expected a bool, got 1"):
        ms.decimate_with_ground_truth(preserve_boundary=1)
    with pytest.raises(FilterParameterError, match=r"expected a mesh index"):
        ms.spectral_correspondence(target=-1)
    with pytest.raises(FilterParameterError, match=r"expected a list of ints"):
        ms.geodesic_distance_from_selection(sources="0 1")


def test_percentage_accepts_absolute_lengths():
    ms = _two_spheres()
    out = ms.outlier_spikes(count=3, height=AbsoluteValue(0.5))
    assert out["height"] == pytest.approx(0.5)
    out = _two_spheres().outlier_spikes(count=3, height=10.0)
    assert out["height"] == pytest.approx(0.1 * _two_spheres().current_mesh().bbox_diagonal())


def test_preconditions_and_filter_errors():
    V, F = icosphere(1)
    ms = MeshSet()
    ms.add_mesh(V, F)
    with pytest.raises(FilterError, match="needs two meshes"):
        ms.spectral_correspondence()
    with pytest.raises(FilterError, match="no source vertices"):
        ms.geodesic_distance_from_selection()
    with pytest.raises(FilterError, match="out of range"):
        ms.geodesic_distance_from_selection(sources=[10_000])
    ms.add_mesh(V, np.zeros((0, 3), int), name="cloud")
    with pytest.raises(FilterError, match="needs a mesh with faces: current mesh 'cloud' has no faces"):
        ms.outlier_spikes()
    with pytest.raises(FilterError, match="MeshSet is empty"):
        MeshSet().mesh_report()
    with pytest.raises(FilterError, match="unknown filter 'no_such_filter'"):
        ms.apply_filter("no_such_filter")


def test_precomputations_are_cached_and_dropped_with_the_geometry():
    ms = _two_spheres()
    ms.geodesic_distance_from_selection(method="heat")
    mesh = ms.current_mesh()
    solver = mesh._cache[("geodesic_solver", "heat")]
    ms.geodesic_distance_from_selection(sources=[3], method="heat")
    assert mesh._cache[("geodesic_solver", "heat")] is solver
    ms.outlier_spikes(count=2)
    assert mesh._cache == {}


# ---- PyMeshLab delegation ------------------------------------------------------------
def test_pymeshlab_filter_by_python_and_display_name():
    ms = _two_spheres(3)
    ms.apply_filter("meshing_decimation_quadric_edge_collapse", targetfacenum=400, preservetopology=True)
    assert ms.current_mesh().face_number() == 400
    rec = ms.history[-1].script
    assert rec.id == "meshing_decimation_quadric_edge_collapse"
    assert rec.name == "Simplification: Quadric Edge Collapse Decimation"
    assert len(rec.params) == 13  # every parameter recorded
    ms.apply_filter("Simplification: Quadric Edge Collapse Decimation", TargetFaceNum=200)
    assert ms.current_mesh().face_number() == 200
    with pytest.raises(FilterParameterError,
                       match="parameter 'bogus' not found .* valid parameters: targetfacenum"):
        ms.apply_filter("meshing_decimation_quadric_edge_collapse", bogus=1)


def test_save_current_mesh_writes_colors(tmp_path):
    import trimesh

    ms = _two_spheres()
    ms.eigenvector_colormap(index=1)
    path = ms.save_current_mesh(tmp_path / "c.ply")
    m = trimesh.load(path, process=False)
    expected = np.round(ms.current_mesh().colors * 255).astype(np.uint8)
    assert np.array_equal(np.asarray(m.visual.vertex_colors), expected)


# ---- scripts -------------------------------------------------------------------------
def test_mlx_round_trip(tmp_path):
    ms = _two_spheres()
    ms.outlier_spikes(count=4, height=2.5, seed=3)
    ms.geodesic_distance_from_selection(sources=[1, 2], method="heat")
    ms.spectral_embedding(k=3, output="attribute", scaling="none")
    ms.mesh_report()
    path = ms.save_filter_script(tmp_path / "s.mlx")
    read = read_mlx(path)
    assert [(f.id, f.name) for f in read] == [(a.script.id, a.script.name) for a in ms.history]
    from geoshape_plugins.registry import get_filter

    for sf, applied in zip(read, ms.history, strict=True):
        f = get_filter(sf.id)
        values = {p.name: f.param(p.name).from_mlx(p.attrs) for p in sf.params}
        original = {p.name: f.param(p.name).from_mlx(p.attrs) for p in applied.script.params}
        assert values == original
    assert {p.name: p.attrs["value"] for p in read[0].params} == {"count": "4", "height": "2.5", "seed": "3"}
    assert mlx_text(read) == path.read_text()
    # replaying the script gives the same meshes
    ms2 = _two_spheres()
    ms2.apply_filter_script(path)
    assert np.array_equal(ms2.current_mesh().V, ms.current_mesh().V)
    assert np.array_equal(ms2.current_mesh().quality, ms.current_mesh().quality)


MESHLAB_SCRIPT = """<!DOCTYPE FilterScript>
<FilterScript>
 <filter name="Add Outlier Spikes">
  <Param name="count" value="3" type="RichInt" tooltip="how &lt;b&gt;many&lt;/b&gt;" description="Spikes"
   isxmlparam="0" colour="red"/>
  <Param name="height" value="0.05" type="RichAbsPerc" min="0" max="3.4" description="Height"/>
  <Param name="colour" value="1" type="RichBool" description="not a parameter of this filter"/>
 </filter>
 <filter id="geodesic_distance_from_selection" name="Some Old Display Name">
  <Param name="method" type="RichEnum" value="1" enum_val0="graph" enum_val1="heat" enum_cardinality="3"/>
  <Param name="sources" type="RichString" value="0, 5"/>
 </filter>
</FilterScript>
"""


def test_meshlab_script_is_read_leniently_with_warnings(tmp_path):
    path = tmp_path / "meshlab.mlx"
    path.write_text(MESHLAB_SCRIPT)
    # MeshLab's documentation attributes pass silently; an unknown attribute is named once
    with pytest.warns(UserWarning, match=r"not needed to run the filters: colour"):
        script = read_mlx(path)
    assert [f.line for f in script] == [3, 9]
    ms = _two_spheres()
    with pytest.warns(UserWarning, match=r"meshlab.mlx:3: filter 'outlier_spikes' has no parameter 'colour'"):
        ms.apply_filter_script(script, source=str(path))
    assert ms.history[0].outputs["height"] == pytest.approx(0.05)
    # the id wins over a stale display name; the enum index is read
    assert ms.history[1].outputs == {"n_sources": 2, "max_distance": pytest.approx(
        ms.current_mesh().quality.max()), "unreachable_vertices": 0, "method": "heat"}


def test_malformed_and_unknown_scripts():
    with pytest.raises(FilterScriptError, match=r"s.mlx:3: malformed XML"):
        parse_mlx("<FilterScript>\n<filter name='a'>\n</filtr>", "s.mlx")
    with pytest.raises(FilterScriptError, match="no <FilterScript>"):
        parse_mlx("<Other/>", "s.mlx")
    script = parse_mlx("<FilterScript>\n <filter id='mesh_report'/>\n <filter name='Frobnicate'/>\n"
                       "</FilterScript>", "s.mlx")
    ms = _two_spheres()
    with pytest.raises(FilterScriptError, match=r"s.mlx:3: unknown filter 'Frobnicate'"):
        ms.apply_filter_script(script, source="s.mlx")
    assert ms.history == []  # nothing ran


# ---- command line ----------------------------------------------------------------------
def _write_inputs(tmp_path):
    from geoshape.io.mesh_io import save_mesh

    V, F = icosphere(2)
    save_mesh(tmp_path / "a.ply", V, F)
    save_mesh(tmp_path / "b.ply", 1.3 * V @ _rotation().T, F)
    return tmp_path / "a.ply", tmp_path / "b.ply"


def test_run_cli_stops_on_unknown_filter_with_name_and_line(tmp_path, capsys):
    from geoshape.__main__ import main

    a, _ = _write_inputs(tmp_path)
    script = tmp_path / "s.mlx"
    script.write_text("<!DOCTYPE FilterScript>\n<FilterScript>\n <filter id='mesh_report'/>\n\n"
                      " <filter name='Not A Filter'>\n </filter>\n</FilterScript>\n")
    code = main(["run", "-i", str(a), "-o", str(tmp_path / "o.ply"), "-s", str(script)])
    err = capsys.readouterr().err
    assert code == 2
    assert "s.mlx:5: unknown filter 'Not A Filter'" in err
    assert not (tmp_path / "o.ply").exists()


def test_run_cli_writes_output_and_reproducible_script(tmp_path, capsys):
    from geoshape.__main__ import main
    from geoshape.io.mesh_io import load_mesh

    a, b = _write_inputs(tmp_path)
    script = tmp_path / "s.mlx"
    script.write_text(
        "<!DOCTYPE FilterScript>\n<FilterScript>\n"
        " <filter id='outlier_spikes'><Param name='count' type='RichInt' value='5'/></filter>\n"
        " <filter id='eigenvector_colormap'><Param name='index' type='RichInt' value='2'/></filter>\n"
        " <filter name='Simplification: Quadric Edge Collapse Decimation'>\n"
        "  <Param name='TargetFaceNum' type='RichInt' value='200'/>\n"
        "  <Param name='OptimalPlacement' type='RichBool' value='false'/>\n"
        " </filter>\n</FilterScript>\n")
    out1, used = tmp_path / "o1.ply", tmp_path / "used.mlx"
    assert main(["run", "-i", str(a), "-i", str(b), "-o", str(out1), "-s", str(script),
                 "--save-script", str(used)]) == 0
    assert "wrote" in capsys.readouterr().out
    out2 = tmp_path / "o2.ply"
    assert main(["run", "-i", str(a), "-i", str(b), "-o", str(out2), "-s", str(used), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [f["id"] for f in summary["filters"]] == [
        "outlier_spikes", "eigenvector_colormap", "meshing_decimation_quadric_edge_collapse"]
    assert out1.read_bytes() == out2.read_bytes()
    assert len(load_mesh(out1)[1]) == 200


def test_filters_cli_lists_everything(capsys):
    from geoshape.__main__ import main

    assert main(["filters", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert [f["id"] for f in listed] == [f.id for f in list_filters()]
    spikes = next(f for f in listed if f["id"] == "outlier_spikes")
    assert [(p["name"], p["default"]) for p in spikes["params"]] == [("count", 20), ("height", 5.0),
                                                                    ("seed", 0)]
    assert main(["filters"]) == 0
    assert "spectral_correspondence" in capsys.readouterr().out


def test_docs_page_is_generated_from_the_registry():
    from geoshape_plugins.docs import filters_markdown

    page = (REPO / "docs" / "filters.md").read_text()
    assert page == filters_markdown(), "regenerate: geoshape filters --markdown > docs/filters.md"
    for f in list_filters():
        assert f"## {f.id}" in page


# ---- acceptance: PyMeshLab decimation + spectral correspondence on TOSCA ------------------
ACCEPTANCE_SCRIPT = """<!DOCTYPE FilterScript>
<FilterScript>
 <filter name="Simplification: Quadric Edge Collapse Decimation">
  <Param name="TargetFaceNum" type="RichInt" value="1600"/>
  <Param name="TargetPerc" type="RichFloat" value="0"/>
  <Param name="QualityThr" type="RichFloat" value="0.3"/>
  <Param name="PreserveBoundary" type="RichBool" value="false"/>
  <Param name="BoundaryWeight" type="RichFloat" value="1"/>
  <Param name="PreserveNormal" type="RichBool" value="false"/>
  <Param name="PreserveTopology" type="RichBool" value="true"/>
  <Param name="OptimalPlacement" type="RichBool" value="true"/>
  <Param name="PlanarQuadric" type="RichBool" value="false"/>
  <Param name="PlanarWeight" type="RichFloat" value="0.001"/>
  <Param name="QualityWeight" type="RichBool" value="false"/>
  <Param name="AutoClean" type="RichBool" value="true"/>
  <Param name="Selected" type="RichBool" value="false"/>
 </filter>
 <filter id="change_current_mesh"><Param name="mesh" type="RichMesh" value="1"/></filter>
 <filter id="meshing_decimation_quadric_edge_collapse">
  <Param name="targetfacenum" type="RichInt" value="1600"/>
  <Param name="preservetopology" type="RichBool" value="true"/>
  <Param name="preserveboundary" type="RichBool" value="false"/>
  <Param name="optimalplacement" type="RichBool" value="true"/>
  <Param name="qualitythr" type="RichFloat" value="0.3"/>
  <Param name="planarquadric" type="RichBool" value="false"/>
  <Param name="preservenormal" type="RichBool" value="false"/>
 </filter>
 <filter id="change_current_mesh"><Param name="mesh" type="RichMesh" value="0"/></filter>
 <filter id="spectral_correspondence">
  <Param name="target" type="RichMesh" value="1"/>
  <Param name="method" type="RichEnum" value="jz"/>
 </filter>
</FilterScript>
"""


@pytest.mark.data
@pytest.mark.slow
def test_acceptance_tosca_script_from_cli_and_python(tmp_path, capsys):
    from geoshape.__main__ import main
    from geoshape.io.mesh_io import load_mesh

    folder = shared_dataset("tosca_r5k")
    a, b = folder / "vtx_5k" / "cat0.off.gz", folder / "vtx_5k" / "cat1.off.gz"
    if not (a.exists() and b.exists()):
        pytest.skip("tosca_r5k cat0/cat1 not found")
    script = tmp_path / "accept.mlx"
    script.write_text(ACCEPTANCE_SCRIPT)
    out1, used, out2 = tmp_path / "o1.ply", tmp_path / "used.mlx", tmp_path / "o2.ply"
    args = ["run", "-i", str(a), "-i", str(b)]
    assert main([*args, "-o", str(out1), "-s", str(script), "--save-script", str(used)]) == 0
    assert main([*args, "-o", str(out2), "-s", str(used)]) == 0
    capsys.readouterr()
    assert out1.read_bytes() == out2.read_bytes()
    V, F = load_mesh(out1)
    assert 700 <= len(V) <= 900 and len(F) == 1600
    # the same from Python, with the methods bound from the registry
    ms = MeshSet()
    ms.load_new_mesh(a)
    ms.load_new_mesh(b)
    ms.set_current_mesh(0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ms.apply_filter_script(used)
    out3 = ms.save_current_mesh(tmp_path / "o3.ply")
    assert out3.read_bytes() == out1.read_bytes()
    colors = ms.current_mesh().colors
    assert colors is not None and len(np.unique(colors.round(3), axis=0)) > 100


def test_param_types_from_text_and_back():
    from geoshape_plugins.params import EnumParam, FilePathParam, IntListParam, PercentageParam

    path = FilePathParam("map", "")
    assert path.coerce(Path("a/b.npy")) == "a/b.npy"
    with pytest.raises(FilterParameterError, match="expected a file path, got 3"):
        path.coerce(3, "f")
    ids = IntListParam("sources")
    assert ids.from_mlx({"value": "1, 2 3"}) == (1, 2, 3)
    assert ids.to_mlx((1, 2)) == {"type": "RichString", "value": "1 2"}
    enum = EnumParam("m", "a", choices=("a", "b"))
    assert enum.from_mlx(enum.to_mlx("b")) == "b"
    with pytest.raises(FilterParameterError, match="enum index 5 out of range"):
        enum.from_mlx({"value": "5"})
    pct = PercentageParam("h", 5.0)
    assert isinstance(pct.from_mlx({"type": "RichAbsPerc", "value": "0.2"}), AbsoluteValue)
    assert pct.from_mlx(pct.to_mlx(2.5)) == 2.5
