"""Old MeshLab filter and parameter names, for running legacy ``.mlx`` filter scripts.

MeshLab scripts written by older releases (1.2.x, 1.3.x up to 1.3.4BETA, 2016.12,
2020.x, 2021.x) name filters by display names (``<filter name="...">``) and parameters
by XML names (``<Param name="...">``) that were later renamed, merged or dropped.
PyMeshLab 2025.7 knows only the current ones. This module is data only:

``LEGACY_FILTER_NAMES``
    old display name -> current PyMeshLab Python filter name. Only names that the
    generic resolver (``pymeshlab_bridge.resolve_pymeshlab_name``: lower case, runs of
    other characters as ``_``, then PyMeshLab's ``keys.txt``) does *not* resolve, or
    resolves to the wrong filter (marked "WRONG" below), are listed.
``LEGACY_PARAM_NAMES``
    current Python filter name -> {old XML parameter name: current XML parameter name}.
``LEGACY_DROPPED_PARAMS``
    current Python filter name -> old XML parameter names that no longer exist; a script
    giving them should drop them with a warning (the filter then uses its default).

Keys (old names) are meant to be compared case-insensitively, after stripping and
collapsing runs of whitespace (old MeshLab names sometimes end with a space, e.g.
``"Select non Manifold Edges "``). The current names are resolved elsewhere: the
values here are checked against ``pymeshlab.filter_list()`` and against the parameters
PyMeshLab reports for each filter (Python parameter = XML name lower-cased, plus ``_``
when that is a Python keyword), and no old parameter name is a current one.

Sources read (public code; versions as given by the sources):

* 3DLIRIOUS/MeshLabXML, ``meshlabxml/{clean,delete,remesh,transform,create,select,
  sampling,normals,layers,transfer,smooth,subdivide,vert_color,compute}.py``: scripts
  for MeshLab 1.3.4BETA and 2016.12, several with ``if script.ml_version == '1.3.4BETA'``
  conditionals.
* cnr-isti-vclab/meshlab, ``src/meshlabplugins/*``: the ``filterName()`` switches and
  ``initParameterSet()`` of stored 1.2.x, 1.3.x and 2020.x revisions of filter_meshing
  (``meshfilter.cpp``), filter_clean, filter_select, filter_func, filter_colorproc,
  filter_unsharp, filter_texture, filter_sampling, filter_mls, filter_ao,
  filter_isoparametrization; ``docs/dox/filter.dox`` (1.2/1.3-era filter list).
* cnr-isti-vclab/PyMeshLab, ``docs/changelog.rst`` (2021.10: renamed, unified and removed
  filters) and the ``keys.txt`` shipped with pymeshlab 2025.7, plus the display and
  Python names compiled into its plugins (``libfilter_ao.so``, ``libfilter_sdfgpu.so``,
  ``libfilter_embree.so``).
* gallantlab/caseforge-pipeline ``simple_serve.py`` (a MeshLab 1.3.x script) and its
  PyMeshLab port in gallantlab/headcase-pipeline (old Poisson -> Screened Poisson).

Not included, because no rename can express them (they need a fixed parameter value or
the filter is gone): "Remove T-Vertices by Edge Flip" and "Repair non Manifold Edges by
splitting vertices" (now a ``method`` of the unified filters), "Ambient Occlusion - Per
Face", "Recompute Weighted Vertex Normals", "Recompute Angle Weighted Vertex Normals"
(now ``weightMode``), "Remove Non Manifold Vertices" (1.3.0, deleted faces; the current
filter splits), "Remove Faces with edges longer than..." (1.3.0; now select + delete),
"Crease Marking with NonFaux Edges", "Directional Geom. Preserv." (store/blend steps
replaced by a named attribute), "Change the current layer" (a MeshSet method in
PyMeshLab, not a filter), "Compact vertices", "Compact faces", "Vertex Color Noise",
"Select Folded Faces", "Cross Field Creation" (removed in 2021.10).
"""

from __future__ import annotations

__all__ = ["LEGACY_FILTER_NAMES", "LEGACY_PARAM_NAMES", "LEGACY_DROPPED_PARAMS"]

#: old MeshLab filter display name -> current PyMeshLab Python filter name
LEGACY_FILTER_NAMES: dict[str, str] = {
    # --- filter_meshing (meshfilter.cpp 1.3.x; MeshLabXML delete.py / remesh.py) ------
    # MeshLab <= 1.3.4BETA; 2016.12 and later: "... Vertices", "Simplification: ...".
    "Remove Unreferenced Vertex": "meshing_remove_unreferenced_vertices",
    "Remove Duplicated Vertex": "meshing_remove_duplicate_vertices",
    "Quadric Edge Collapse Decimation": "meshing_decimation_quadric_edge_collapse",
    "Quadric Edge Collapse Decimation (with texture)": (
        "meshing_decimation_quadric_edge_collapse_with_texture"
    ),
    # MeshLab 1.2-1.3.x; 2020.x: "Simplification: Clustering Decimation".
    "Clustering decimation": "meshing_decimation_clustering",
    # MeshLab 1.3.x-2021.10; keys.txt maps it to meshing_re_orient_faces_coherentely, which
    # no longer exists (current: "Re-Orient all faces coherently").
    "Re-Orient all faces coherentely": "meshing_re_orient_faces_coherently",
    # MeshLab 1.3.x-2016.12 (MeshLabXML transform.py writes them for both); 2020.x:
    # "Transform: Scale, Normalize", "Transform: Translate, Center, set Origin",
    # "Matrix: Freeze Current Matrix", "Matrix: Reset Current Matrix".
    "Transform: Scale": "compute_matrix_from_scaling_or_normalization",
    "Transform: Move, Translate, Center": "compute_matrix_from_translation",
    "Freeze Current Matrix": "apply_matrix_freeze",
    "Reset Current Matrix": "set_matrix_identity",
    # MeshLab 1.3.x-2020.x; 2021.10: "Smooth normals on point sets".
    "Smooths normals on a point sets": "apply_normal_point_cloud_smoothing",
    # MeshLab 1.3.0 (same algorithm as the default method "Remove Faces").
    "Remove Non Manifold Faces": "meshing_repair_non_manifold_edges",
    # MeshLab 1.2.x; 1.3.0 and later: "Subdivision Surfaces: Loop/Butterfly .../Midpoint".
    "Loop Subdivision Surfaces": "meshing_surface_subdivision_loop",
    "Butterfly Subdivision Surfaces": "meshing_surface_subdivision_butterfly",
    "Midpoint Subdivision Surfaces": "meshing_surface_subdivision_midpoint",
    # --- filter_clean (cleanfilter.cpp 1.3.x and 2020.x; MeshLabXML clean.py, delete.py) -
    # MeshLab 1.3.x-2016.12; 2020.x: "Repair non Manifold Edges by removing faces".
    "Remove Faces from Non Manifold Edges": "meshing_repair_non_manifold_edges",
    # MeshLab <= 1.3.4BETA; 2016.12: "Repair non Manifold Vertices by splitting".
    "Split Vertexes Incident on Non Manifold Faces": "meshing_repair_non_manifold_vertices",
    # MeshLab 1.3.x-2021.07; unified in 2021.10 (PyMeshLab changelog). The defaults of
    # the unified filters are these methods ("Edge Collapse", "Remove Faces").
    "Remove T-Vertices by Edge Collapse": "meshing_remove_t_vertices",
    "Repair non Manifold Edges by removing faces": "meshing_repair_non_manifold_edges",
    # --- filter_select (meshselect.cpp, older 1.3.x) -----------------------------------
    # Later: "Select by Vertex Quality", "Select by Face Quality".
    "Select Faces by Vertex Quality": "compute_selection_by_scalar_per_vertex",
    "Select Faces by Face Quality": "compute_selection_by_scalar_per_face",
    # MeshLab 1.3.x-2021.07 (PyMeshLab 2021.10 changelog: select_visible_points renamed).
    "Select Visible Points": "compute_selection_of_visible_convex_hull_per_vertex",
    # --- filter_func (filter_func.cpp; MeshLabXML transform.py) -------------------------
    # MeshLab <= 1.3.4BETA; 2016.12: "Per Vertex Geometric Function".
    "Geometric Function": "compute_coord_by_function",
    # MeshLab 1.3.x-2021.07 (2021.10 changelog: define_new_per_*_attribute renamed), and
    # the hyphenated spelling of MeshLab 1.2.x.
    "Define New Per Vertex Attribute": "compute_new_custom_scalar_attribute_per_vertex",
    "Define New Per Face Attribute": "compute_new_custom_scalar_attribute_per_face",
    "Define New Per-Vertex Attribute": "compute_new_custom_scalar_attribute_per_vertex",
    "Define New Per-Face Attribute": "compute_new_custom_scalar_attribute_per_face",
    # --- filter_create (MeshLabXML create.py: 'Box' if 1.3.4BETA else 'Box/Cube') -------
    "Box": "create_cube",
    # --- filter_colorproc (filter_colorproc.cpp 1.3.x; later "... Adjustment") ---------
    "Vertex Color Levels Adjustement": "apply_color_level_adjustment_per_vertex",
    # --- filter_unsharp (filter_unsharp.cpp 1.3.x; later "Re-Compute ...") -------------
    # The 1.3.x filter summed the face normals; the current one defaults to
    # weightMode "Simple Average".
    "Recompute Vertex Normals": "compute_normal_per_vertex",
    "Recompute Face Normals": "compute_normal_per_face",
    "Recompute Per-Quad Face Normals": "compute_normal_polygon_mesh_per_face",
    # --- filter_texture (filter_texture.cpp 1.3.4/2016.12; MeshLabXML transfer.py) -----
    # 2020.x: "Transfer: Vertex Color to Texture", "Transfer: Vertex Attributes to
    # Texture (1 or 2 meshes)", "Transfer: Texture to Vertex Color (1 or 2 meshes)".
    "Vertex Color to Texture": "compute_texmap_from_color",
    "Transfer Vertex Attributes to Texture (between 2 meshes)": "transfer_attributes_to_texture_per_vertex",
    "Texture to Vertex Color (between 2 meshes)": "transfer_texture_to_color_per_vertex",
    # --- filter_sampling (MeshLabXML sampling.py, 1.3.4BETA and 2016.12) ---------------
    # 2020.x: "Mesh Element Sampling", "Clustered Vertex Sampling".
    "Mesh Element Subsampling": "generate_sampling_element",
    "Clustered Vertex Subsampling": "generate_sampling_clustered_vertex",
    # --- filter_mls (mlsplugin.cpp 1.3.x; MeshLabXML select.py 1.3.4BETA/2016.12) ------
    # 2020.x: "Select small disconnected component".
    "Small component selection": "compute_selection_by_small_disconnected_components_per_face",
    # --- Poisson reconstruction -----------------------------------------------------------
    # filter_poisson, MeshLab <= 1.3.4BETA (MeshLabXML remesh.surface_poisson); removed in
    # 2016.12 in favour of Screened Poisson, its successor (with pointWeight 0 it is the
    # unscreened method). Old parameters: see LEGACY_PARAM_NAMES / LEGACY_DROPPED_PARAMS.
    "Surface Reconstruction: Poisson": "generate_surface_reconstruction_screened_poisson",
    # filter_screened_poisson, MeshLab 2016.12 (an <xmlfilter>, MeshLabXML remesh.py);
    # 2020.x: "Surface Reconstruction: Screened Poisson".
    "Screened Poisson Surface Reconstruction": "generate_surface_reconstruction_screened_poisson",
    # --- filter_ao (filter_ao.cpp): the OpenGL filter is now the "_gpu" one -------------
    # MeshLab 1.3.x ("- Per Vertex") and 1.2.x ("Vertex ..."); later merged into
    # "Ambient Occlusion" with occMode (default per-Vertex).
    "Ambient Occlusion - Per Vertex": "compute_scalar_ambient_occlusion_gpu",
    "Vertex Ambient Occlusion": "compute_scalar_ambient_occlusion_gpu",
    # WRONG today: MeshLab 2016.12-2021.x (and still the display name of the OpenGL filter
    # in libfilter_ao.so); keys.txt sends ambient_occlusion to
    # compute_scalar_ambient_occlusion, which is now the Embree filter "Compute Ambient
    # occlusion" (parameter Rays only).
    "Ambient Occlusion": "compute_scalar_ambient_occlusion_gpu",
    # --- filter_sdfgpu: same story (keys.txt -> the Embree filters of libfilter_embree.so)
    # WRONG today: "Shape Diameter Function" -> compute_scalar_by_shape_diameter_function_
    # per_vertex ("Compute Shape-Diameter Function"), "Volumetric obscurance" ->
    # compute_scalar_by_volumetric_obscurance ("Compute Obscurance").
    "Shape Diameter Function": "compute_scalar_by_shape_diameter_function_per_vertex_gpu",
    "Volumetric obscurance": "compute_scalar_by_volumetric_obscurance_gpu",
    # --- filter_isoparametrization (1.3.x-2016.12; 2020.x: "Iso Parametrization: Main") --
    "Iso Parametrization": "compute_iso_parametrization",
}

#: current PyMeshLab Python filter name -> {old XML parameter name: current XML parameter name}
LEGACY_PARAM_NAMES: dict[str, dict[str, str]] = {
    # filter_meshing 1.3.x-2016.12 (meshfilter.cpp initParameterSet; MeshLabXML
    # transform.py; caseforge-pipeline script): "Apply to all layers" was ToAll, it is
    # allLayers from 2020.x on.
    "compute_matrix_from_rotation": {"ToAll": "allLayers"},
    "compute_matrix_from_scaling_or_normalization": {"ToAll": "allLayers"},
    "compute_matrix_by_principal_axis": {"ToAll": "allLayers"},
    "compute_matrix_by_fitting_to_plane": {"ToAll": "allLayers"},
    # "Transform: Move, Translate, Center" (1.3.x-2016.12): the bool centerFlag became the
    # enum traslMethod (0 "XYZ translation", 1 "Center on Scene BBox", ...); false/true
    # read as a bool land on 0/1, which PyMeshLab accepts as enum indices.
    "compute_matrix_from_translation": {"ToAll": "allLayers", "centerFlag": "traslMethod"},
    # "Surface Reconstruction: Poisson" (<= 1.3.4BETA): OctDepth is Screened Poisson's
    # reconstruction depth (SamplesPerNode keeps its name, up to case).
    "generate_surface_reconstruction_screened_poisson": {"OctDepth": "depth"},
}

#: current PyMeshLab Python filter name -> old XML parameter names that no longer exist
#: (dropped with a warning)
LEGACY_DROPPED_PARAMS: dict[str, frozenset[str]] = {
    # "Clustering decimation" / "Simplification: Clustering Decimation" (1.3.x-2020.x).
    "meshing_decimation_clustering": frozenset({"Selected"}),
    # "Convex Hull" (MeshLabXML remesh.hull, 1.3.4BETA and 2016.12).
    "generate_convex_hull": frozenset({"reorient"}),
    # "Conditional Vertex Selection" (1.3.x; gone in 2016.12, MeshLabXML select.py).
    "compute_selection_by_condition_per_vertex": frozenset({"strictSelect"}),
    # "Select Border" (meshselect.cpp 1.3.x declared a stray RichInt "Iteration").
    "compute_selection_from_mesh_border": frozenset({"Iteration"}),
    # "Surface Reconstruction: Poisson" (<= 1.3.4BETA) options Screened Poisson lacks.
    "generate_surface_reconstruction_screened_poisson": frozenset({"SolverDivide", "Offset"}),
    # "Vertex Color to Texture" / "Transfer Vertex Attributes to Texture (between 2
    # meshes)" (filter_texture.cpp 1.3.4/2016.12; MeshLabXML transfer.py).
    "compute_texmap_from_color": frozenset({"assign"}),
    "transfer_attributes_to_texture_per_vertex": frozenset({"assign"}),
    # "Ambient Occlusion - Per Vertex" / "Vertex Ambient Occlusion" (filter_ao.cpp).
    "compute_scalar_ambient_occlusion_gpu": frozenset({"useVBO"}),
    # "Vertex Color Filling" (filter_colorproc.cpp 1.3.x): three DynamicFloat channels,
    # now a single RichColor color1.
    "set_color_per_vertex": frozenset({"r", "g", "b"}),
    # "Vertex Color White Balance" (filter_colorproc.cpp 1.3.x): automatic mode removed.
    "apply_color_white_balance_per_vertex": frozenset({"auto"}),
}
