"""geoshape's filters: declarations plus thin ``apply`` functions over the library.

Each ``apply`` calls one library function (the same one the CLI calls) and only moves data
between it and the meshes of the MeshSet. Geodesic solvers, spectral embeddings and the
per-mesh precomputations of correspondence are cached on the mesh, keyed by every
parameter that affects them.
"""

from __future__ import annotations

import numpy as np
from geoshape_plugins.params import (
    BoolParam,
    EnumParam,
    FilterError,
    FloatParam,
    IntListParam,
    IntParam,
    MeshParam,
    PercentageParam,
    StringParam,
)
from geoshape_plugins.registry import HAS_FACES, Arity, Filter, register

from geoshape.correspondence.mesh_matching import CORRESPONDENCE_METHODS, DEFAULT_METHOD
from geoshape.geometry.geodesics import DEFAULT_GEODESIC_METHOD, GEODESIC_METHODS
from geoshape.retrieval.descriptors.evd import EVD_CONFIG_NAMES
from geoshape.spectral.embedding import EMBEDDING_METHODS, SCALINGS

AFFINITIES = ("geodesic", "euclidean", "combined")
SIGMA_RULES = ("max", "mean")
COLORMAP_CHOICES = ("coolwarm", "RdBu_r", "viridis", "turbo", "plasma", "gray")


# ---- shared helpers -----------------------------------------------------------------
def _solver(mesh, method: str):
    from geoshape.geometry.geodesics import GeodesicSolver

    return mesh.cached(("geodesic_solver", method), lambda: GeodesicSolver(mesh.V, mesh.F, method))


def _embedding(mesh, *, k, method="auto", n_samples=0, affinity="geodesic", sigma="max",
               geodesics=DEFAULT_GEODESIC_METHOD, scaling="sqrt", seed=0):
    from geoshape.spectral.embedding import spectral_embedding

    samples = None if n_samples == 0 else n_samples
    key = ("spectral_embedding", k, method, samples, affinity, sigma, geodesics, scaling, seed)
    return mesh.cached(key, lambda: spectral_embedding(
        mesh.V, mesh.F, k, method=method, n_samples=samples, affinity=affinity, sigma=sigma,
        geodesics=geodesics, scaling=scaling, seed=seed, solver=_solver(mesh, geodesics)))


def _prepared(mesh):
    from geoshape.correspondence.mesh_matching import PreparedMesh

    return mesh.cached(("prepared_mesh",), lambda: PreparedMesh(mesh.V, mesh.F, name=mesh.name))


def _other_mesh(ms) -> int:
    """the first mesh other than the current one"""
    if ms is None or len(ms) < 2:
        return 1
    return 0 if ms.current_index != 0 else 1


def _evd_samples(ms) -> int:
    """min(500 (the library default), number of vertices of the current mesh)"""
    from geoshape.retrieval.descriptors.evd import EVD_N_SAMPLES

    if ms is None or not len(ms):
        return EVD_N_SAMPLES
    return min(EVD_N_SAMPLES, ms.current_mesh().vertex_number())


_EMBED_PARAMS = (
    EnumParam("method", "auto", "Eigensolver", "exact: all-pairs distances (n <= 2000); nystrom: "
              "sampled rows; auto: exact up to 2000 vertices", choices=EMBEDDING_METHODS),
    IntParam("n_samples", 0, "Nystrom samples", "Nystrom samples l; 0 = library default (50)", min=0),
    EnumParam("affinity", "geodesic", "Affinity", "distances under the Gaussian", choices=AFFINITIES),
    EnumParam("sigma", "max", "Gaussian width", "sigma = maximum or mean distance", choices=SIGMA_RULES),
    EnumParam("geodesics", DEFAULT_GEODESIC_METHOD, "Geodesic backend",
              "graph: shortest paths on the structural graph; heat: heat method; exact: MMP",
              choices=GEODESIC_METHODS),
    EnumParam("scaling", "sqrt", "Eigenvector scaling", "sqrt: U sqrt(lambda) (thesis)", choices=SCALINGS),
    IntParam("seed", 0, "Seed", "seed of the first max-min sample and of the eigensolver", min=0),
)


def _embed_kwargs(p: dict) -> dict:
    return {k: p[k] for k in ("method", "n_samples", "affinity", "sigma", "geodesics", "scaling", "seed")}


# ---- geodesic_distance_from_selection ----------------------------------------------
def _geodesic_apply(ms, p, progress):
    mesh = ms.current_mesh()
    if p["sources"]:
        sources = np.asarray(p["sources"], dtype=np.int64)
        if sources.max() >= mesh.vertex_number():
            raise FilterError(
                f"geodesic_distance_from_selection: source vertex {int(sources.max())} out of range "
                f"[0, {mesh.vertex_number() - 1}]"
            )
    elif mesh.selection is not None and mesh.selection.any():
        sources = np.flatnonzero(mesh.selection)
    else:
        raise FilterError("geodesic_distance_from_selection: no source vertices: select vertices on "
                          "the mesh or pass sources=[...]")
    solver = _solver(mesh, p["method"])
    dist = np.full(mesh.vertex_number(), np.inf)
    chunk = 64
    for start in range(0, len(sources), chunk):
        dist = np.minimum(dist, solver.distances(sources[start:start + chunk]).min(axis=0))
        progress(min(1.0, (start + chunk) / len(sources)), "geodesic distances")
    finite = np.isfinite(dist)
    mesh.quality = np.where(finite, dist, -1.0)
    return {"n_sources": len(sources), "max_distance": float(dist[finite].max()),
            "unreachable_vertices": int((~finite).sum()), "method": solver.method}


register(Filter(
    id="geodesic_distance_from_selection",
    name="Geodesic Distance from Selection",
    description="Geodesic distance of every vertex to the nearest source vertex (the selected "
    "vertices, or the listed ids), stored as vertex quality. Backends: shortest paths on the "
    "structural graph, the heat method (Crane, Weischedel and Wardetzky, 'Geodesics in heat', "
    "ACM TOG 2013) or exact polyhedral geodesics (Mitchell, Mount and Papadimitriou, SIAM J. "
    "Comput. 1987). Unreachable vertices get quality -1.",
    categories=("quality", "measure"),
    arity=Arity.SINGLE,
    params=(
        IntListParam("sources", (), "Source vertices",
                     "vertex ids; empty = use the vertex selection of the mesh"),
        EnumParam("method", DEFAULT_GEODESIC_METHOD, "Geodesic backend",
                  "graph (any mesh), heat (one surface; solver cached per mesh) or exact (small meshes)",
                  choices=GEODESIC_METHODS),
    ),
    preconditions=(),
    apply=_geodesic_apply,
))


# ---- spectral_embedding -------------------------------------------------------------
def _spectral_apply(ms, p, progress):
    from geoshape.spectral.embedded_mesh import embedding_vertices

    mesh = ms.current_mesh()
    progress(0.0, "spectral embedding")
    emb = _embedding(mesh, k=p["k"], **_embed_kwargs(p))
    coords, eigenvalues = emb.coords.copy(), emb.eigenvalues.copy()
    name = p["attribute"]
    if p["output"] == "replace_coordinates":
        mesh.attributes["original_positions"] = mesh.V.copy()
        mesh.set_geometry(embedding_vertices(coords), mesh.F, keep_attributes=True)
    mesh.attributes[name] = coords
    progress(1.0, "spectral embedding")
    return {"eigenvalues": eigenvalues, "attribute": name, "method": emb.params.get("method")}


register(Filter(
    id="spectral_embedding",
    name="Spectral Embedding (Geodesic Affinity)",
    description="Spectral embedding of the mesh: top eigenvectors of a Gaussian affinity of "
    "geodesic distances, first dropped, scaled by sqrt(eigenvalue) (Jain and Zhang, 'A spectral "
    "approach to shape-based retrieval of articulated 3D models', CAD 2007; Nystrom "
    "approximation after Fowlkes et al., PAMI 2004). Replaces the vertex positions by the first "
    "three coordinates (the pose-invariant 'embedded mesh'), or only stores all k coordinates "
    "as the vertex attribute named by 'attribute' (n x k).",
    categories=("spectral", "remeshing"),
    arity=Arity.SINGLE,
    params=(
        IntParam("k", 5, "Dimensions", "embedding dimensions (k + 1 eigenpairs, the first dropped)", min=1),
        *_EMBED_PARAMS,
        EnumParam("output", "replace_coordinates", "Output",
                  "replace the vertex positions by the embedding, or store it as an attribute only",
                  choices=("replace_coordinates", "attribute")),
        StringParam("attribute", "spectral_embedding", "Attribute name",
                    "vertex attribute receiving the (n, k) coordinates"),
    ),
    preconditions=(),
    apply=_spectral_apply,
))


# ---- eigenvector_colormap -----------------------------------------------------------
def _eigencolor_apply(ms, p, progress):
    from geoshape.plot.colormap import scalar_colors

    mesh = ms.current_mesh()
    k = max(5, p["index"] + 1)  # same cache entry as spectral_embedding's default k = 5
    emb = _embedding(mesh, k=k, **_embed_kwargs(p))
    values = emb.coords[:, p["index"]]
    mesh.quality = values.copy()
    mesh.colors = scalar_colors(values, p["colormap"], symmetric=True)
    return {"eigenvalue": float(emb.eigenvalues[p["index"]]), "min": float(values.min()),
            "max": float(values.max())}


register(Filter(
    id="eigenvector_colormap",
    name="Colorize by Affinity Eigenvector",
    description="Colours the vertices by one eigenvector of the geodesic Gaussian affinity "
    "(a column of the spectral embedding, symmetric colour range around 0) and stores it as "
    "vertex quality (Jain and Zhang, CAD 2007, Fig. 4.3 of the thesis).",
    categories=("color", "spectral"),
    arity=Arity.SINGLE,
    params=(
        IntParam("index", 0, "Eigenvector", "column of the embedding (0 = first kept eigenvector)", min=0),
        EnumParam("colormap", "coolwarm", "Colour map", "Matplotlib colour map", choices=COLORMAP_CHOICES),
        *_EMBED_PARAMS,
    ),
    preconditions=(),
    apply=_eigencolor_apply,
))


# ---- spectral_correspondence ----------------------------------------------------------
def _correspondence_apply(ms, p, progress):
    from geoshape.correspondence.mesh_matching import correspond
    from geoshape.plot.colormap import position_colors

    src_index, tgt_index = ms.current_index, p["target"]
    if tgt_index == src_index:
        raise FilterError(f"spectral_correspondence: target mesh {tgt_index} is the current mesh; "
                          "choose another mesh")
    source, target = ms.current_mesh(), ms.mesh(tgt_index)
    progress(0.0, "correspondence")
    result = correspond(_prepared(source), None, _prepared(target), None, method=p["method"])
    p2p = result.p2p_12
    source.attributes[p["attribute"]] = p2p.copy()
    colored_target = False
    if p["transfer"] in ("colors_and_quality", "colors"):
        if target.colors is None:
            target.colors = position_colors(target.V)
            colored_target = True
        source.colors = target.colors[p2p].copy()
    if p["transfer"] in ("colors_and_quality", "quality") and target.quality is not None:
        source.quality = target.quality[p2p].copy()
    progress(1.0, "correspondence")
    return {"cost": float(result.cost), "method": result.method, "target": int(tgt_index),
            "attribute": p["attribute"], "colored_target": colored_target}


register(Filter(
    id="spectral_correspondence",
    name="Spectral Correspondence",
    description="Dense vertex correspondence from the current mesh to the target mesh. The "
    "default 'geoshape' method aligns spectral embeddings of geodesic affinities (Jain and "
    "Zhang, 'Robust 3D shape correspondence in the spectral domain', SMI 2006), refines with "
    "non-rigid TPS-ICP and ZoomOut (Melzi et al., SIGGRAPH Asia 2019) and keeps the "
    "orientation-preserving candidate. The map (for each source vertex, a target vertex) is "
    "stored as the vertex attribute named by 'attribute'; colours and quality are pulled from "
    "the target through it (a target without colours is first coloured by position).",
    categories=("correspondence", "color"),
    arity=Arity.PAIR,
    params=(
        MeshParam("target", _other_mesh, "Target mesh", "index of the mesh to match onto"),
        EnumParam("method", DEFAULT_METHOD, "Method", "correspondence method",
                  choices=CORRESPONDENCE_METHODS),
        EnumParam("transfer", "colors_and_quality", "Transfer", "what to pull from the target",
                  choices=("colors_and_quality", "colors", "quality", "none")),
        StringParam("attribute", "correspondence", "Attribute name",
                    "vertex attribute receiving the map (n,) int"),
    ),
    preconditions=(HAS_FACES,),
    apply=_correspondence_apply,
))


# ---- decimate_with_ground_truth -------------------------------------------------------
def _decimate_apply(ms, p, progress):
    from geoshape_datasets_gen.decimate import decimate_exact

    mesh = ms.current_mesh()
    progress(0.0, "decimation")
    d = decimate_exact(mesh.V, mesh.F, p["ratio"], preserve_boundary=p["preserve_boundary"],
                       preserve_topology=p["preserve_topology"])
    n_before = mesh.vertex_number()
    mesh.set_geometry(d.V, d.F, source_ids=d.orig_ids)
    mesh.attributes["original_ids"] = d.orig_ids.copy()
    progress(1.0, "decimation")
    return {"vertices_before": n_before, "vertices": len(d.V), "fraction": float(d.fraction)}


register(Filter(
    id="decimate_with_ground_truth",
    name="Decimation with Exact Ground Truth",
    description="Quadric edge collapse (Garland and Heckbert, SIGGRAPH 1997) without optimal "
    "placement, so every surviving vertex keeps its exact position; the id of each survivor in "
    "the input is stored as the vertex attribute 'original_ids' (the ground truth of the "
    "decimation experiment, thesis 4.2.2). Colours, quality, selection and attributes follow "
    "the survivors.",
    categories=("remeshing", "benchmark"),
    arity=Arity.SINGLE,
    params=(
        FloatParam("ratio", 0.5, "Vertex ratio", "wanted fraction of vertices, in (0, 1]", min=0.0, max=1.0),
        BoolParam("preserve_boundary", True, "Preserve boundary", "do not move boundary vertices"),
        BoolParam("preserve_topology", True, "Preserve topology", "keep the genus and manifoldness"),
    ),
    preconditions=(HAS_FACES,),
    apply=_decimate_apply,
))


# ---- outlier_spikes -----------------------------------------------------------------
def _spikes_apply(ms, p, progress):
    from geoshape_datasets_gen.spikes import add_spikes

    mesh = ms.current_mesh()
    diag = mesh.bbox_diagonal()
    height = PercentageParam.absolute(p["height"], diag) / diag if diag > 0 else 0.0
    n = mesh.vertex_number()
    s = add_spikes(mesh.V, mesh.F, p["count"], height, seed=p["seed"])
    k = len(s.V) - n
    mesh.set_geometry(s.V, s.F, source_ids=np.concatenate([np.arange(n), np.full(k, -1)]))
    is_spike = np.zeros(len(s.V), dtype=bool)
    is_spike[n:] = True
    mesh.attributes["is_spike"] = is_spike
    return {"spikes": k, "height": float(height * diag), "faces": s.faces.copy()}


register(Filter(
    id="outlier_spikes",
    name="Add Outlier Spikes",
    description="Adds spikes on random faces: a vertex at the face centroid, pulled off the "
    "surface along the face normal (the contamination experiment of the thesis, 4.7; Jain and "
    "Zhang, CAD 2007). Original vertices keep their ids; spike tips are appended and flagged by "
    "the vertex attribute 'is_spike'.",
    categories=("noise", "benchmark"),
    arity=Arity.SINGLE,
    params=(
        IntParam("count", 20, "Spikes", "number of spikes (one per face)", min=0),
        PercentageParam("height", 5.0, "Height", "tip distance from the face plane"),
        IntParam("seed", 0, "Seed", "seed of the face draw", min=0),
    ),
    preconditions=(HAS_FACES,),
    apply=_spikes_apply,
))


# ---- evd_descriptor -------------------------------------------------------------------
def _evd_apply(ms, p, progress):
    from geoshape.retrieval.descriptors.evd import evd_descriptor

    mesh = ms.current_mesh()
    if p["config"] == "heat":  # no samples and no geodesics: the other options do not apply
        return {"evd": evd_descriptor(mesh.V, mesh.F, config="heat", n_eigenvalues=p["n_eigenvalues"])}
    evd = evd_descriptor(mesh.V, mesh.F, config=p["config"], n_eigenvalues=p["n_eigenvalues"],
                         n_samples=p["n_samples"], geodesics=p["geodesics"], seed=p["seed"])
    return {"evd": evd}


register(Filter(
    id="evd_descriptor",
    name="Eigenvalue Descriptor (EVD)",
    description="Shape descriptor for retrieval: square roots of the top eigenvalues of the "
    "geodesic Gaussian affinity of max-min samples (Jain and Zhang, CAD 2007, thesis 4.6.2). "
    "Returned as the output 'evd'; compare descriptors with the chi-square distance.",
    categories=("measure", "spectral"),
    arity=Arity.SINGLE,
    params=(
        EnumParam("config", "quadrature", "Configuration", "quadrature: samples weighted by their "
                  "geodesic Voronoi areas, sigma = 0.1 sqrt(area); thesis: unweighted, sigma = max "
                  "geodesic distance (the thesis used 60 samples); heat: the narrow-kernel limit "
                  "from exact Laplace-Beltrami eigenvalues (ignores samples, geodesics, seed)",
                  choices=EVD_CONFIG_NAMES),
        IntParam("n_eigenvalues", 20, "Eigenvalues", "descriptor length (<= n_samples; heat: "
                 "< the vertex count)", min=1),
        IntParam("n_samples", _evd_samples, "Samples", "max-min samples; keep it fixed across a "
                 "collection", min=1),
        EnumParam("geodesics", DEFAULT_GEODESIC_METHOD, "Geodesic backend", "geodesic backend",
                  choices=GEODESIC_METHODS),
        IntParam("seed", 0, "Seed", "seed of the first sample", min=0),
    ),
    preconditions=(),
    apply=_evd_apply,
))


# ---- mesh_report ------------------------------------------------------------------------
def _report_apply(ms, p, progress):
    from geoshape.geometry.report import mesh_report, report_problems

    mesh = ms.current_mesh()
    report = mesh_report(mesh.V, mesh.F, name=mesh.name)
    report["problems"] = report_problems(report)
    return report


register(Filter(
    id="mesh_report",
    name="Mesh Report",
    description="Counts and defects of the current mesh: vertices, faces, edges, components, "
    "boundary and non-manifold edges and vertices, degenerate and duplicate faces, unreferenced "
    "vertices, Euler characteristic, bounding box and area.",
    categories=("measure",),
    arity=Arity.SINGLE,
    params=(),
    preconditions=(),
    apply=_report_apply,
))


# ---- change_current_mesh ----------------------------------------------------------------
def _current_apply(ms, p, progress):
    ms.set_current_mesh(p["mesh"])
    return {"current": p["mesh"]}


register(Filter(
    id="change_current_mesh",
    name="Change the Current Mesh",
    description="Makes another mesh of the set the current one, so that a script can apply "
    "filters to several meshes (MeshLab does this in its GUI, outside scripts).",
    categories=("layer",),
    arity=Arity.VARIABLE,
    params=(MeshParam("mesh", 0, "Mesh", "index of the mesh to make current"),),
    preconditions=(),
    apply=_current_apply,
))
