"""Running PyMeshLab filters on the meshes of a geoshape :class:`~geoshape_plugins.meshset.MeshSet`.

PyMeshLab cannot register Python filters, so the direction is the other way: a geoshape
MeshSet delegates any filter that is not its own to a ``pymeshlab.MeshSet`` twin holding
copies of its meshes (:class:`PyMeshLabTwin`), then copies the results back. The twin lives
on from one PyMeshLab filter to the next, so what geoshape's meshes do not hold (face
selection, per-face quality and colour, normals) carries over between consecutive PyMeshLab
filters exactly as in PyMeshLab; it is rebuilt after a geoshape filter or any change made to
the meshes from Python. A parameter left out takes MeshLab's default, never a value from an
earlier call: PyMeshLab computes the defaults that depend on the mesh on the current mesh,
and the others are the fresh-process defaults recorded in
:func:`~geoshape_plugins.pymeshlab_names.pristine_defaults` (PyMeshLab itself remembers the
last values of some filters process-wide, and so does its own script loader). The recorded
script holds every value used, so replaying it is exact.

Filter names (:func:`resolve_pymeshlab_name`), in this order: a PyMeshLab Python name
(``meshing_decimation_quadric_edge_collapse``); a current MeshLab display name ("Simplification:
Quadric Edge Collapse Decimation", recorded from PyMeshLab by
:mod:`geoshape_plugins.pymeshlab_names`); an old MeshLab display name
(:mod:`geoshape_plugins.meshlab_legacy`); else the display name in PyMeshLab's pre-2022
spelling (lower case, runs of other characters as ``_``) through PyMeshLab's own table of
renamed filters (``keys.txt`` shipped with it). Display names compare case-insensitively
with runs of white space as one.

Parameter names (:func:`script_params`): MeshLab's XML name (``stepSmoothNum``, ``lambda``)
becomes PyMeshLab's Python name by PyMeshLab's rule (lower case, ``_`` after a Python
keyword: ``lambda_``), after the old-name table for scripts of older MeshLab versions.
In scripts, a parameter the filter does not have is ignored with a warning, as PyMeshLab's
own script loader does; from Python (:meth:`MeshSet.apply_filter`) it is an error.

What is copied: vertices, faces, per-vertex colours and quality into PyMeshLab; back,
the same plus the vertex selection. geoshape's named attributes and selection are kept
when the filter leaves the vertex count and faces unchanged and dropped otherwise.
"""

from __future__ import annotations

import difflib
import functools
import re
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from geoshape_plugins.mlx import ScriptFilter, ScriptParam, read_mlx
from geoshape_plugins.params import FilterError, FilterParameterError
from geoshape_plugins.pymeshlab_names import (
    display_name_table,
    normalized_name,
    pristine_defaults,
    python_param_name,
)

__all__ = ["pymeshlab_filter_names", "resolve_pymeshlab_name", "closest_filter_names", "script_value",
           "script_params", "PyMeshLabTwin", "apply_pymeshlab_filter"]


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


@functools.lru_cache(maxsize=1)
def _legacy_filters() -> dict[str, str]:
    from geoshape_plugins.meshlab_legacy import LEGACY_FILTER_NAMES

    return {normalized_name(old): new for old, new in LEGACY_FILTER_NAMES.items()}


def resolve_pymeshlab_name(key: str) -> str | None:
    """PyMeshLab's Python name for a Python name or a current or old MeshLab display name, or None.

    >>> resolve_pymeshlab_name("Taubin Smooth")
    'apply_coord_taubin_smoothing'
    >>> resolve_pymeshlab_name("Quadric Edge Collapse Decimation")  # MeshLab <= 2016.12
    'meshing_decimation_quadric_edge_collapse'
    """
    names = pymeshlab_filter_names()
    if key in names:
        return key
    norm = normalized_name(key)
    for table in (display_name_table(), _legacy_filters()):
        if table.get(norm) in names:
            return table[norm]
    snake = re.sub(r"[^a-z0-9]+", "_", norm).strip("_")
    if snake in names:
        return snake
    new = _renamed().get(snake) or _renamed().get(re.sub(r"_+", "_", snake))
    return new if new in names else None


def closest_filter_names(key: str, n: int = 3) -> list[str]:
    """Up to ``n`` known filter names (geoshape ids and names, MeshLab display names, PyMeshLab
    Python names) closest to ``key``, for "did you mean" messages."""
    from geoshape_plugins.meshlab_legacy import LEGACY_FILTER_NAMES
    from geoshape_plugins.pymeshlab_names import recorded_filters
    from geoshape_plugins.registry import list_filters

    known = [f.id for f in list_filters()] + [f.name for f in list_filters()]
    known += [e["name"] for e in recorded_filters().values()] + list(LEGACY_FILTER_NAMES)
    known += sorted(pymeshlab_filter_names())
    by_norm = {}
    for name in known:
        by_norm.setdefault(normalized_name(name), name)
    hits = difflib.get_close_matches(normalized_name(key), list(by_norm), n=n, cutoff=0.5)
    return [by_norm[h] for h in hits]


def script_value(attrs: dict[str, str], where: str = "", like: Any = None) -> Any:
    """The PyMeshLab value of an ``.mlx`` ``<Param>`` from its ``type`` and value attributes.

    ``like`` is the filter's default value; it gives the type of a parameter written without
    ``type`` (MeshLab 2016's ``<xmlparam>``).
    """
    import pymeshlab

    kind = attrs.get("type") or _type_of(like)
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
        if kind == "RichShotf":
            raise FilterParameterError(f"{where}: camera (RichShotf) parameters are not supported")
    except (KeyError, ValueError) as exc:
        raise FilterParameterError(f"{where}: cannot read a {kind} value from {attrs!r}: {exc}") from None
    return text


def _type_of(value: Any) -> str:
    """The MeshLab type of a PyMeshLab default value (for parameters written without a type)."""
    if isinstance(value, (bool, np.bool_)):
        return "RichBool"
    if isinstance(value, (int, np.integer)):
        return "RichInt"
    if isinstance(value, (float, np.floating)):
        return "RichFloat"
    name = type(value).__name__
    return {"PureValue": "RichAbsPerc", "PercentageValue": "RichPercentage"}.get(name, "RichString")


def script_params(pyname: str, params: list[ScriptParam], defaults: dict[str, Any], where: str = "",
                  ) -> dict[str, Any]:
    """The PyMeshLab keyword values of a script filter's ``<Param>`` elements.

    Parameters
    ----------
    pyname : str
        The PyMeshLab filter.
    params : list of ScriptParam
    defaults : dict
        ``filter_parameter_values(pyname)``: the filter's parameters by Python name.
    where : str
        Script name and line, for messages.

    Old parameter names are renamed (:mod:`geoshape_plugins.meshlab_legacy`); a parameter
    the filter does not have (an old one that was dropped, or any other) is ignored with a
    warning, as PyMeshLab's script loader does.
    """
    from geoshape_plugins.meshlab_legacy import LEGACY_DROPPED_PARAMS, LEGACY_PARAM_NAMES

    renames = {k.lower(): v for k, v in LEGACY_PARAM_NAMES.get(pyname, {}).items()}
    dropped = {k.lower() for k in LEGACY_DROPPED_PARAMS.get(pyname, ())}
    lower = {k.lower(): k for k in defaults}
    values = {}
    for p in params:
        key = python_param_name(renames.get(p.name.lower(), p.name))
        key = lower.get(key, lower.get(p.name.lower()))
        if key is None:
            why = ("a parameter of older MeshLab versions that PyMeshLab's filter no longer has"
                   if p.name.lower() in dropped else "not a parameter of this filter")
            warnings.warn(f"{where}: {pyname!r} ignores {p.name!r} ({why}); valid parameters: "
                          f"{', '.join(defaults) or '(none)'}", UserWarning, stacklevel=2)
            continue
        value = script_value(p.attrs, f"{where} {p.name}", defaults[key])
        default = defaults[key]
        if isinstance(value, (bool, np.bool_)) and isinstance(default, int) and not isinstance(default, bool):
            value = int(value)  # an old bool option that became an enum (centerFlag -> traslMethod)
        values[key] = value
    return values


def _to_pymeshlab(mesh):
    import pymeshlab

    kw = {"vertex_matrix": mesh.V, "face_matrix": mesh.F.astype(np.int32)}
    if mesh.colors is not None:
        kw["v_color_matrix"] = np.ascontiguousarray(mesh.colors, dtype=np.float64)
    if mesh.quality is not None:
        kw["v_scalar_array"] = np.ascontiguousarray(mesh.quality, dtype=np.float64)
    return pymeshlab.Mesh(**kw)


def _update_mesh(mesh, pm) -> None:
    """Copy PyMeshLab mesh ``pm`` into geoshape mesh ``mesh`` (attributes kept if the faces are)."""
    V = np.ascontiguousarray(pm.vertex_matrix(), dtype=np.float64)
    F = np.ascontiguousarray(pm.face_matrix(), dtype=np.int64).reshape(-1, 3)
    colors = np.asarray(pm.vertex_color_matrix(), dtype=np.float64) if pm.has_vertex_color() else None
    quality = np.asarray(pm.vertex_scalar_array(), dtype=np.float64) if pm.has_vertex_scalar() else None
    selection = np.asarray(pm.vertex_selection_array(), dtype=bool)
    # PyMeshLab gives every mesh white colours and zero quality: do not invent them
    if mesh.colors is None and colors is not None and np.all(colors == 1.0):
        colors = None
    if mesh.quality is None and quality is not None and not np.any(quality):
        quality = None
    same = V.shape == mesh.V.shape and np.array_equal(F, mesh.F)
    if same:
        if not np.array_equal(V, mesh.V):
            mesh.set_geometry(V, F, keep_attributes=True)
        if selection.any() or mesh.selection is None:
            mesh.selection = selection if selection.any() else None
    else:
        mesh.set_geometry(V, F, keep_attributes=False)
        mesh.selection = selection if selection.any() else None
    if not _same_array(colors, mesh.colors):
        mesh.colors = colors
    if not _same_array(quality, mesh.quality):
        mesh.quality = quality


def _same_array(a, b) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))


class PyMeshLabTwin:
    """The ``pymeshlab.MeshSet`` that mirrors a geoshape MeshSet for PyMeshLab filters.

    Reused from one PyMeshLab filter to the next while the geoshape meshes are still the
    arrays it last copied back, so per-face data that only PyMeshLab keeps (face selection,
    face quality and colour) carries over as in PyMeshLab; rebuilt, O(total mesh size),
    after a geoshape filter (:meth:`invalidate`), a new mesh, or arrays assigned from Python.
    Changing a mesh's arrays in place from Python is not noticed: assign new arrays instead.
    """

    def __init__(self):
        self.pms = None
        self.ids: list[int] = []  # PyMeshLab mesh id of each geoshape mesh, in order
        self._seen: list[tuple] = []

    @staticmethod
    def _state(ms) -> list[tuple]:
        return [(m, m.V, m.F, m.colors, m.quality, m.selection) for m in ms.meshes]

    def invalidate(self) -> None:
        self.pms = None

    def _fresh(self, ms) -> bool:
        now = self._state(ms)
        return self.pms is not None and len(now) == len(self._seen) and all(
            a is b for old, new in zip(self._seen, now, strict=True) for a, b in zip(old, new, strict=True)
        )

    def meshset(self, ms):
        """The twin of ``ms``, rebuilt if stale, with ``ms``'s current mesh current."""
        import pymeshlab

        if not self._fresh(ms):
            self.pms = pymeshlab.MeshSet()
            self.ids = []
            for mesh in ms.meshes:
                self.pms.add_mesh(_to_pymeshlab(mesh))
                self.ids.append(self.pms.current_mesh_id())
            self._seen = self._state(ms)
        if self.ids:
            self.pms.set_current_mesh(self.ids[ms.current_index])
        return self.pms

    def copy_back(self, ms) -> None:
        """Bring ``ms`` up to date with the twin: changed, new and deleted meshes, current mesh."""
        from geoshape_plugins.meshset import Mesh

        pms = self.pms
        kept = [(mesh, pid) for mesh, pid in zip(ms.meshes, self.ids, strict=True) if pms.mesh_id_exists(pid)]
        for mesh, pid in kept:
            _update_mesh(mesh, pms.mesh(pid))
        ids = [pid for _, pid in kept]
        meshes = [mesh for mesh, _ in kept]
        # ids only grow: a new mesh has an id no kept mesh has, below this bound
        bound = max(self.ids, default=-1) + 2 * pms.mesh_number() + 64
        for pid in range(bound):
            if len(ids) == pms.mesh_number():
                break
            if pid not in ids and pid not in self.ids and pms.mesh_id_exists(pid):
                mesh = Mesh(np.zeros((1, 3)), np.zeros((0, 3), dtype=np.int64), name=f"mesh {pid}")
                _update_mesh(mesh, pms.mesh(pid))
                meshes.append(mesh)
                ids.append(pid)
        ms.meshes[:] = meshes
        self.ids = ids
        current = pms.current_mesh_id() if pms.mesh_number() else None
        ms.current_index = ids.index(current) if current in ids else 0
        self._seen = self._state(ms)


def apply_pymeshlab_filter(ms, name: str, params: dict[str, Any] | None = None, *,
                           script: list[ScriptParam] | None = None,
                           where: str = "") -> tuple[dict, ScriptFilter]:
    """Apply PyMeshLab filter ``name`` to the current mesh of geoshape MeshSet ``ms``.

    Parameters
    ----------
    ms : geoshape_plugins.meshset.MeshSet
    name : str
        PyMeshLab Python name or MeshLab display name (current or old).
    params : dict, optional
        Parameters by PyMeshLab name (case-insensitive); an unknown one is an error.
    script : list of ScriptParam, optional
        Or: the ``<Param>`` elements of a script (:func:`script_params`: MeshLab XML names,
        old names renamed, unknown ones ignored with a warning).
    where : str
        Prefix of messages (script name and line).

    The parameters left out take MeshLab's defaults (see the module docstring).
    Cost: the filter's, plus copying the meshes back, O(mesh size).

    Returns
    -------
    outputs : dict
        What the filter returned (measures), as plain Python values.
    record : ScriptFilter
        The filter as it was applied (display name, every parameter), for scripts.

    Raises
    ------
    FilterError
        Unknown filter (with the closest names), unknown parameter (the valid ones are
        listed), or PyMeshLab's own error message.
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
        close = closest_filter_names(name)
        hint = f"; closest known names: {', '.join(repr(c) for c in close)}" if close else ""
        raise FilterError(
            f"{prefix}unknown filter {name!r} (neither a geoshape nor a PyMeshLab filter){hint}"
        )
    twin = ms.pymeshlab_twin
    pms = twin.meshset(ms)
    try:
        defaults = pms.filter_parameter_values(pyname)
    except pymeshlab.PyMeshLabException as exc:
        raise FilterError(f"{prefix}PyMeshLab filter {pyname!r}: {exc}") from None
    given = pristine_defaults(pyname, defaults)
    if script is not None:
        given.update(script_params(pyname, script, defaults, where or name))
    lower = {k.lower(): k for k in defaults}
    for key, value in (params or {}).items():
        if key.lower() not in lower:
            raise FilterParameterError(
                f"{prefix}parameter {key!r} not found for PyMeshLab filter {pyname!r}; "
                f"valid parameters: {', '.join(defaults) or '(none)'}"
            )
        given[lower[key.lower()]] = value
    try:
        out = pms.apply_filter(pyname, **given)
    except pymeshlab.PyMeshLabException as exc:
        twin.invalidate()  # a failed filter may leave PyMeshLab's meshes half changed
        raise FilterError(f"{prefix}PyMeshLab filter {pyname!r} failed: {str(exc).strip()}") from None
    twin.copy_back(ms)
    return _plain(out or {}), _record(pms, pyname, given)


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
        value = by_lower.get(python_param_name(p.name))
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
