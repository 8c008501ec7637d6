"""Reading and writing triangle meshes without ever reordering vertices.

Benchmark ground truth is by vertex id, so the readers here keep the file's vertex order:
no merging of duplicates, no removal of unreferenced vertices. Polygons are
fan-triangulated. Formats: OFF (own parser), OBJ (own parser), PLY and STL (trimesh with
``process=False``), each optionally gzipped (``.off.gz``…). Every malformed file raises
:class:`~geoshape.errors.InvalidMeshError` naming the file — libigl's
``read_triangle_mesh`` is deliberately not used, since it aborts the interpreter on some
PLY files. Writers are atomic: a temp file beside the destination, renamed on success.

Cost: O(n + m) time and memory for n vertices and m faces.
"""

from __future__ import annotations

import gzip
import io
import os
import zlib
from pathlib import Path

import numpy as np

from geoshape.errors import InvalidMeshError
from geoshape.io.atomic import atomic_path
from geoshape.io.interop import mesh_input
from geoshape.io.validate import check_mesh

MESH_FORMATS = ("off", "obj", "ply", "stl")


def mesh_format(path: str | os.PathLike) -> tuple[str, bool]:
    """``(format, gzipped)`` of a mesh path from its extension, e.g. ``("off", True)``."""
    name = Path(path).name.lower()
    gz = name.endswith(".gz")
    if gz:
        name = name[:-3]
    ext = name.rsplit(".", 1)[-1] if "." in name else ""
    if ext not in MESH_FORMATS:
        allowed = ", ".join(f".{e}[.gz]" for e in MESH_FORMATS)
        raise InvalidMeshError(f"{path}: unsupported mesh extension (supported: {allowed})")
    return ext, gz


def is_mesh_file(path: str | os.PathLike) -> bool:
    """True when ``path`` has a supported mesh extension."""
    try:
        mesh_format(path)
    except InvalidMeshError:
        return False
    return True


def _read_bytes(path: Path, gz: bool) -> bytes:
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InvalidMeshError(f"{path}: no such file") from None
    except OSError as exc:
        raise InvalidMeshError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if gz:
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as exc:
            raise InvalidMeshError(f"{path}: corrupt gzip data: {exc}") from None
    return data


def _content_lines(text: str) -> list[str]:
    """Non-empty lines with ``#`` comments removed."""
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            out.append(line)
    return out


def _fan_triangulate(polys: list[list[int]], where: str) -> np.ndarray:
    tris: list[tuple[int, int, int]] = []
    for k, poly in enumerate(polys):
        if len(poly) < 3:
            raise InvalidMeshError(f"{where}: face {k} has {len(poly)} vertices (need >= 3)")
        for j in range(1, len(poly) - 1):
            tris.append((poly[0], poly[j], poly[j + 1]))
    try:
        return np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    except OverflowError:  # an index beyond int64: out of range for any mesh
        raise InvalidMeshError(f"{where}: face index too large (beyond 64-bit integers)") from None


def _parse_off(text: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    lines = _content_lines(text)
    if not lines:
        raise InvalidMeshError(f"{where}: empty file")
    head = lines[0].split()
    if not head[0].upper().endswith("OFF"):
        raise InvalidMeshError(f"{where}: not an OFF file (first token {head[0]!r})")
    if head[0].upper() not in ("OFF", "COFF", "NOFF", "CNOFF"):
        raise InvalidMeshError(f"{where}: unsupported OFF variant {head[0]!r}")
    rest = head[1:]
    pos = 1
    if not rest:
        if len(lines) < 2:
            raise InvalidMeshError(f"{where}: truncated OFF header (no counts line)")
        rest = lines[1].split()
        pos = 2
    try:
        n_v, n_f = int(rest[0]), int(rest[1])
    except (ValueError, IndexError):
        raise InvalidMeshError(f"{where}: bad OFF counts line {' '.join(rest)!r}") from None
    if n_v < 0 or n_f < 0:
        raise InvalidMeshError(f"{where}: negative counts in OFF header")
    if len(lines) < pos + n_v + n_f:
        raise InvalidMeshError(
            f"{where}: truncated OFF: header announces {n_v} vertices and {n_f} faces, "
            f"file has only {len(lines) - pos} data lines"
        )
    try:
        V = np.array([ln.split()[:3] for ln in lines[pos : pos + n_v]], dtype=np.float64)
    except ValueError:
        raise InvalidMeshError(f"{where}: malformed vertex line in OFF") from None
    V = V.reshape(-1, 3) if V.size else np.zeros((0, 3))
    if V.shape != (n_v, 3):
        raise InvalidMeshError(f"{where}: every OFF vertex line needs 3 coordinates")
    face_lines = lines[pos + n_v : pos + n_v + n_f]
    try:
        rows = [ln.split() for ln in face_lines]
        if rows and all(len(r) >= 4 and r[0] == "3" for r in rows):
            F = np.array([r[1:4] for r in rows], dtype=np.int64)
        else:
            polys = []
            for r in rows:
                k = int(r[0])
                if len(r) < k + 1:
                    raise InvalidMeshError(f"{where}: face line {' '.join(r)!r} lists fewer than {k} indices")
                polys.append([int(x) for x in r[1 : k + 1]])
            F = _fan_triangulate(polys, where)
    except InvalidMeshError:  # already precise (it is a ValueError too)
        raise
    except ValueError:
        raise InvalidMeshError(f"{where}: malformed face line in OFF") from None
    except OverflowError:
        raise InvalidMeshError(f"{where}: face index too large in OFF (beyond 64-bit integers)") from None
    return V, F.reshape(-1, 3)


def _parse_obj(text: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    verts: list[list[str]] = []
    polys: list[list[int]] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        if parts[0] == "v":
            if len(parts) < 4:
                raise InvalidMeshError(f"{where}:{lineno}: vertex line needs 3 coordinates")
            verts.append(parts[1:4])
        elif parts[0] == "f":
            try:
                idx = [int(tok.split("/", 1)[0]) for tok in parts[1:]]
            except ValueError:
                raise InvalidMeshError(f"{where}:{lineno}: malformed face line") from None
            n_now = len(verts)
            polys.append([i - 1 if i > 0 else n_now + i for i in idx])
    try:
        V = np.array(verts, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        raise InvalidMeshError(f"{where}: malformed vertex coordinates in OBJ") from None
    return V, _fan_triangulate(polys, where)


def _load_with_trimesh(data: bytes, fmt: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    try:
        mesh = trimesh.load(io.BytesIO(data), file_type=fmt, process=False, maintain_order=True)
    except ImportError:  # a corrupt binary file sends trimesh to an optional text decoder
        raise InvalidMeshError(f"{where}: cannot parse {fmt.upper()} file: truncated or corrupt "
                               f"(neither a complete binary {fmt.upper()} nor readable text)") from None
    except Exception as exc:  # third-party parsers raise anything on corrupt input
        raise InvalidMeshError(f"{where}: cannot parse {fmt.upper()} file: {exc}") from None
    if isinstance(mesh, trimesh.Scene):
        geoms = list(mesh.geometry.values())
        if len(geoms) != 1:
            raise InvalidMeshError(f"{where}: file holds {len(geoms)} meshes, expected one")
        mesh = geoms[0]
    V = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64)
    F = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    return V, F


def load_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh, keeping the file's vertex order.

    Parameters
    ----------
    path : str or PathLike
        ``.off``, ``.obj``, ``.ply`` or ``.stl``, optionally gzipped (``.off.gz``…).

    Returns
    -------
    V : (n, 3) float64
        Vertex positions, in file order (unreferenced vertices kept).
    F : (m, 3) int64
        Triangles (polygons fan-triangulated); ``m`` may be 0 for a point cloud.

    Raises
    ------
    InvalidMeshError
        Missing file, unsupported extension, corrupt or truncated content, NaN/inf
        coordinates, face indices out of range.

    Examples
    --------
    >>> V, F = load_mesh("bunny.off.gz")  # doctest: +SKIP
    """
    path = Path(path)
    if path.is_dir():
        raise InvalidMeshError(f"{path}: is a folder, expected a mesh file")
    fmt, gz = mesh_format(path)
    data = _read_bytes(path, gz)
    where = str(path)
    if fmt in ("off", "obj"):
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            text = data.decode("latin-1")
        V, F = (_parse_off if fmt == "off" else _parse_obj)(text, where)
    else:
        V, F = _load_with_trimesh(data, fmt, where)
    return check_mesh(V, F, name=where, allow_no_faces=True, min_vertices=1)


def _colors_uint8(colors, n: int, where: str) -> np.ndarray | None:
    if colors is None:
        return None
    C = np.asarray(colors)
    if C.ndim != 2 or C.shape[0] != n or C.shape[1] not in (3, 4):
        raise InvalidMeshError(f"{where}: colors must have shape ({n}, 3) or ({n}, 4), got {C.shape}")
    if C.dtype.kind == "f":
        if not np.isfinite(C).all():
            raise InvalidMeshError(f"{where}: colors contain NaN or inf")
        C = np.clip(np.round(C * 255.0), 0, 255)
    C = C.astype(np.uint8)
    if C.shape[1] == 3:
        C = np.column_stack([C, np.full(n, 255, np.uint8)])
    return C


def _format_rows(A: np.ndarray, fmt: str) -> str:
    buf = io.StringIO()
    if len(A):
        np.savetxt(buf, A, fmt=fmt)
    return buf.getvalue()


def _off_bytes(V, F, C) -> bytes:
    head = ("COFF" if C is not None else "OFF") + f"\n{len(V)} {len(F)} 0\n"
    if C is not None:
        rows = _format_rows(np.column_stack([V, C.astype(np.float64)]), "%.17g %.17g %.17g %d %d %d %d")
    else:
        rows = _format_rows(V, "%.17g")
    faces = _format_rows(np.column_stack([np.full(len(F), 3), F]), "%d")
    return (head + rows + faces).encode()


def _obj_bytes(V, F, C) -> bytes:
    if C is not None:
        rows = _format_rows(
            np.column_stack([V, C[:, :3] / 255.0]), "v %.17g %.17g %.17g %.6g %.6g %.6g"
        )
    else:
        rows = _format_rows(V, "v %.17g %.17g %.17g")
    return (rows + _format_rows(F + 1, "f %d %d %d")).encode()


def _ply_bytes(V, F, C) -> bytes:
    n, m = len(V), len(F)
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {n}",
              "property double x", "property double y", "property double z"]
    vfields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    if C is not None:
        header += [f"property uchar {c}" for c in ("red", "green", "blue", "alpha")]
        vfields += [("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")]
    header += [f"element face {m}", "property list uchar int vertex_indices", "end_header"]
    vert = np.empty(n, dtype=vfields)
    vert["x"], vert["y"], vert["z"] = V[:, 0], V[:, 1], V[:, 2]
    if C is not None:
        for j, key in enumerate(("red", "green", "blue", "alpha")):
            vert[key] = C[:, j]
    face = np.empty(m, dtype=[("k", "u1"), ("i", "<i4", (3,))])
    face["k"], face["i"] = 3, F
    return ("\n".join(header) + "\n").encode() + vert.tobytes() + face.tobytes()


def _stl_bytes(V, F) -> bytes:
    import trimesh

    return trimesh.Trimesh(V, F, process=False).export(file_type="stl")


@mesh_input
def save_mesh(path: str | os.PathLike, V, F, colors=None) -> Path:
    """Write a mesh atomically; vertex order is kept exactly as given.

    Parameters
    ----------
    path : str or PathLike
        Destination; the format follows the extension (``.off``, ``.obj``, ``.ply``,
        ``.stl``, each optionally ``.gz``). Coordinates are written with 17 significant
        digits (text) or as float64 (PLY), so a round trip is exact (STL stores float32
        and repeats vertices per triangle).
    V : (n, 3) array_like of float
    F : (m, 3) array_like of int
    colors : (n, 3) or (n, 4) array_like, optional
        Per-vertex colours, uint8 0–255 or float 0–1 (OFF as COFF, OBJ as ``v x y z r g b``,
        PLY as uchar properties; STL ignores them).

    Returns
    -------
    Path of the written file.
    """
    path = Path(path)
    fmt, gz = mesh_format(path)
    V, F = check_mesh(V, F, name=f"mesh for {path}", allow_no_faces=True, min_vertices=1)
    C = _colors_uint8(colors, len(V), str(path))
    if fmt == "off":
        data = _off_bytes(V, F, C)
    elif fmt == "obj":
        data = _obj_bytes(V, F, C)
    elif fmt == "ply":
        data = _ply_bytes(V, F, C)
    else:
        data = _stl_bytes(V, F)
    if gz:
        data = gzip.compress(data, compresslevel=6, mtime=0)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path
