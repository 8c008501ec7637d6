"""Property tests (hypothesis) of the public input boundary: validators and file loaders.

Whatever they are given, :func:`~geoshape.io.validate.check_mesh`,
:func:`~geoshape.io.validate.check_contour`, :func:`~geoshape.io.mesh_io.load_mesh` and
:func:`~geoshape.io.silhouette.load_silhouette` either succeed with a well-formed result or
raise a :class:`~geoshape.errors.GeoshapeError` subclass (for files: naming the file) —
never another exception, never a crash. The loaders run in a worker subprocess, since
Pillow's decoders and NumPy's buffer readers are C code that could take the interpreter
down; a dead worker fails the test with the offending bytes.

Inputs found by these tests and fixed in the library: face indices beyond 64-bit integers in
OFF/OBJ (``OverflowError``), image headers announcing billions of pixels
(``PIL.Image.DecompressionBombError``), ragged face lists given to ``check_mesh``
(``ValueError``), contour coordinates whose perimeter squared overflows in ``check_contour``
(``OverflowError``).
"""

from __future__ import annotations

import gzip
import io
import json
import select
import struct
import subprocess
import sys
import zlib

import hypothesis.extra.numpy as hnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoshape.errors import InvalidContourError, InvalidMeshError
from geoshape.io.validate import check_contour, check_mesh

FUZZ = settings(max_examples=60, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

# ---------------------------------------------------------------- validators

_scalars = st.one_of(st.floats(), st.integers(-(2**70), 2**70), st.text(max_size=2), st.none(),
                     st.booleans(), st.complex_numbers(max_magnitude=10))
_ragged = st.lists(st.one_of(_scalars, st.lists(_scalars, max_size=4)), max_size=6)
_any_array = hnp.arrays(
    dtype=st.sampled_from([np.float64, np.float32, np.int64, np.int32, np.uint64, np.uint8, np.bool_,
                           np.complex128, np.dtype("U2"), np.object_]),
    shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=6),
)
_triangles = st.lists(st.lists(st.integers(-3, 8), min_size=3, max_size=3), max_size=6)
_points3 = hnp.arrays(np.float64, st.tuples(st.integers(0, 8), st.just(3)),
                      elements=st.floats(allow_nan=True, allow_infinity=True))
_points2 = hnp.arrays(np.float64, st.tuples(st.integers(0, 20), st.just(2)),
                      elements=st.floats(allow_nan=True, allow_infinity=True))
_anything = st.one_of(_any_array, _ragged, _triangles, _points3, st.none(), st.text(max_size=3))


@pytest.mark.filterwarnings("ignore::RuntimeWarning", "ignore::numpy.exceptions.ComplexWarning")
@settings(FUZZ, max_examples=300)
@given(V=st.one_of(_anything, _points3), F=st.one_of(_anything, _triangles),
       allow_no_faces=st.booleans(), min_vertices=st.integers(0, 4))
def test_check_mesh_accepts_well_formed_or_raises_invalid_mesh(V, F, allow_no_faces, min_vertices):
    try:
        V2, F2 = check_mesh(V, F, name="probe", allow_no_faces=allow_no_faces, min_vertices=min_vertices)
    except InvalidMeshError as exc:
        assert str(exc).startswith("probe: ")
        return
    assert V2.dtype == np.float64 and V2.ndim == 2 and V2.shape[1] == 3 and len(V2) >= min_vertices
    assert np.isfinite(V2).all() and V2.flags.c_contiguous
    assert F2.dtype == np.int64 and F2.ndim == 2 and F2.shape[1] == 3
    assert len(F2) > 0 or allow_no_faces
    assert F2.size == 0 or (F2.min() >= 0 and F2.max() < len(V2))


@pytest.mark.filterwarnings("ignore::RuntimeWarning", "ignore::numpy.exceptions.ComplexWarning")
@settings(FUZZ, max_examples=300)
@given(P=st.one_of(_anything, _points2), min_points=st.integers(0, 10))
def test_check_contour_accepts_well_formed_or_raises_invalid_contour(P, min_points):
    try:
        P2 = check_contour(P, name="probe", min_points=min_points)
    except InvalidContourError as exc:
        assert str(exc).startswith("probe: ")
        return
    assert P2.dtype == np.float64 and P2.ndim == 2 and P2.shape[1] == 2 and len(P2) >= min_points
    assert np.isfinite(P2).all()


def test_inputs_the_fuzzer_found_in_the_validators_raise_named_errors():
    with pytest.raises(InvalidMeshError, match="^probe: faces are not an"):
        check_mesh(np.eye(3), [[0, 1, 2], [0, 1]], name="probe")  # ragged rows
    huge = 1e200 * np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 2], [-1, 2], [-1, 1], [-1, 0]])
    with pytest.raises(InvalidContourError, match="^probe: coordinates too large"):
        check_contour(huge, name="probe")


# ---------------------------------------------------------------- loaders, in a worker process

_WORKER = r"""
import json, sys, traceback, warnings
warnings.simplefilter("ignore")
import numpy as np
from geoshape.errors import GeoshapeError
from geoshape.io.mesh_io import load_mesh
from geoshape.io.silhouette import load_silhouette

for line in sys.stdin:
    kind, path = json.loads(line)
    try:
        if kind == "mesh":
            V, F = load_mesh(path)
            ok = (V.dtype == np.float64 and V.ndim == 2 and V.shape[1] == 3 and len(V) >= 1
                  and bool(np.isfinite(V).all()) and F.dtype == np.int64 and F.ndim == 2
                  and F.shape[1] == 3 and (F.size == 0 or (F.min() >= 0 and F.max() < len(V))))
        else:
            mask = load_silhouette(path)
            ok = mask.dtype == bool and mask.ndim == 2 and mask.size > 0 and 0 < mask.sum() < mask.size
        reply = {"result": "loaded", "well_formed": bool(ok)}
    except GeoshapeError as exc:
        reply = {"result": "error", "type": type(exc).__name__, "message": str(exc)}
    except BaseException as exc:
        reply = {"result": "escaped", "type": type(exc).__name__, "message": str(exc)[:500],
                 "traceback": traceback.format_exc()[-3000:]}
    print(json.dumps(reply), flush=True)
"""


class LoaderWorker:
    """A subprocess that loads files on request; restarted if a load killed it."""

    timeout = 120.0  # seconds for one load (they take milliseconds)

    def __init__(self):
        self.proc = None

    def _start(self):
        self.proc = subprocess.Popen([sys.executable, "-c", _WORKER], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)

    def load(self, kind: str, path) -> dict:
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        self.proc.stdin.write(json.dumps([kind, str(path)]) + "\n")
        self.proc.stdin.flush()
        # one request, one reply line: nothing is ever buffered ahead, so select() is exact
        if not select.select([self.proc.stdout], [], [], self.timeout)[0]:
            self.proc.kill()
            self.proc.wait()
            raise AssertionError(f"the loader hung for {self.timeout} s on {path.name}: "
                                 f"{path.read_bytes()[:300]!r}")
        line = self.proc.stdout.readline()
        if not line:
            code = self.proc.wait()
            raise AssertionError(f"the loader killed the interpreter (exit code {code}) on "
                                 f"{path.name}: {path.read_bytes()[:300]!r}")
        return json.loads(line)

    def close(self):
        if self.proc is not None and self.proc.poll() is None:
            self.proc.stdin.close()
            self.proc.wait(timeout=30)


@pytest.fixture(scope="module")
def worker():
    w = LoaderWorker()
    yield w
    w.close()


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


def _check_load(worker, kind, path, data: bytes):
    path.write_bytes(data)
    reply = worker.load(kind, path)
    assert reply["result"] != "escaped", (
        f"{reply['type']} escaped on {path.name} {data[:300]!r}:\n{reply['traceback']}")
    if reply["result"] == "error":
        assert reply["type"] == ("InvalidMeshError" if kind == "mesh" else "InvalidImageError"), reply
        assert str(path) in reply["message"], reply["message"]
    else:
        assert reply["well_formed"], f"{path.name} loaded into a malformed result: {data[:300]!r}"


def _valid_mesh_bytes(fmt: str) -> bytes:
    """A tetrahedron as written by ``save_mesh``."""
    import tempfile
    from pathlib import Path

    from geoshape.io.mesh_io import save_mesh

    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with tempfile.TemporaryDirectory() as tmp:
        return save_mesh(Path(tmp) / f"tet.{fmt}", V, F).read_bytes()


_TOKENS = ["OFF", "COFF", "3", "4", "0", "1", "2", "-1", "99999999999999999999", "-99999999999999999999",
           "nan", "inf", "1e999", "1.5", "v", "f", "vt", "1/1", "-3/1", "#", "ply", "format", "ascii",
           "binary_little_endian", "1.0", "element", "vertex", "face", "property", "float", "double",
           "uchar", "int", "list", "vertex_indices", "x", "y", "z", "end_header", "solid", "facet",
           "normal", "outer", "loop", "endloop", "endfacet", "endsolid", "\n", "\n", "\n"]


@st.composite
def _mutated(draw, valid: bytes) -> bytes:
    """A valid file truncated, with bytes overwritten, or with format tokens spliced in."""
    data = bytearray(valid)
    how = draw(st.sampled_from(["truncate", "overwrite", "splice"]))
    if how == "truncate":
        return bytes(data[: draw(st.integers(0, len(data)))])
    if how == "overwrite":
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        return bytes(data)
    at = draw(st.integers(0, len(data)))
    tokens = " ".join(draw(st.lists(st.sampled_from(_TOKENS), max_size=12))).encode()
    return bytes(data[:at]) + tokens + bytes(data[at:])


def _mesh_bytes(fmt: str):
    soup = st.lists(st.sampled_from(_TOKENS), max_size=60).map(lambda t: " ".join(t).encode())
    return st.one_of(st.binary(max_size=600), _mutated(_valid_mesh_bytes(fmt)), soup)


@pytest.mark.parametrize("suffix", [".off", ".obj", ".ply", ".stl", ".off.gz"])
@settings(FUZZ)
@given(data=st.data())
def test_load_mesh_on_random_bytes_loads_or_raises_invalid_mesh(worker, fuzz_dir, suffix, data):
    fmt = suffix.split(".")[1]
    content = data.draw(_mesh_bytes(fmt), label="content")
    if suffix.endswith(".gz") and data.draw(st.booleans(), label="compress"):
        content = gzip.compress(content)  # else: not gzip data at all
    _check_load(worker, "mesh", fuzz_dir / f"m{suffix}", content)


def _valid_image_bytes(fmt: str) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray((np.arange(64).reshape(8, 8) % 3 * 100).astype(np.uint8)).save(buf, format=fmt)
    return buf.getvalue()


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


@st.composite
def _forged_header(draw, fmt: str) -> bytes:
    """A well-formed header announcing any size and depth, then random bytes."""
    w, h = draw(st.integers(0, 10**6)), draw(st.integers(0, 10**6))
    tail = draw(st.binary(max_size=200))
    if fmt == "PPM":
        magic = draw(st.sampled_from([b"P1", b"P2", b"P4", b"P5", b"P6"]))
        return magic + b"\n%d %d\n%d\n" % (w, h, draw(st.integers(0, 70000))) + tail
    ihdr = struct.pack(">IIBBBBB", w, h, draw(st.sampled_from([1, 2, 4, 8, 16, 3])),
                       draw(st.sampled_from([0, 2, 3, 4, 6, 5])), 0, 0, draw(st.integers(0, 1)))
    chunks = _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", tail) + _png_chunk(b"IEND", b"")
    return b"\x89PNG\r\n\x1a\n" + chunks


@pytest.mark.parametrize("suffix, fmt", [(".png", "PNG"), (".pgm", "PPM"), (".jpg", "JPEG")])
@settings(FUZZ)
@given(data=st.data())
def test_load_silhouette_on_random_bytes_loads_or_raises_invalid_image(worker, fuzz_dir, suffix, fmt, data):
    content = data.draw(st.one_of(st.binary(max_size=600), _mutated(_valid_image_bytes(fmt)),
                                  _forged_header(fmt)), label="content")
    _check_load(worker, "image", fuzz_dir / f"s{suffix}", content)


@pytest.mark.parametrize("name, content, match", [
    ("big.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n", "face index too large"),
    ("big.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 99999999999999999999\n", "face index too large"),
    ("bigpoly.off", b"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 -99999999999999999999\n",
     "face index too large"),
    ("bomb.pgm", b"P5\n30000 30000\n255\n" + bytes(100), "image too large"),
])
def test_inputs_the_fuzzer_found_raise_named_errors(worker, fuzz_dir, name, content, match):
    path = fuzz_dir / name
    path.write_bytes(content)
    reply = worker.load("image" if name.endswith(".pgm") else "mesh", path)
    assert reply["result"] == "error", reply
    assert match in reply["message"] and str(path) in reply["message"]
