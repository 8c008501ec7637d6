"""Running PyMeshLab filters on the meshes of a geoshape :class:`~geoshape_plugins.meshset.MeshSet`.

PyMeshLab cannot register Python filters, so the direction is the other way: a geoshape
MeshSet delegates any filter that is not its own to a fresh ``pymeshlab.MeshSet`` holding
copies of its meshes, then copies the results back. Every parameter is passed explicitly
(PyMeshLab re-uses the value of a parameter left out from the previous call of the same
filter): the defaults PyMeshLab computes on the current mesh, overridden by the caller's.
Caveat: PyMeshLab's "defaults" of mesh-independent parameters are themselves the last
values used in the process (its parameter state is global), so a call that leaves
parameters out depends on earlier calls; the recorded script holds every value, and
replaying it is exact. Give every parameter in scripts meant to be reproducible.

Names. Python names (``meshing_decimation_quadric_edge_collapse``) are used as they are;
a MeshLab display name ("Simplification: Quadric Edge Collapse Decimation") is turned
into PyMeshLab's pre-2022 name (lower case, runs of other characters as ``_``) and then
through PyMeshLab's own table of renamed filters (``keys.txt`` shipped with it).
Parameter names are matched case-insensitively (MeshLab writes ``TargetFaceNum``,
PyMeshLab calls it ``targetfacenum``).

What is copied: vertices, faces, per-vertex colours and quality into PyMeshLab; back,
the same plus the vertex selection. geoshape's named attributes and selection are kept
when the filter leaves the vertex count and faces unchanged and dropped otherwise.
"""

from __future__ import annotations

import functools
import re
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from geoshape_plugins.mlx import ScriptFilter, ScriptParam, read_mlx
from geoshape_plugins.params import FilterError, FilterParameterError

__all__ = ["pymeshlab_filter_names", "resolve_pymeshlab_name", "script_value", "apply_pymeshlab_filter"]


@functools.lru_cache(maxsize=1)
def pymeshlab_filter_names() -> frozenset[str]:
    """Python names of every filter PyMeshLab offers (empty if PyMeshLab is missing)."""
    try:
        import pymeshlab
    except ImportError:
        return frozenset()
    return frozenset(pymeshlab.filter_list())


@functools.lru_cache(maxsize=1)
def _renamed() -> dict[str, str]:
    """PyMeshLab's table old name -> current name (``keys.txt`` in its package folder)."""
    try:
        import pymeshlab
    except ImportError:
        return {}
    path = Path(pymeshlab.__file__).with_name("keys.txt")
    table = {}
    try:
        for line in path.read_text(encoding="utf-8").splitlines():
            parts = line.split()
            if len(parts) == 2:
                table[parts[0]] = parts[1]
    except OSError:
        return {}
    return table


def resolve_pymeshlab_name(key: str) -> str | None:
    """PyMeshLab's Python name for a Python name or MeshLab display name, or None."""
    names = pymeshlab_filter_names()
    if key in names:
        return key
    snake = re.sub(r"[^a-z0-9]+", "_", key.lower()).strip("_")
    if snake in names:
        return snake
    new = _renamed().get(snake)
    if new in names:
        return new
    return None


def script_value(attrs: dict[str, str], where: str = "") -> Any:
    """The PyMeshLab value of an ``.mlx`` ``<Param>`` from its ``type`` and value attributes."""
    import pymeshlab

    kind = attrs.get("type", "RichString")
    text = attrs.get("value", "")
    try:
        if kind == "RichBool":
            return text.strip().lower() in ("true", "1")
        if kind in ("RichInt", "RichEnum", "RichMesh"):
            return int(text)
        if kind in ("RichFloat", "RichDynamicFloat"):
            return float(text)
        if kind == "RichAbsPerc":
            return pymeshlab.PureValue(float(text))
        if kind == "RichPercentage":
            return pymeshlab.PercentageValue(float(text))
        if kind == "RichColor":
            return pymeshlab.Color(*(int(float(attrs[c])) for c in "rgba"))
        if kind in ("RichPosition", "RichDirection", "RichPoint3f"):
            return np.array([float(attrs[c]) for c in "xyz"])
        if kind == "RichMatrix44f":
            return np.array([float(attrs[f"val{i}"]) for i in range(16)]).reshape(4, 4)
    except (KeyError, ValueError) as exc:
        raise FilterParameterError(f"{where}: cannot read a {kind} value from {attrs!r}: {exc}") from None
    return text


def _to_pymeshlab(mesh):
    import pymeshlab

    kw = {"vertex_matrix": mesh.V, "face_matrix": mesh.F.astype(np.int32)}
    if mesh.colors is not None:
        kw["v_color_matrix"] = np.ascontiguousarray(mesh.colors, dtype=np.float64)
    if mesh.quality is not None:
        kw["v_scalar_array"] = np.ascontiguousarray(mesh.quality, dtype=np.float64)
    return pymeshlab.Mesh(**kw)


def _copy_back(ms, pms, touched: list[int]) -> None:
    """Copy meshes of the PyMeshLab set ``pms`` into the geoshape set ``ms``."""
    from geoshape_plugins.meshset import Mesh

    for pid in touched:
        pm = pms.mesh(pid)
        V = np.ascontiguousarray(pm.vertex_matrix(), dtype=np.float64)
        F = np.ascontiguousarray(pm.face_matrix(), dtype=np.int64).reshape(-1, 3)
        colors = np.asarray(pm.vertex_color_matrix(), dtype=np.float64) if pm.has_vertex_color() else None
        quality = np.asarray(pm.vertex_scalar_array(), dtype=np.float64) if pm.has_vertex_scalar() else None
        selection = np.asarray(pm.vertex_selection_array(), dtype=bool)
        if pid >= len(ms.meshes):
            ms.meshes.append(Mesh(V, F, name=f"mesh {pid}", colors=colors, quality=quality))
            continue
        mesh = ms.meshes[pid]
        same = V.shape == mesh.V.shape and np.array_equal(F, mesh.F)
        # PyMeshLab gives every mesh white colours and zero quality: do not invent them
        if mesh.colors is None and colors is not None and np.all(colors == 1.0):
            colors = None
        if mesh.quality is None and quality is not None and not np.any(quality):
            quality = None
        if same:
            if not np.array_equal(V, mesh.V):
                mesh.set_geometry(V, F, keep_attributes=True)
            mesh.colors, mesh.quality = colors, quality
            if selection.any() or mesh.selection is None:
                mesh.selection = selection if selection.any() else None
        else:
            mesh.set_geometry(V, F, keep_attributes=False)
            mesh.colors, mesh.quality = colors, quality
            mesh.selection = selection if selection.any() else None


def apply_pymeshlab_filter(ms, name: str, params: dict[str, Any], *,
                           where: str = "") -> tuple[dict, ScriptFilter]:
    """Apply PyMeshLab filter ``name`` to the current mesh of geoshape MeshSet ``ms``.

    Parameters
    ----------
    ms : geoshape_plugins.meshset.MeshSet
    name : str
        PyMeshLab Python name or MeshLab display name.
    params : dict
        Parameters by PyMeshLab name (case-insensitive); the others take PyMeshLab's
        defaults computed on the current mesh, and all are passed explicitly.
    where : str
        Prefix of error messages (script name and line).

    Returns
    -------
    outputs : dict
        What the filter returned (measures), as plain Python values.
    record : ScriptFilter
        The filter as it was applied (display name, every parameter), for scripts.

    Raises
    ------
    FilterError
        Unknown filter, unknown parameter (the valid ones are listed), or PyMeshLab's
        own error message.
    """
    try:
        import pymeshlab
    except ImportError:  # pragma: no cover - pymeshlab is a dependency
        from geoshape.errors import MissingDependencyError

        raise MissingDependencyError("running MeshLab filters needs pymeshlab: pip install pymeshlab") \
            from None
    prefix = f"{where}: " if where else ""
    pyname = resolve_pymeshlab_name(name)
    if pyname is None:
        raise FilterError(f"{prefix}unknown filter {name!r} (neither a geoshape nor a PyMeshLab filter)")
    pms = pymeshlab.MeshSet()
    for mesh in ms.meshes:
        pms.add_mesh(_to_pymeshlab(mesh))
    if ms.meshes:
        pms.set_current_mesh(ms.current_index)
    n_before = pms.mesh_number()
    try:
        defaults = pms.filter_parameter_values(pyname)
    except pymeshlab.PyMeshLabException as exc:
        raise FilterError(f"{prefix}PyMeshLab filter {pyname!r}: {exc}") from None
    lower = {k.lower(): k for k in defaults}
    full = dict(defaults)
    for key, value in params.items():
        if key.lower() not in lower:
            raise FilterParameterError(
                f"{prefix}parameter {key!r} not found for PyMeshLab filter {pyname!r}; "
                f"valid parameters: {', '.join(defaults) or '(none)'}"
            )
        full[lower[key.lower()]] = value
    try:
        out = pms.apply_filter(pyname, **full)
    except pymeshlab.PyMeshLabException as exc:
        raise FilterError(f"{prefix}PyMeshLab filter {pyname!r} failed: {str(exc).strip()}") from None
    touched = list(range(pms.mesh_number()))
    _copy_back(ms, pms, touched)
    if pms.mesh_number() > n_before or pms.current_mesh_id() != ms.current_index:
        ms.current_index = min(pms.current_mesh_id(), len(ms.meshes) - 1)
    record = _record(pms, pyname, full)
    return _plain(out or {}), record


def _record(pms, pyname: str, full: dict) -> ScriptFilter:
    """The applied filter as a script entry: PyMeshLab's own record, values at full precision."""
    with tempfile.TemporaryDirectory(prefix="geoshape-mlx-") as tmp:
        path = Path(tmp) / "filter.mlx"
        pms.save_filter_script(str(path))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            recorded = read_mlx(path)
    by_lower = {k.lower(): v for k, v in full.items()}
    if recorded:
        name, params = recorded[-1].name, recorded[-1].params
    else:  # pragma: no cover - PyMeshLab always records the filter
        name, params = None, [ScriptParam(k, {"value": str(v)}) for k, v in full.items()]
    for p in params:
        value = by_lower.get(p.name.lower())
        if isinstance(value, (bool, np.bool_)):
            p.attrs["value"] = "true" if value else "false"
        elif isinstance(value, (int, np.integer)) and p.attrs.get("type") in (
            "RichInt", "RichEnum", "RichMesh"
        ):
            p.attrs["value"] = str(int(value))
        elif isinstance(value, (float, np.floating)) and p.attrs.get("type") in (
            "RichFloat", "RichAbsPerc", "RichDynamicFloat"
        ):
            p.attrs["value"] = repr(float(value))
    return ScriptFilter(pyname, name, params)


def _plain(value):
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
