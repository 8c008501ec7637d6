"""MeshLab display names and XML parameter names of PyMeshLab's filters, recorded from PyMeshLab.

A MeshLab ``.mlx`` script names a filter by its display name ("Re-Orient all faces
coherently") and its parameters by MeshLab's XML names (``stepSmoothNum``, ``lambda``).
PyMeshLab's Python API uses other names (``meshing_re_orient_faces_coherently``,
``stepsmoothnum``, ``lambda_``) and offers no listing of the display names. The table in
``data/pymeshlab_filters.json`` is therefore *recorded from PyMeshLab itself*: each filter is
applied with its defaults to a small mesh in a child process and PyMeshLab's own
``save_filter_script`` says which display name and XML parameter names it writes. Regenerate
it after upgrading PyMeshLab::

    python -m geoshape_plugins.pymeshlab_names plugins/data/pymeshlab_filters.json

It also records each parameter's MeshLab type and, for the parameters whose default does
not depend on the mesh (the same on two different probe meshes, and not a percentage or a
mesh reference), that default as a fresh PyMeshLab process computes it. PyMeshLab remembers
the last values of some filters process-wide (quadric decimation and isotropic remeshing
keep MeshLab's ``last*`` statics), so a default asked of a PyMeshLab that already ran the
filter may be a leftover; :func:`pristine_defaults` gives the recorded ones instead.

Filters that cannot run on the probe meshes (they need textures, rasters, cameras, a file)
are not in the table; :func:`geoshape_plugins.pymeshlab_bridge.resolve_pymeshlab_name` still
finds them from the display name through PyMeshLab's old-name table.

XML parameter name -> Python name is PyMeshLab's rule, checked on every recorded filter by
the tests: lower case, plus a trailing ``_`` when the result is a Python keyword
(:func:`python_param_name`).

Cost: recording applies ~210 filters, one child process each (about a minute); reading the
table is one JSON load, cached.
"""

from __future__ import annotations

import functools
import json
import keyword
import os
import re
import sys
from pathlib import Path

__all__ = ["TABLE_PATH", "normalized_name", "python_param_name", "recorded_filters",
           "pristine_defaults", "display_name_table", "record_table"]

#: Where the recorded table lives (package data).
TABLE_PATH = Path(__file__).with_name("data") / "pymeshlab_filters.json"


def normalized_name(name: str) -> str:
    """A display name compared case-insensitively, runs of white space as one space.

    >>> normalized_name("  Select non Manifold  Edges ")
    'select non manifold edges'
    """
    return re.sub(r"\s+", " ", name).strip().lower()


def python_param_name(xml_name: str) -> str:
    """PyMeshLab's Python name of a MeshLab XML parameter name.

    >>> python_param_name("stepSmoothNum"), python_param_name("lambda")
    ('stepsmoothnum', 'lambda_')
    """
    low = xml_name.lower()
    return low + "_" if keyword.iskeyword(low) else low


@functools.lru_cache(maxsize=1)
def recorded_filters() -> dict[str, dict]:
    """``{python name: {"name": display name, "params": [XML names]}}`` from the recorded table."""
    try:
        data = json.loads(TABLE_PATH.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return dict(data.get("filters", {}))


def pristine_defaults(pyname: str, live: dict) -> dict:
    """The recorded fresh-process defaults of ``pyname``'s mesh-independent parameters.

    Parameters
    ----------
    pyname : str
        PyMeshLab filter.
    live : dict
        ``filter_parameter_values(pyname)`` of the running PyMeshLab, by Python name: it
        gives the value types and says which parameters exist.

    Returns
    -------
    dict by Python name (a subset of ``live``); empty for a filter not in the table.
    """
    from geoshape_plugins.pymeshlab_bridge import script_value

    entry = recorded_filters().get(pyname, {})
    out = {}
    for xml, attrs in entry.get("defaults", {}).items():
        key = python_param_name(xml)
        if key in live:
            out[key] = script_value(attrs, f"{pyname} default {xml}", live[key])
    return out


@functools.lru_cache(maxsize=1)
def display_name_table() -> dict[str, str]:
    """``{normalized display name: python name}`` for every recorded filter."""
    return {normalized_name(entry["name"]): py for py, entry in recorded_filters().items()}


# ---- recording (run once per PyMeshLab version) ------------------------------------------
def _probe_sets():
    """Ways to set up a MeshSet before a filter: the filter keeps the first that works."""
    import numpy as np
    import pymeshlab

    def spheres(ms):
        ms.create_sphere(subdiv=2)
        ms.create_sphere(subdiv=1)
        ms.set_current_mesh(0)

    def cloud(ms):
        ms.create_sphere(subdiv=3)
        m = ms.current_mesh()
        V = m.vertex_matrix()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, v_normals_matrix=V / np.linalg.norm(V, axis=1)[:, None]))

    def selected(ms):
        ms.create_sphere(subdiv=2)
        ms.compute_selection_by_condition_per_face(condselect="(x0 > 0)")
        ms.compute_scalar_by_function_per_vertex(q="x")

    return [spheres, cloud, selected]


#: MeshLab types whose default MeshLab always computes from the meshes
MESH_DEPENDENT_TYPES = frozenset({"RichAbsPerc", "RichPercentage", "RichMesh", "RichShotf"})


def _same_default(a, b) -> bool:
    import numpy as np

    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and bool(np.all(a == b))
    if hasattr(a, "value") and callable(a.value):
        return a.value() == b.value()
    try:
        return bool(a == b) if type(a) in (bool, int, float, str) else repr(a) == repr(b)
    except Exception:  # noqa: BLE001 - an uncomparable value counts as mesh-dependent
        return False


def _record_one(pyname: str, out, setup_index: int) -> None:  # pragma: no cover - child process
    import tempfile
    import warnings

    import pymeshlab
    from geoshape_plugins.mlx import read_mlx

    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)  # PyMeshLab prints to the C stdout
    os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
    os.chdir(tempfile.mkdtemp(prefix="geoshape-probe-"))  # some filters write files (cameras.out)
    setup = _probe_sets()[setup_index]
    other = pymeshlab.MeshSet()  # the same probe, larger and finer: what differs is mesh-dependent
    setup(other)
    other.compute_matrix_from_scaling_or_normalization(axisx=3.0, uniformflag=True, alllayers=True)
    try:
        other.meshing_surface_subdivision_midpoint(iterations=1)
    except pymeshlab.PyMeshLabException:
        pass
    other_defaults = other.filter_parameter_values(pyname)
    ms = pymeshlab.MeshSet()
    setup(ms)
    defaults = ms.filter_parameter_values(pyname)
    ms.apply_filter(pyname)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "f.mlx"
        ms.save_filter_script(str(path))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            recorded = read_mlx(path)[-1]
    constant = {}
    for p in recorded.params:
        key = python_param_name(p.name)
        if (p.attrs.get("type") not in MESH_DEPENDENT_TYPES and key in defaults
                and _same_default(defaults[key], other_defaults.get(key))):
            constant[p.name] = {k: v for k, v in p.attrs.items() if k != "name"}
    out.put({"name": recorded.name, "params": [p.name for p in recorded.params],
             "types": [p.attrs.get("type", "") for p in recorded.params], "defaults": constant})


def record_table(timeout: float = 60.0, progress=None) -> dict:
    """Record display and XML parameter names of every PyMeshLab filter (see module docstring).

    Each attempt runs in a child process (some filters crash the process on unsuitable
    input); a filter that fails on every probe mesh is left out.
    """
    import multiprocessing as mp
    import queue
    import time

    import pymeshlab

    ctx = mp.get_context("fork")
    names = sorted(pymeshlab.filter_list())
    filters = {}
    for i, pyname in enumerate(names):
        for setup in range(len(_probe_sets())):
            out = ctx.Queue()
            child = ctx.Process(target=_record_one, args=(pyname, out, setup), daemon=True)
            child.start()
            entry, deadline = None, time.monotonic() + timeout
            while entry is None and time.monotonic() < deadline:
                try:
                    entry = out.get(timeout=0.2)
                except queue.Empty:
                    if not child.is_alive():  # failed or crashed: one last look, then next probe
                        try:
                            entry = out.get(timeout=0.2)
                        except queue.Empty:
                            break
            child.join(1.0)
            if child.is_alive():
                child.kill()
            if entry is not None:
                filters[pyname] = entry
                break
        if progress is not None:
            progress(i + 1, len(names), pyname, pyname in filters)
    version = getattr(pymeshlab, "__version__", None)
    if version is None:
        from importlib.metadata import version as dist_version

        version = dist_version("pymeshlab")
    return {"pymeshlab_version": version, "filters": filters}


def table_text(table: dict) -> str:
    """The table as JSON with one filter per line (small diffs when PyMeshLab changes)."""
    filters = sorted(table["filters"].items())
    lines = [f"  {json.dumps(k)}: {json.dumps(v, sort_keys=True)}" for k, v in filters]
    return ('{"pymeshlab_version": ' + json.dumps(table["pymeshlab_version"]) + ', "filters": {\n'
            + ",\n".join(lines) + "\n}}\n")


def main(argv: list[str] | None = None) -> int:  # pragma: no cover - maintenance command
    argv = sys.argv[1:] if argv is None else argv
    dest = Path(argv[0]) if argv else TABLE_PATH

    def report(i, n, name, ok):
        sys.stderr.write(f"[{i}/{n}] {'ok     ' if ok else 'skipped'} {name}\n")

    table = record_table(progress=report)
    from geoshape.io.atomic import write_text_atomic

    write_text_atomic(dest, table_text(table))
    sys.stdout.write(f"{dest}: {len(table['filters'])} filters of PyMeshLab {table['pymeshlab_version']}\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
