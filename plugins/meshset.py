"""``geoshape_plugins.MeshSet``: meshes plus every registered filter as a method, like PyMeshLab's.

>>> import geoshape
>>> ms = geoshape_plugins.MeshSet()                                   # doctest: +SKIP
>>> ms.load_new_mesh("cat0.off.gz")                           # doctest: +SKIP
>>> ms.geodesic_distance_from_selection(sources=[0])          # doctest: +SKIP
>>> ms.apply_filter("meshing_decimation_quadric_edge_collapse", targetfacenum=3000)  # doctest: +SKIP
>>> ms.save_filter_script("session.mlx")                      # doctest: +SKIP

Methods are generated from the registry at import (one per filter id, with its parameters
as keyword-only arguments and its documentation); unknown keyword arguments and wrong
types raise :class:`~geoshape_plugins.params.FilterParameterError` listing the valid parameters.
Every applied filter, geoshape's or PyMeshLab's, is recorded with all its parameters, so
:meth:`MeshSet.save_filter_script` writes a script that replays the session.
"""

from __future__ import annotations

import inspect
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from geoshape_plugins.mlx import ScriptFilter, ScriptParam, read_mlx, write_mlx
from geoshape_plugins.params import FilterError, FilterParameterError
from geoshape_plugins.registry import Arity, Filter, find_filter, list_filters, resolve_params

from geoshape.io.interop import mesh_input

__all__ = ["Mesh", "MeshSet", "AppliedFilter", "no_progress"]


def no_progress(fraction: float, message: str = "") -> None:
    """The default progress callback: does nothing."""


class Mesh:
    """One mesh of a :class:`MeshSet` and its per-vertex data.

    Attributes
    ----------
    V : (n, 3) float64
    F : (m, 3) int64
    name : str
    colors : (n, 4) float64 in [0, 1] or None
        Per-vertex RGBA.
    quality : (n,) float64 or None
        Per-vertex scalar (MeshLab's "quality").
    selection : (n,) bool or None
        Selected vertices.
    attributes : dict of str -> (n, ...) array
        Named per-vertex attributes (correspondence maps, embeddings, ids…).

    Expensive precomputations (geodesic solvers, embeddings) are cached with
    :meth:`cached`, keyed by their parameters, and dropped when the geometry changes.
    """

    def __init__(self, V, F, *, name: str = "mesh", colors=None, quality=None, selection=None,
                 attributes: dict | None = None):
        from geoshape.io.validate import check_mesh

        self.V, self.F = check_mesh(V, F, name=name, allow_no_faces=True, min_vertices=1)
        self.name = name
        self.colors = None if colors is None else self._per_vertex(colors, "colors", (4,))
        self.quality = None if quality is None else self._per_vertex(quality, "quality", ())
        self.selection = None if selection is None else np.asarray(selection, dtype=bool).reshape(-1)
        if self.selection is not None and len(self.selection) != len(self.V):
            raise FilterError(f"{name}: selection must have {len(self.V)} entries, got {len(self.selection)}")
        self.attributes: dict[str, np.ndarray] = dict(attributes or {})
        self._cache: dict = {}

    def _per_vertex(self, values, what: str, tail: tuple) -> np.ndarray:
        a = np.asarray(values, dtype=np.float64)
        if what == "colors" and a.ndim == 2 and a.shape[1] == 3:
            a = np.column_stack([a, np.ones(len(a))])
        if a.shape != (len(self.V), *tail):
            raise FilterError(f"{self.name}: {what} must have shape {(len(self.V), *tail)}, got {a.shape}")
        return a

    def vertex_number(self) -> int:
        return len(self.V)

    def face_number(self) -> int:
        return len(self.F)

    def bbox_diagonal(self) -> float:
        """Length of the diagonal of the axis-aligned bounding box."""
        return float(np.linalg.norm(self.V.max(axis=0) - self.V.min(axis=0)))

    def cached(self, key: tuple, compute: Callable[[], Any]) -> Any:
        """``compute()`` once per ``key`` for the current geometry."""
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

    def set_geometry(self, V, F, *, source_ids=None, keep_attributes: bool = False) -> None:
        """Replace the geometry, clearing the caches.

        Parameters
        ----------
        V : (n', 3) float
        F : (m', 3) int
        source_ids : (n',) int, optional
            For each new vertex, the old vertex whose colour, quality, selection and
            attributes it inherits (-1: a new vertex, zeros / grey / unselected).
        keep_attributes : bool
            Keep per-vertex data as is (only valid when the vertex count is unchanged).
        """
        from geoshape.io.validate import check_mesh

        V, F = check_mesh(V, F, name=self.name, allow_no_faces=True, min_vertices=1)
        if source_ids is not None:
            ids = np.asarray(source_ids, dtype=np.int64)
            new = ids < 0
            take = np.where(new, 0, ids)

            def carry(a, fill):
                if a is None:
                    return None
                out = a[take].copy()
                out[new] = fill
                return out

            self.colors = carry(self.colors, (0.5, 0.5, 0.5, 1.0))
            self.quality = carry(self.quality, 0.0)
            self.selection = carry(self.selection, False)
            self.attributes = {k: carry(a, 0) for k, a in self.attributes.items()}
        elif not (keep_attributes and len(V) == len(self.V)):
            self.colors = self.quality = self.selection = None
            self.attributes = {}
        self.V, self.F = V, F
        self._cache = {}

    def copy(self) -> Mesh:
        m = Mesh(self.V.copy(), self.F.copy(), name=self.name)
        m.colors = None if self.colors is None else self.colors.copy()
        m.quality = None if self.quality is None else self.quality.copy()
        m.selection = None if self.selection is None else self.selection.copy()
        m.attributes = {k: v.copy() for k, v in self.attributes.items()}
        return m

    def __repr__(self) -> str:
        return f"Mesh({self.name!r}, {len(self.V)} vertices, {len(self.F)} faces)"


@dataclass
class AppliedFilter:
    """One filter applied in a session: what the script records and what it returned."""

    script: ScriptFilter
    outputs: dict = field(default_factory=dict)
    seconds: float = 0.0
    origin: str = "geoshape"


class MeshSet:
    """A set of meshes with a current one, on which filters are applied.

    Parameters
    ----------
    progress : callable, optional
        ``progress(fraction, message)`` called by long filters.

    Examples
    --------
    >>> import trimesh
    >>> s = trimesh.creation.icosphere(2)
    >>> ms = MeshSet()
    >>> ms.add_mesh(s.vertices, s.faces, name="sphere")
    0
    >>> out = ms.geodesic_distance_from_selection(sources=[0])
    >>> round(out["max_distance"], 1) > 3.0
    True
    """

    def __init__(self, progress: Callable[[float, str], None] | None = None):
        self.meshes: list[Mesh] = []
        self.current_index = 0
        self.history: list[AppliedFilter] = []
        self.progress = progress or no_progress
        self._twin = None

    @property
    def pymeshlab_twin(self):
        """The :class:`~geoshape_plugins.pymeshlab_bridge.PyMeshLabTwin` PyMeshLab filters run on."""
        if self._twin is None:
            from geoshape_plugins.pymeshlab_bridge import PyMeshLabTwin

            self._twin = PyMeshLabTwin()
        return self._twin

    # ---- meshes -------------------------------------------------------------------
    @mesh_input
    def add_mesh(self, V, F, *, name: str | None = None, colors=None, quality=None,
                 selection=None, set_as_current: bool = True) -> int:
        """Add a mesh ``(V, F)`` or one trimesh / Open3D / pymeshlab mesh (a pymeshlab
        ``MeshSet``: its current mesh), vertex order kept; returns its index.

        Only the geometry of a mesh object is taken; give ``colors`` etc. explicitly.
        """
        name = name or f"mesh {len(self.meshes)}"
        self.meshes.append(Mesh(V, F, name=name, colors=colors, quality=quality, selection=selection))
        if set_as_current:
            self.current_index = len(self.meshes) - 1
        return len(self.meshes) - 1

    def load_new_mesh(self, path: str | os.PathLike) -> int:
        """Load a mesh file (order-preserving reader) as a new current mesh; returns its index."""
        from geoshape.io.mesh_io import load_mesh

        V, F = load_mesh(path)
        return self.add_mesh(V, F, name=Path(path).name)

    def current_mesh_as(self, kind: str):
        """The current mesh as ``kind``: ``"trimesh"``, ``"open3d"``, ``"pymeshlab"``,
        ``"pymeshlab_meshset"`` or ``"arrays"`` (a ``(V, F)`` tuple); a new object with the same
        vertex order and the per-vertex colours (see :func:`geoshape.io.interop.as_kind`)."""
        from geoshape.io.interop import as_kind

        m = self.current_mesh()
        return as_kind(kind, m.V, m.F, colors=m.colors)

    def save_current_mesh(self, path: str | os.PathLike) -> Path:
        """Write the current mesh (with its colours) atomically."""
        from geoshape.io.mesh_io import save_mesh

        m = self.current_mesh()
        return save_mesh(path, m.V, m.F, colors=m.colors)

    def mesh_number(self) -> int:
        return len(self.meshes)

    def __len__(self) -> int:
        return len(self.meshes)

    def mesh(self, index: int) -> Mesh:
        if not (isinstance(index, (int, np.integer)) and 0 <= index < len(self.meshes)):
            raise FilterError(f"no mesh {index!r}: the MeshSet holds {len(self.meshes)} meshes")
        return self.meshes[int(index)]

    def set_current_mesh(self, index: int) -> None:
        self.mesh(index)
        self.current_index = int(index)

    def current_mesh(self) -> Mesh:
        if not self.meshes:
            raise FilterError("the MeshSet is empty: load a mesh first")
        return self.meshes[self.current_index]

    # ---- filters ------------------------------------------------------------------
    def apply_filter(self, name: str, **params) -> dict:
        """Apply a geoshape filter (id or display name) or, failing that, a PyMeshLab filter.

        Returns
        -------
        dict of the filter's outputs (measures, descriptors…), possibly empty.
        """
        f = find_filter(name)
        if f is not None:
            return self._apply_geoshape(f, params)
        return self._apply_pymeshlab(name, params)

    def _check_preconditions(self, f: Filter) -> None:
        if not self.meshes:
            raise FilterError(f"filter {f.id!r} needs a mesh: the MeshSet is empty")
        if f.arity is Arity.PAIR and len(self.meshes) < 2:
            raise FilterError(f"filter {f.id!r} needs two meshes; the MeshSet holds {len(self.meshes)}")
        mesh = self.current_mesh()
        for pre in f.preconditions:
            missing = pre.check(mesh)
            if missing:
                raise FilterError(f"filter {f.id!r} needs {pre.name}: current mesh {mesh.name!r} {missing}")

    def _apply_geoshape(self, f: Filter, params: dict, line: int = 0) -> dict:
        self._check_preconditions(f)
        values = resolve_params(f, params, self)
        t0 = time.perf_counter()
        if self._twin is not None:
            self._twin.invalidate()  # geoshape filters may change meshes in place
        outputs = f.apply(self, values, self.progress) or {}
        seconds = time.perf_counter() - t0
        script = ScriptFilter(
            f.id, f.name, [ScriptParam(p.name, p.to_mlx(values[p.name])) for p in f.params], line
        )
        self.history.append(AppliedFilter(script, outputs, seconds, "geoshape"))
        return outputs

    def _apply_pymeshlab(self, name: str, params: dict | None, where: str = "", line: int = 0,
                         script: list[ScriptParam] | None = None) -> dict:
        from geoshape_plugins.pymeshlab_bridge import apply_pymeshlab_filter

        if not self.meshes:
            raise FilterError(f"filter {name!r} needs a mesh: the MeshSet is empty")
        t0 = time.perf_counter()
        outputs, record = apply_pymeshlab_filter(self, name, params, script=script, where=where)
        record.line = line
        self.history.append(AppliedFilter(record, outputs, time.perf_counter() - t0, "pymeshlab"))
        return outputs

    # ---- scripts ------------------------------------------------------------------
    def filter_script(self) -> list[ScriptFilter]:
        """Every filter applied so far, with all its parameters, as script entries."""
        return [a.script for a in self.history]

    def save_filter_script(self, path: str | os.PathLike) -> Path:
        """Write the session's filters to an ``.mlx`` script (atomically)."""
        return write_mlx(path, self.filter_script())

    def clear_filter_script(self) -> None:
        self.history.clear()

    def apply_filter_script(self, script, *, source: str | None = None) -> list[AppliedFilter]:
        """Run a script: an ``.mlx`` path or a list of :class:`ScriptFilter`.

        Every filter name is checked before anything runs; an unknown one raises
        :class:`~geoshape_plugins.mlx.FilterScriptError` with its name and line.

        Returns
        -------
        list of AppliedFilter, one per filter of the script.
        """
        from geoshape_plugins.mlx import FilterScriptError
        from geoshape_plugins.pymeshlab_bridge import closest_filter_names, resolve_pymeshlab_name

        if isinstance(script, (str, os.PathLike)):
            source = source or str(script)
            script = read_mlx(script)
        source = source or "<script>"
        plan = []
        for sf in script:
            f = find_filter(sf.id) if sf.id else None
            if f is None and not sf.id and sf.name:
                f = find_filter(sf.name)
            if f is None and resolve_pymeshlab_name(sf.key) is None:
                alt = f" (name {sf.name!r})" if sf.id and sf.name else ""
                close = closest_filter_names(sf.key)
                hint = f"; closest known names: {', '.join(repr(c) for c in close)}" if close else ""
                raise FilterScriptError(
                    f"{source}:{sf.line}: unknown filter {sf.key!r}{alt}: neither a geoshape filter "
                    f"(see 'geoshape filters') nor a PyMeshLab filter{hint}"
                )
            plan.append((sf, f))
        start = len(self.history)
        for sf, f in plan:
            where = f"{source}:{sf.line}"
            if f is not None:
                self._apply_geoshape(f, self._script_params(f, sf, where), sf.line)
            else:
                self._apply_pymeshlab(sf.key, None, where, sf.line, script=sf.params)
        return self.history[start:]

    @staticmethod
    def _script_params(f: Filter, sf: ScriptFilter, where: str) -> dict:
        import warnings

        values = {}
        for p in sf.params:
            if p.name not in f.param_names:
                warnings.warn(
                    f"{where}: filter {f.id!r} has no parameter {p.name!r} (ignored); "
                    f"valid parameters: {', '.join(f.param_names) or '(none)'}",
                    UserWarning,
                    stacklevel=3,
                )
                continue
            try:
                values[p.name] = f.param(p.name).from_mlx(p.attrs, f.id)
            except FilterParameterError as exc:
                raise FilterParameterError(f"{where}: {exc}") from None
        return values


def _bind(f: Filter):
    """A method ``ms.<f.id>(**params)`` with the filter's signature and documentation."""

    def method(self, **params):
        return self._apply_geoshape(f, params)

    method.__name__ = method.__qualname__ = f.id
    method.__signature__ = inspect.Signature(
        [inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)]
        + [inspect.Parameter(p.name, inspect.Parameter.KEYWORD_ONLY,
                             default=p.default if not callable(p.default) else None)
           for p in f.params]
    )
    lines = [f.name, "", f.description, "", "Parameters", "----------"]
    for p in f.params:
        lines += [f"{p.name} : {p.type_text()}, default {p.describe_default()}", f"    {p.tooltip}"]
    lines += ["", "Returns", "-------", "dict of outputs"]
    method.__doc__ = "\n".join(lines)
    return method


for _f in list_filters():
    setattr(MeshSet, _f.id, _bind(_f))
del _f
