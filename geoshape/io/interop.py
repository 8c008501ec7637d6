"""Accept other libraries' mesh objects at the boundary, and hand results back as them.

Public functions take ``(V, F)`` arrays; :func:`as_arrays` converts a
``trimesh.Trimesh``, an Open3D ``TriangleMesh``, a pymeshlab ``Mesh`` or ``MeshSet``
(its current mesh) once, and :func:`like` converts arrays back into the caller's kind.
Detection is by type name, so Open3D is never imported unless the object came from it.
"""

from __future__ import annotations

import numpy as np

from geoshape.errors import InvalidMeshError, MissingDependencyError
from geoshape.io.validate import check_mesh


def _kind(obj) -> str:
    mod = type(obj).__module__ or ""
    name = type(obj).__name__
    if isinstance(obj, (tuple, list)) and len(obj) == 2:
        return "arrays"
    if mod.startswith("trimesh") and name == "Trimesh":
        return "trimesh"
    if mod.startswith("open3d") and name == "TriangleMesh":
        return "open3d"
    if mod.startswith("pymeshlab") and name == "Mesh":
        return "pymeshlab"
    if mod.startswith("pymeshlab") and name == "MeshSet":
        return "pymeshlab_meshset"
    return "unknown"


def is_mesh_object(obj) -> bool:
    """True for a mesh given as one object: a ``(V, F)`` pair or a trimesh / Open3D / pymeshlab mesh."""
    return _kind(obj) != "unknown"


def as_arrays(mesh, F=None, *, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """``(V, F)`` arrays from arrays or a mesh object of trimesh, Open3D or pymeshlab.

    Parameters
    ----------
    mesh : (n, 3) array_like, or (V, F) tuple, or a mesh object
        When ``F`` is given, ``mesh`` is the vertex array.
    F : (m, 3) array_like of int, optional

    Returns
    -------
    V : (n, 3) float64, F : (m, 3) int64, validated by :func:`check_mesh`.
    """
    if F is not None:
        return check_mesh(mesh, F, name=name)
    kind = _kind(mesh)
    if kind == "arrays":
        V, F = mesh
    elif kind == "trimesh":
        V, F = mesh.vertices, mesh.faces
    elif kind == "open3d":
        V, F = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    elif kind == "pymeshlab":
        V, F = mesh.vertex_matrix(), mesh.face_matrix()
    elif kind == "pymeshlab_meshset":
        current = mesh.current_mesh()
        V, F = current.vertex_matrix(), current.face_matrix()
    else:
        raise InvalidMeshError(
            f"{name}: expected (V, F) arrays, a trimesh.Trimesh, an open3d TriangleMesh or a "
            f"pymeshlab Mesh; got {type(mesh).__name__}"
        )
    return check_mesh(V, F, name=name)


def like(template, V, F, colors=None):
    """Return ``(V, F)`` (and optional per-vertex ``colors`` in [0, 1]) as ``template``'s kind.

    ``template`` is the object the caller passed in; arrays give back ``(V, F)``.
    """
    kind = _kind(template)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    C = None if colors is None else np.asarray(colors, dtype=np.float64)[:, :3]
    if kind in ("arrays", "unknown"):
        return (V, F)
    if kind == "trimesh":
        import trimesh

        mesh = trimesh.Trimesh(V, F, process=False)
        if C is not None:
            rgba = np.column_stack([np.round(C * 255), np.full(len(V), 255)])
            mesh.visual.vertex_colors = rgba.astype(np.uint8)
        return mesh
    if kind == "open3d":
        try:
            import open3d as o3d
        except ImportError as exc:  # pragma: no cover - template came from open3d
            raise MissingDependencyError("open3d is needed to return an Open3D mesh") from exc
        mesh = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F.astype(np.int32))
        )
        if C is not None:
            mesh.vertex_colors = o3d.utility.Vector3dVector(C)
        return mesh
    import pymeshlab

    if C is not None:
        rgba = np.column_stack([C, np.ones(len(V))])
        mesh = pymeshlab.Mesh(vertex_matrix=V, face_matrix=F, v_color_matrix=rgba)
    else:
        mesh = pymeshlab.Mesh(vertex_matrix=V, face_matrix=F)
    if kind == "pymeshlab_meshset":
        ms = pymeshlab.MeshSet()
        ms.add_mesh(mesh)
        return ms
    return mesh
