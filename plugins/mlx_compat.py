"""Is a ``.mlx`` script's result through geoshape the one PyMeshLab gives? (tests and ``geoshape bench mlx``)

:func:`compare_with_pymeshlab` runs a script through a geoshape
:class:`~geoshape_plugins.meshset.MeshSet` and through PyMeshLab's own
``load_filter_script`` + ``apply_filter_script`` on the same input files. When PyMeshLab
refuses the script (old MeshLab names, MeshLab 2016's ``<xmlfilter>``, which it skips), the
reference is PyMeshLab replaying the script geoshape saved (current names, every value).
Meshes are equal when the vertex arrays agree to ``1e-9`` and the faces are the same set of
oriented triangles (PyMeshLab's clustering decimation emits them in varying order).
"""

from __future__ import annotations

import os
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Comparison", "compare_with_pymeshlab", "same_mesh"]


@dataclass
class Comparison:
    """Outcome of one script.

    Attributes
    ----------
    script : str
    filters : int
        Filters geoshape ran.
    geoshape : (n_vertices, n_faces) or None
        None when geoshape failed (``error`` says why).
    pymeshlab : str
        ``"runs"``, ``"refuses: <message>"`` or ``"skips <xmlfilter>"``.
    reference : str
        What geoshape's mesh was compared with: ``"PyMeshLab"``, ``"PyMeshLab replaying geoshape's
        saved script"`` or ``"none (geoshape filters)"``.
    same : bool or None
    warnings : list of str
    """

    script: str
    filters: int = 0
    geoshape: tuple[int, int] | None = None
    pymeshlab: str = ""
    reference: str = ""
    same: bool | None = None
    error: str = ""
    warnings: list[str] = field(default_factory=list)


def _oriented_faces(F) -> np.ndarray:
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    F = np.take_along_axis(F, (np.argmin(F, axis=1)[:, None] + np.arange(3)) % 3, axis=1)
    return F[np.lexsort(F.T[::-1])]


def same_mesh(V1, F1, V2, F2, atol: float = 1e-9) -> bool:
    """Same vertices (to ``atol``, same order) and the same set of oriented faces."""
    V1, V2 = np.asarray(V1), np.asarray(V2)
    if V1.shape != V2.shape or np.asarray(F1).shape != np.asarray(F2).shape:
        return False
    return bool(np.allclose(V1, V2, rtol=0, atol=atol)) and np.array_equal(_oriented_faces(F1),
                                                                           _oriented_faces(F2))


def _pymeshlab_run(script, inputs):
    """PyMeshLab's own run: ((V, F), None) or (None, message)."""
    import pymeshlab

    pms = pymeshlab.MeshSet()
    for path in inputs:
        pms.load_new_mesh(os.fspath(path))
    pms.set_current_mesh(0)
    try:
        pms.load_filter_script(os.fspath(script))
        pms.apply_filter_script()
    except pymeshlab.PyMeshLabException as exc:
        return None, str(exc).strip().splitlines()[0]
    m = pms.current_mesh()
    return (m.vertex_matrix(), m.face_matrix()), None


def compare_with_pymeshlab(script, inputs) -> Comparison:
    """Run ``script`` on the mesh files ``inputs`` (the first current) both ways; see module doc.

    Cost: two runs of the script (three when PyMeshLab refuses it).
    """
    from geoshape_plugins.meshset import MeshSet

    script = Path(script)
    result = Comparison(script.name)
    ms = MeshSet()
    for path in inputs:
        ms.load_new_mesh(path)
    ms.set_current_mesh(0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            ms.apply_filter_script(script)
        except Exception as exc:  # noqa: BLE001 - reported, not raised: this is a comparison
            result.error = f"{type(exc).__name__}: {exc}"
            return result
    result.warnings = [str(w.message) for w in caught]
    result.filters = len(ms.history)
    mesh = ms.current_mesh()
    result.geoshape = (len(mesh.V), len(mesh.F))
    skips_xml = "<xmlfilter" in script.read_text(encoding="utf-8", errors="replace")
    ref, message = _pymeshlab_run(script, inputs)
    result.pymeshlab = "skips <xmlfilter>" if skips_xml else ("runs" if ref else f"refuses: {message}")
    if any(a.origin == "geoshape" for a in ms.history):
        result.reference = "none (geoshape filters)"
        return result
    if ref is None or skips_xml:
        with tempfile.TemporaryDirectory(prefix="geoshape-mlx-") as tmp:
            used = ms.save_filter_script(Path(tmp) / "used.mlx")
            ref, message = _pymeshlab_run(used, inputs)
        result.reference = "PyMeshLab replaying geoshape's saved script"
        if ref is None:
            result.same, result.error = False, f"PyMeshLab cannot replay the saved script: {message}"
            return result
    else:
        result.reference = "PyMeshLab"
    result.same = same_mesh(mesh.V, mesh.F, *ref)
    return result
