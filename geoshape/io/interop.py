"""Accept other libraries' mesh objects at the boundary, and hand results back as them.

Public functions take ``(V, F)`` arrays; :func:`as_arrays` converts a
``trimesh.Trimesh``, an Open3D ``TriangleMesh``, a pymeshlab ``Mesh`` or ``MeshSet``
(its current mesh) or a ``(V, F)`` pair once, and :func:`like` / :func:`as_kind` convert
arrays back into the caller's kind. :func:`mesh_input` is the one decorator through which
every public ``(V, F, ...)`` function also takes a single mesh object in place of ``V, F``.
Vertex order is never changed. Detection is by type name, so Open3D is never imported
unless the object came from it.
"""

from __future__ import annotations

import functools
import hashlib
import inspect

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidMeshError, MissingDependencyError
from geoshape.io.validate import check_mesh

__all__ = ["MESH_KINDS", "as_arrays", "as_kind", "is_mesh_object", "like", "mesh_content_sha256",
           "mesh_input"]

#: What :func:`as_kind` builds (``pymeshlab_meshset``: a new MeshSet holding the mesh).
MESH_KINDS = ("arrays", "trimesh", "open3d", "pymeshlab", "pymeshlab_meshset")


def _is_pair(obj) -> bool:
    """A ``(V, F)`` pair, not a list of two vertices, two faces or two meshes."""
    try:
        return np.ndim(obj[0]) == 2
    except (ValueError, TypeError):  # ragged: two pairs, or not numeric
        return False


def _kind(obj) -> str:
    mod = type(obj).__module__ or ""
    name = type(obj).__name__
    if isinstance(obj, (tuple, list)) and len(obj) == 2 and _is_pair(obj):
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


def as_arrays(mesh, F=None, *, name: str = "mesh", **check) -> tuple[np.ndarray, np.ndarray]:
    """``(V, F)`` arrays from arrays or a mesh object of trimesh, Open3D or pymeshlab.

    Parameters
    ----------
    mesh : (n, 3) array_like, or (V, F) tuple, or a mesh object
        When ``F`` is given, ``mesh`` is the vertex array.
    F : (m, 3) array_like of int, optional
    name : str
        How the mesh is named in errors.
    **check
        Passed to :func:`check_mesh` (``allow_no_faces``, ``min_vertices``).

    Returns
    -------
    V : (n, 3) float64, F : (m, 3) int64, validated by :func:`check_mesh`, vertices in the
    object's order.
    """
    if F is not None:
        return check_mesh(mesh, F, name=name, **check)
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
    return check_mesh(V, F, name=name, **check)


def like(template, V, F, colors=None):
    """Return ``(V, F)`` (and optional per-vertex ``colors`` in [0, 1]) as ``template``'s kind.

    ``template`` is the object the caller passed in; arrays give back ``(V, F)``.
    """
    kind = _kind(template)
    return as_kind("arrays" if kind == "unknown" else kind, V, F, colors)


def as_kind(kind: str, V, F, colors=None):
    """Build a mesh of ``kind`` (one of :data:`MESH_KINDS`) from ``(V, F)``, same vertex order.

    ``colors``: optional per-vertex RGB or RGBA in [0, 1] (alpha is dropped). ``"arrays"``
    gives the ``(V, F)`` tuple (float64, int64) and ignores colours.
    """
    check_choice("mesh kind", kind, MESH_KINDS)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    C = None if colors is None else np.asarray(colors, dtype=np.float64)[:, :3]
    if kind == "arrays":
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
        except ImportError as exc:  # pragma: no cover - the open3d extra is installed in the tests
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


def mesh_content_sha256(V, F) -> str:
    """Hex SHA-256 of a mesh's geometry: float64 vertices and int64 faces, in order, with shapes.

    The same geometry gives the same hash whichever library held it (O(n + m)).
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    h = hashlib.sha256(f"geoshape mesh v1 {V.shape} {F.shape}\n".encode())
    h.update(V.astype("<f8", copy=False).tobytes())
    h.update(F.astype("<i8", copy=False).tobytes())
    return h.hexdigest()


def mesh_input(func=None, *, returns_mesh: bool = False):
    """Decorator: the ``V`` argument may be one mesh object standing for ``V, F``.

    ``f(mesh, *rest)`` becomes ``f(V, F, *rest)`` with the arrays of :func:`as_arrays`
    (trimesh, Open3D, pymeshlab ``Mesh`` / ``MeshSet``, or a ``(V, F)`` pair), so later
    positional arguments keep their meaning; ``f(V, F, ...)`` is passed through untouched.
    Vertex order is never changed; the function validates the arrays as usual.

    ``returns_mesh=True`` (the generators): the mesh in a result comes back in the caller's
    kind. A returned vertex array (faces unchanged) becomes a mesh like the input when the
    input was an object; a returned named tuple with ``V`` (and ``F``) gets its ``mesh``
    field filled (``(V, F)`` for array input); a list is handled item by item.
    """
    if func is None:
        return functools.partial(mesh_input, returns_mesh=returns_mesh)
    params = list(inspect.signature(func).parameters)
    i = params.index("V")

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        template = None
        if len(args) > i:
            obj = args[i]
            if is_mesh_object(obj):
                template = obj
                V, F = _object_arrays(obj, kwargs)
                args = (*args[:i], V, F, *args[i + 1:])
            elif not returns_mesh:
                return func(*args, **kwargs)
            else:
                V, F = obj, args[i + 1] if len(args) > i + 1 else kwargs.get("F")
        elif "V" in kwargs:
            if is_mesh_object(kwargs["V"]):
                template = kwargs["V"]
                kwargs["V"], kwargs["F"] = V, F = _object_arrays(template, kwargs)
            else:
                V, F = kwargs["V"], kwargs.get("F")
        else:
            return func(*args, **kwargs)
        out = func(*args, **kwargs)
        return _in_kind(out, template, V, F) if returns_mesh else out

    return wrapper


def _object_arrays(obj, kwargs) -> tuple[np.ndarray, np.ndarray]:
    if kwargs.pop("F", None) is not None:
        raise InvalidMeshError("F is given with a mesh object; give either (V, F) arrays or one mesh")
    # lenient here: the function applies its own check (and its own messages)
    return as_arrays(obj, allow_no_faces=True, min_vertices=1)


def _in_kind(out, template, V, F):
    if isinstance(out, list):
        return [_in_kind(o, template, V, F) for o in out]
    if isinstance(out, np.ndarray):
        return out if template is None else like(template, out, F)
    return out._replace(mesh=like(template, out.V, getattr(out, "F", F)))
