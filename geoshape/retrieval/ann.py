"""Vector search for the shape index: a memory-mapped sidecar per descriptor set.

:class:`geoshape.retrieval.index.ShapeIndex` keeps, next to its SQLite file, one *sidecar*
file per stored (descriptor, parameters) set whose descriptor is a fixed-length vector
compared by a vector distance (metric χ², L1 or L2 in the registry: ``evd*``, ``d2*``,
``shapedna``, ``gsv``, ``shd*``; CCD and LFD are not vectors and keep the in-memory path).
The sidecar is a cache: SQLite stays the only truth, and the sidecar records the content
version of the set it was built from (see :mod:`geoshape.retrieval.index`); a sidecar of
another version is brought up to date (incrementally) or rebuilt, never trusted.

Embedding
---------
Each stored row ``x`` (float64) is mapped to a float32 vector ``φ(x)`` whose Euclidean
distance ``p = ‖φ(a) − φ(b)‖`` bounds the descriptor's own distance from below:

- χ² (on absolute values, as :func:`geoshape.distances.chi2_distances`): ``φ(x) = √|x|``
  (Hellinger). Per entry ``(a − b)² / (a + b) = (√a − √b)² (√a + √b)² / (a + b)`` and the last
  factor lies in [1, 2], so ``p² / 2 ≤ χ² ≤ p²``;
- L2: ``φ(x) = x``, ``p`` is the distance itself;
- L1: ``φ(x) = x``, ``p ≤ L1 ≤ √d p``;
- ``pcavox_lb`` (rows of a pcavox descriptor's cosine projection, searched for candidates
  only): ``φ`` = the symmetry-invariant sorted magnitudes of the lowest coefficients,
  ``p ≤`` the projection bound ``≤`` the pcavox distance.

Search
------
``brute`` (exact): ``p²`` to every row (one float32 matrix-vector product over the
memory-mapped matrix), the ``2k + 10`` smallest re-scored with the descriptor's own distance
(float64) giving ``δ`` = the k-th exact distance, then *every* row whose lower bound is
``≤ δ`` (allowing for float32 rounding) re-scored too: the answer is the exact top k,
ties broken by path, as the all-pairs matrix gives. O(N d) per query.

``ivf`` (approximate): rows are stored grouped by the nearest of ``nlist ≈ √N`` k-means
centroids of the embedding; a query scans the ``nprobe`` lists whose centroids are nearest
(at least ``MIN_SCAN`` rows), then re-scores as above within the scanned rows. Rows in
lists not scanned are missed: recall below 1 (measured by ``geoshape bench index``).
O(nlist d + scanned d) per query.

k-nearest-neighbour graph
-------------------------
For diffusion re-ranking (``--rerank lcdp``) a sidecar may hold, for each row, its
:data:`GRAPH_K` nearest other rows and their distances (exact, ties by a 64-bit hash of
the path so that it does not depend on insertion order). Built on first use: all pairs in
O(N² d) (float32 BLAS blocks, certified as the brute search) up to :data:`GRAPH_IVF_MIN`
rows, above that block by block of IVF lists, skipping the lists that the triangle
inequality rules out (same graph). It is then kept up to date when the set changes: new
rows get their lists, a kept row whose list a new row improves is updated, a row that lost
a neighbour is recomputed, so the graph always equals the one built from scratch; O(N d)
per added row.

File format
-----------
``GSVEC001`` (8 bytes), the header length (8 bytes, little endian), a JSON header (meta
data and the offset, dtype and shape of each array), then the arrays, each aligned to 64
bytes, memory-mapped read-only when opened. Written to a temporary file and renamed, so a
reader sees the old file or the new one, never half of one.

Memory
------
The file holds ``N d`` float64 (exact rows) + ``N d`` float32 (embedding) + about 30 bytes
and the path per row, + ``N K`` × 16 bytes with the graph. Queries touch only what they
read: ``brute`` the whole float32 matrix (``4 N d`` bytes, in the page cache after the first
query), ``ivf`` the centroids and the scanned lists; re-scoring reads a few hundred float64
rows.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from geoshape.errors import InvalidOptionError

__all__ = ["VECTOR_METRICS", "GRAPH_K", "VectorSet", "embed", "pair_distances", "path_hashes"]

#: descriptor metrics searched through a sidecar
VECTOR_METRICS = ("chi2", "l1", "l2")
#: metrics of lower-bound rows (:func:`geoshape.retrieval.descriptors.lower_bound_rows`):
#: ``pcavox_lb`` is :func:`~geoshape.retrieval.descriptors.pcavox.pcavox_projection_distance`,
#: embedded by :func:`~geoshape.retrieval.descriptors.pcavox.pcavox_projection_embedding`
#: (its Euclidean distance bounds it from below, like L2's identity)
BOUND_METRICS = ("pcavox_lb",)
#: neighbours stored per row in the k-nearest-neighbour graph
GRAPH_K = 10
#: a query in ``ivf`` mode scans at least this many rows
MIN_SCAN = 4096
#: :meth:`VectorSet.build_graph` prunes by IVF lists above this many rows
GRAPH_IVF_MIN = 20_000
#: rows of the k-means training sample per list
TRAIN_PER_LIST = 32
KMEANS_ITERATIONS = 8
MAGIC = b"GSVEC001"
_ALIGN = 64
#: float32 Gram-trick rounding allowance, per dimension, relative to the squared norms
_EPS_PER_DIM = 1e-6


# ---------------------------------------------------------------------------------------
# Distances and embedding
# ---------------------------------------------------------------------------------------


def embed(metric: str, X) -> np.ndarray:
    """``φ(X)``: float32 rows whose Euclidean distances bound ``metric`` from below."""
    X = np.asarray(X, dtype=np.float64)
    if metric == "chi2":
        return np.sqrt(np.abs(X)).astype(np.float32)
    if metric == "pcavox_lb":
        from geoshape.retrieval.descriptors.pcavox import pcavox_projection_embedding

        return pcavox_projection_embedding(X).astype(np.float32)
    return X.astype(np.float32)


def _smallest(p, k: int) -> np.ndarray:
    """Indices of at least the ``k`` smallest entries of ``p`` (a superset may come back):
    a threshold from a strided sample, then one comparison pass; O(len(p)), about 4x faster
    than ``argpartition`` on 10^6 entries."""
    m = len(p)
    if k >= m:
        return np.arange(m)
    if m <= 32768:
        return np.argpartition(p, k - 1)[:k]
    step = m // 8192
    sample = np.array(p[::step])
    j = min(len(sample) - 1, 4 * k // step + 8)
    idx = np.flatnonzero(p <= np.partition(sample, j)[j])
    if len(idx) < k:
        return np.argpartition(p, k - 1)[:k]
    if len(idx) > 64 * k:
        idx = idx[np.argpartition(p[idx], k - 1)[:k]]
    return idx


def _row_candidates(P: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``(row, column)`` pairs holding at least the ``k`` smallest entries of each row of
    ``P`` (more may come): each row's threshold from a strided sample of it."""
    B, N = P.shape
    if N <= 8192:
        idx = np.argpartition(P, k - 1, axis=1)[:, :k]
        return np.repeat(np.arange(B), k), idx.ravel()
    step = N // 2048
    S = np.array(P[:, ::step])
    j = min(S.shape[1] - 1, 2 * k // step + 4)
    mask = P <= np.partition(S, j, axis=1)[:, j][:, None]
    for r in np.flatnonzero(mask.sum(axis=1) < k):  # rare: too few below the sampled threshold
        mask[r, np.argpartition(P[r], k - 1)[:k]] = True
    return np.nonzero(mask)


def _list_rows(loff, chosen) -> np.ndarray:
    """Rows of the IVF lists ``chosen`` (ascending)."""
    loff = np.asarray(loff)
    return np.concatenate([np.arange(loff[j], loff[j + 1]) for j in np.sort(chosen)] or
                          [np.zeros(0, np.int64)])


def _p2_threshold(metric: str, delta):
    """The largest squared embedding distance whose lower bound is still ``≤ delta``."""
    delta = np.asarray(delta, dtype=np.float64)
    if metric == "chi2":
        return 2.0 * delta
    return delta * delta


def pair_distances(metric: str, A, B) -> np.ndarray:
    """The descriptor distance of ``A[..., i, :]`` and ``B[..., i, :]`` (broadcast), float64.

    Entry by entry the same numbers as :func:`geoshape.distances.chi2_distances` (χ²) and
    the L1 of :func:`geoshape.retrieval.descriptors.descriptor_distances`; L2 is computed
    from the differences (not the Gram trick), and every value is symmetric in A and B.
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    if metric == "chi2":
        A, B = np.abs(A), np.abs(B)
        s = A + B
        diff = A - B
        diff *= diff
        term = np.divide(diff, s, out=np.zeros(np.broadcast_shapes(A.shape, B.shape)), where=s > 0)
        return 0.5 * term.sum(axis=-1)
    if metric == "l1":
        return np.abs(A - B).sum(axis=-1)
    if metric == "l2":
        return np.sqrt(((A - B) ** 2).sum(axis=-1))
    if metric == "pcavox_lb":
        from geoshape.retrieval.descriptors.pcavox import pcavox_projection_distance

        return pcavox_projection_distance(A, B)
    raise InvalidOptionError(f"metric {metric!r} is not a vector distance "
                             f"({', '.join(VECTOR_METRICS + BOUND_METRICS)})")


_CONTROLLER = None


def _one_blas_thread():
    """One BLAS thread for a query's small products: threaded BLAS on busy cores makes a
    37,000 x 20 matrix-vector product 30x slower (measured 8.6 ms against 0.26 ms on the
    2-core CI machine under load). A cached threadpoolctl controller: 0.03 ms a call."""
    global _CONTROLLER
    try:
        if _CONTROLLER is None:
            import scipy.linalg  # noqa: F401  (threadpoolctl limits the libraries already loaded)
            from threadpoolctl import ThreadpoolController

            _CONTROLLER = ThreadpoolController()
        return _CONTROLLER.limit(limits=1, user_api="blas")
    except Exception:  # pragma: no cover - threadpoolctl unusable: leave the pools alone
        return contextlib.nullcontext()


def path_hashes(paths) -> np.ndarray:
    """A 64-bit hash of each path: the graph's tie-break (independent of insertion order)
    and the key that finds a path's row (always checked against the path itself)."""
    return _blob_hashes(*_pack_paths(list(paths)))


def _mix64(h: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser (a bijection of uint64 that spreads every input bit)."""
    h = h ^ (h >> np.uint64(30))
    h = h * np.uint64(0xBF58476D1CE4E5B9)
    h = h ^ (h >> np.uint64(27))
    h = h * np.uint64(0x94D049BB133111EB)
    return h ^ (h >> np.uint64(31))


def _blob_hashes(blob, off) -> np.ndarray:
    """Hash of each path of a blob, vectorised: the path's bytes packed 8 to a 64-bit word,
    each word mixed with its index, summed, mixed with the length (O(total bytes))."""
    blob, off = np.asarray(blob, dtype=np.uint8), np.asarray(off, dtype=np.int64)
    n = len(off) - 1
    if n <= 0:
        return np.zeros(0, dtype=np.uint64)
    lens = np.diff(off)
    words = (lens + 7) // 8
    woff = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(words, out=woff[1:])
    pos = np.arange(len(blob), dtype=np.int64) - np.repeat(off[:-1], lens)  # byte index in its path
    padded = np.zeros(8 * int(woff[-1]), dtype=np.uint8)  # each path zero-padded to whole words
    padded[8 * np.repeat(woff[:-1], lens) + pos] = blob
    packed = padded.view("<u8")
    wpos = np.arange(len(packed), dtype=np.uint64) - np.repeat(woff[:-1], words).astype(np.uint64)
    with np.errstate(over="ignore"):
        mixed = _mix64(packed ^ _mix64(wpos + np.uint64(0x9E3779B97F4A7C15)))
        h = np.zeros(n, dtype=np.uint64)
        nz = words > 0
        h[nz] = np.add.reduceat(mixed, woff[:-1][nz]) if len(mixed) else 0
        return _mix64(h ^ _mix64(lens.astype(np.uint64)))


# ---------------------------------------------------------------------------------------
# k-means (the IVF's coarse quantiser)
# ---------------------------------------------------------------------------------------


def _assign(E: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Index of the nearest centroid of each row (float32 BLAS in blocks)."""
    cn = np.einsum("ij,ij->i", C, C)
    out = np.empty(len(E), dtype=np.int32)
    block = max(1, (1 << 24) // max(1, len(C)))
    for s in range(0, len(E), block):
        G = E[s : s + block] @ C.T
        G *= -2.0
        G += cn
        out[s : s + block] = np.argmin(G, axis=1)
    return out


def _kmeans(E: np.ndarray, nlist: int, seed: int = 0) -> np.ndarray:
    """``nlist`` centroids of the rows of ``E`` (Lloyd on a sample of ``32 nlist`` rows)."""
    rng = np.random.default_rng(seed)
    n = len(E)
    m = min(n, TRAIN_PER_LIST * nlist)
    S = np.asarray(E[np.sort(rng.choice(n, m, replace=False))] if m < n else E, dtype=np.float32)
    C = S[rng.choice(len(S), nlist, replace=False)].copy()
    for _ in range(KMEANS_ITERATIONS):
        a = _assign(S, C)
        counts = np.bincount(a, minlength=nlist)
        sums = np.stack([np.bincount(a, weights=S[:, j], minlength=nlist) for j in range(S.shape[1])], 1)
        empty = counts == 0
        C = (sums / np.maximum(counts, 1)[:, None]).astype(np.float32)
        if empty.any():  # re-seed an empty list with a random sample row
            C[empty] = S[rng.choice(len(S), int(empty.sum()), replace=False)]
    return C


def n_lists(n: int) -> int:
    """Number of IVF lists for ``n`` rows: about √n."""
    return int(max(1, min(65536, round(np.sqrt(max(n, 1))))))


# ---------------------------------------------------------------------------------------
# Paths stored as one byte blob + offsets
# ---------------------------------------------------------------------------------------


def _pack_paths(paths) -> tuple[np.ndarray, np.ndarray]:
    enc = [p.encode("utf-8", "surrogatepass") for p in paths]
    off = np.zeros(len(enc) + 1, dtype=np.int64)
    if enc:
        np.cumsum([len(b) for b in enc], out=off[1:])
    return np.frombuffer(b"".join(enc), dtype=np.uint8).copy(), off


def _take_paths(blob, off, idx) -> tuple[np.ndarray, np.ndarray]:
    """The paths ``idx`` (in that order) as a new blob + offsets."""
    idx = np.asarray(idx, dtype=np.int64)
    starts = np.asarray(off[:-1])[idx]
    lens = np.asarray(off[1:])[idx] - starts
    new_off = np.zeros(len(idx) + 1, dtype=np.int64)
    np.cumsum(lens, out=new_off[1:])
    pos = np.arange(int(new_off[-1]), dtype=np.int64) - np.repeat(new_off[:-1] - starts, lens)
    return np.asarray(blob)[pos], new_off


# ---------------------------------------------------------------------------------------
# The container file
# ---------------------------------------------------------------------------------------


def _write_container(path: Path, meta: dict, arrays: dict[str, np.ndarray]) -> None:
    """Write ``meta`` and ``arrays`` to ``path`` atomically (temporary file + rename)."""
    specs, offset = {}, 0
    for name, a in arrays.items():
        a = np.ascontiguousarray(a)
        arrays[name] = a
        specs[name] = [offset, a.dtype.str, list(a.shape)]
        offset += -(-a.nbytes // _ALIGN) * _ALIGN
    header = json.dumps({"meta": meta, "arrays": specs}).encode()
    start = -(-(len(MAGIC) + 8 + len(header)) // _ALIGN) * _ALIGN
    tmp = path.parent / f".{path.name}.{os.getpid()}-{os.urandom(4).hex()}.part"
    try:
        with open(tmp, "wb") as fh:
            fh.write(MAGIC + len(header).to_bytes(8, "little") + header)
            fh.write(b"\0" * (start - fh.tell()))
            for name, a in arrays.items():
                fh.seek(start + specs[name][0])
                fh.write(memoryview(a.reshape(-1)).cast("B") if a.size else b"")
            fh.truncate(start + offset)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _read_container(path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """``(meta, arrays)`` of a container; arrays memory-mapped read-only. Raises ValueError
    (or OSError) for anything that is not a whole container."""
    with open(path, "rb") as fh:
        if fh.read(len(MAGIC)) != MAGIC:
            raise ValueError(f"{path}: not a vector sidecar")
        hlen = int.from_bytes(fh.read(8), "little")
        header = json.loads(fh.read(hlen))
        size = os.fstat(fh.fileno()).st_size
    start = -(-(len(MAGIC) + 8 + hlen) // _ALIGN) * _ALIGN
    arrays = {}
    for name, (off, dtype, shape) in header["arrays"].items():
        dt = np.dtype(dtype)
        count = int(np.prod(shape)) if shape else 1
        if start + off + count * dt.itemsize > size:
            raise ValueError(f"{path}: truncated")
        if count == 0:
            arrays[name] = np.zeros(shape, dtype=dt)
        else:
            arrays[name] = np.memmap(path, dtype=dt, mode="r", offset=start + off, shape=tuple(shape))
    return header["meta"], arrays


def _remove_stale_parts(folder: Path) -> None:
    """Delete temporaries of writers that died (their pid no longer exists on this host)."""
    for part in folder.glob(".*.part"):
        try:
            pid = int(part.name.rsplit(".", 2)[-2].split("-")[0])
            os.kill(pid, 0)
        except ProcessLookupError:
            with contextlib.suppress(OSError):
                part.unlink()
        except (ValueError, IndexError, PermissionError, OSError):
            continue


@contextlib.contextmanager
def file_lock(path: Path, timeout: float):
    """An exclusive ``flock`` on ``path``; yields True when held, False after ``timeout``
    seconds (or where file locks are unavailable), so the caller can go on without it."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield False
        return
    try:
        fh = open(path, "a+b")
    except OSError:
        yield False
        return
    try:
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except OSError:
                if time.monotonic() > deadline:
                    yield False
                    return
                time.sleep(0.05)
        try:
            yield True
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    finally:
        fh.close()


# ---------------------------------------------------------------------------------------
# One descriptor set
# ---------------------------------------------------------------------------------------


@dataclass(eq=False)
class VectorSet:
    """The rows of one (descriptor, parameters) set, grouped by IVF list, + optional graph.

    Attributes
    ----------
    meta : dict
        ``index_id``, ``descriptor``, ``params``, ``version`` (of the SQLite content it
        mirrors), ``metric``, ``shape`` (of one stored descriptor), ``trained_n``.
    X : (N, d) float64
        The stored descriptors, flattened.
    E : (N, d) float32
        Their embedding ``φ``; ``sqn`` its squared row norms.
    hashes : (N,) uint64
        :func:`path_hashes` of the paths.
    blob, off
        The paths, UTF-8, row ``i`` in ``blob[off[i]:off[i + 1]]``.
    C : (nlist, d) float32, loff : (nlist + 1,) int64
        IVF centroids; rows of list ``j`` are ``loff[j]:loff[j + 1]``.
    nbr : (N, K) int64 or None, nbd : (N, K) float64 or None
        The graph: ``nbr[i]`` the K nearest other rows (``-1`` when fewer exist), nearest
        first, ``nbd[i]`` their distances.
    """

    meta: dict
    X: np.ndarray
    E: np.ndarray
    sqn: np.ndarray
    hashes: np.ndarray
    blob: np.ndarray
    off: np.ndarray
    lists: np.ndarray
    C: np.ndarray
    loff: np.ndarray
    nbr: np.ndarray | None = None
    nbd: np.ndarray | None = None
    _sqn_max: float = field(default=-1.0, repr=False)
    _cn: np.ndarray | None = field(default=None, repr=False)  # centroid squared norms
    _by_hash: tuple | None = field(default=None, repr=False)  # (rows in hash order, sorted hashes)

    # -- basics ------------------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.X)

    @property
    def d(self) -> int:
        return self.X.shape[1]

    @property
    def metric(self) -> str:
        return self.meta["metric"]

    @property
    def version(self) -> int:
        return int(self.meta["version"])

    @property
    def nlist(self) -> int:
        return len(self.C)

    @property
    def has_graph(self) -> bool:
        return self.nbr is not None

    def path(self, i: int) -> str:
        return bytes(self.blob[int(self.off[i]) : int(self.off[i + 1])]).decode("utf-8", "surrogatepass")

    def paths(self, idx=None) -> list[str]:
        idx = range(self.n) if idx is None else idx
        return [self.path(int(i)) for i in idx]

    def positions_of(self, paths) -> dict[str, int]:
        """Row of each of ``paths`` that is stored (by hash, then checked)."""
        paths = list(paths)
        if not paths or self.n == 0:
            return {}
        want = path_hashes(paths)
        rows = np.flatnonzero(np.isin(np.asarray(self.hashes), want))
        out = {}
        wanted = set(paths)
        for r in rows.tolist():
            p = self.path(r)
            if p in wanted:
                out[p] = r
        return out

    def rows_of(self, paths) -> np.ndarray:
        """Row of each of ``paths``, ``-1`` where not stored: a binary search of its hash in
        the rows sorted by hash (sorted once per loaded set, O(N log N)), then checked
        against the path; O(P log N) for P paths."""
        paths = list(paths)
        out = np.full(len(paths), -1, dtype=np.int64)
        if not paths or self.n == 0:
            return out
        if self._by_hash is None:
            order = np.argsort(np.asarray(self.hashes), kind="stable")
            self._by_hash = (order, np.asarray(self.hashes)[order])
        order, sorted_hashes = self._by_hash
        want = path_hashes(paths)
        lo = np.searchsorted(sorted_hashes, want, side="left")
        hi = np.searchsorted(sorted_hashes, want, side="right")
        for j, (a, b) in enumerate(zip(lo.tolist(), hi.tolist(), strict=True)):
            for r in order[a:b].tolist():  # almost always one row; collisions checked
                if self.path(r) == paths[j]:
                    out[j] = r
                    break
        return out

    def sample_rows(self, size: int) -> np.ndarray:
        """Rows of the ``size`` smallest path hashes, ascending: a pseudo-random sample that
        does not depend on insertion order or list grouping, and changes little when rows
        are added or removed. O(N)."""
        size = min(int(size), self.n)
        if size <= 0:
            return np.zeros(0, dtype=np.int64)
        hashes = np.asarray(self.hashes)
        rows = np.argpartition(hashes, size - 1)[:size] if size < self.n else np.arange(self.n)
        return np.sort(rows).astype(np.int64)

    def _eps(self, extra_sqn) -> np.ndarray:
        """Allowance for float32 rounding of squared embedding distances."""
        if self._sqn_max < 0:
            self._sqn_max = float(np.max(self.sqn)) if self.n else 0.0
        return _EPS_PER_DIM * (self.d + 8) * (self._sqn_max + np.asarray(extra_sqn, dtype=np.float64)) + 1e-30

    # -- building ----------------------------------------------------------------------
    @classmethod
    def build(cls, meta: dict, paths: list[str], X: np.ndarray, *, seed: int = 0) -> VectorSet:
        """A set from its rows (IVF trained on them, no graph)."""
        X = np.ascontiguousarray(np.asarray(X, dtype=np.float64).reshape(len(paths), -1))
        E = embed(meta["metric"], X)
        blob, off = _pack_paths(paths)
        hashes = _blob_hashes(blob, off)
        meta = {**meta, "trained_n": len(paths)}
        C = _kmeans(E, n_lists(len(E)), seed) if len(E) else np.zeros((1, X.shape[1]), np.float32)
        lists = _assign(E, C) if len(E) else np.zeros(0, np.int32)
        vs = cls(meta, X, E, np.einsum("ij,ij->i", E, E), hashes, blob, off, lists, C,
                 np.zeros(1, np.int64))
        return vs._sorted_by_list()

    def _sorted_by_list(self, order=None) -> VectorSet:
        """Rows regrouped by IVF list (stable); the graph's row numbers follow."""
        if order is None:
            order = np.argsort(self.lists, kind="stable")
        inv = np.empty(self.n, dtype=np.int64)
        inv[order] = np.arange(self.n)
        blob, off = _take_paths(self.blob, self.off, order)
        nbr = nbd = None
        if self.nbr is not None:
            nb = np.asarray(self.nbr)[order]
            nbr = np.where(nb >= 0, inv[np.maximum(nb, 0)], -1)
            nbd = np.asarray(self.nbd)[order]
        lists = np.asarray(self.lists)[order]
        loff = np.zeros(self.nlist + 1, dtype=np.int64)
        np.cumsum(np.bincount(lists, minlength=self.nlist), out=loff[1:])
        return VectorSet(dict(self.meta), np.asarray(self.X)[order], np.asarray(self.E)[order],
                         np.asarray(self.sqn)[order], np.asarray(self.hashes)[order], blob, off, lists,
                         np.asarray(self.C), loff, nbr, nbd)

    def updated(self, removed_paths, added_paths: list[str], added_X: np.ndarray, version: int) -> VectorSet:
        """This set with rows removed (by path; a changed row is removed and added) and
        rows added, at ``version``; the graph, if any, is brought up to date exactly.

        O(N) copying; IVF centroids retrained when N has doubled or halved since training;
        graph: O(N d) per added row and per row that lost one of its neighbours.
        """
        pos = self.positions_of(removed_paths)
        keep = np.ones(self.n, dtype=bool)
        keep[list(pos.values())] = False
        kept = np.flatnonzero(keep)
        added_X = np.asarray(added_X, dtype=np.float64)
        if added_X.size != len(added_paths) * self.d:
            raise ValueError(f"{len(added_paths)} rows of {added_X.size} values: "
                             f"not of the set's length {self.d}")
        added_X = added_X.reshape(len(added_paths), self.d)
        X = np.concatenate([np.asarray(self.X)[kept], added_X])
        E_new = embed(self.metric, added_X)
        E = np.concatenate([np.asarray(self.E)[kept], E_new])
        sqn = np.concatenate([np.asarray(self.sqn)[kept], np.einsum("ij,ij->i", E_new, E_new)])
        hashes = np.concatenate([np.asarray(self.hashes)[kept], path_hashes(added_paths)])
        kb, ko = _take_paths(self.blob, self.off, kept)
        ab, ao = _pack_paths(added_paths)
        blob = np.concatenate([kb, ab])
        off = np.concatenate([ko, ao[1:] + ko[-1]])
        n = len(X)
        meta = {**self.meta, "version": int(version)}
        trained = int(meta.get("trained_n", self.n))
        C = np.asarray(self.C)
        if n and (n > 2 * trained or 2 * n < trained or len(C) > n):
            C = _kmeans(E, n_lists(n))
            lists = _assign(E, C)
            meta["trained_n"] = n
        else:
            lists = np.concatenate([np.asarray(self.lists)[kept],
                                    _assign(E_new, C) if len(E_new) else np.zeros(0, np.int32)])
        out = VectorSet(meta, X, E, sqn, hashes, blob, off, lists, C, np.zeros(len(C) + 1, np.int64))
        if self.nbr is not None:
            remap = np.full(self.n, -1, dtype=np.int64)
            remap[kept] = np.arange(len(kept))
            old = np.asarray(self.nbr)[kept]
            nbr = np.where(old >= 0, remap[np.maximum(old, 0)], -1)
            nbd = np.array(np.asarray(self.nbd)[kept], dtype=np.float64)
            lost = ((old >= 0) & (nbr < 0)).any(axis=1)
            short = (nbr < 0).sum(axis=1) > max(0, GRAPH_K - (n - 1))  # lists not full but could be
            out.nbr = np.concatenate([nbr, np.full((len(added_paths), GRAPH_K), -1, np.int64)])
            out.nbd = np.concatenate([nbd, np.full((len(added_paths), GRAPH_K), np.inf)])
            out._update_graph(dirty=np.flatnonzero(lost | short),
                              new=np.arange(len(kept), n, dtype=np.int64))
        return out._sorted_by_list()

    # -- persistence -------------------------------------------------------------------
    def save(self, path: Path) -> None:
        arrays = {"X": self.X, "E": self.E, "sqn": self.sqn, "hashes": self.hashes, "blob": self.blob,
                  "off": self.off, "lists": self.lists, "C": self.C, "loff": self.loff}
        if self.nbr is not None:
            arrays.update(nbr=self.nbr, nbd=self.nbd)
        _remove_stale_parts(path.parent)
        _write_container(path, {**self.meta, "graph_k": GRAPH_K if self.nbr is not None else 0}, arrays)

    @classmethod
    def load(cls, path: Path) -> VectorSet:
        meta, a = _read_container(path)
        if meta.get("graph_k", 0) not in (0, GRAPH_K):
            a.pop("nbr", None)
            a.pop("nbd", None)
        # plain ndarray views of the mapped file: the same pages, without np.memmap's
        # per-indexing overhead (5 µs a call: it dominated looking up a few hundred paths)
        a = {name: np.asarray(v) for name, v in a.items()}
        return cls(meta, a["X"], a["E"], a["sqn"], a["hashes"], a["blob"], a["off"], a["lists"], a["C"],
                   a["loff"], a.get("nbr"), a.get("nbd"))

    def nbytes(self) -> int:
        arrays = (self.X, self.E, self.sqn, self.hashes, self.blob, self.off, self.lists, self.C, self.loff,
                  self.nbr, self.nbd)
        return int(sum(a.nbytes for a in arrays if a is not None))

    # -- search ------------------------------------------------------------------------
    def search(self, q, k: int, *, mode: str = "brute", nprobe: int | None = None,
               min_scan: int = MIN_SCAN, certify: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Rows of the ``k`` nearest stored descriptors to ``q`` and their exact distances,
        nearest first, ties by path.

        ``mode="brute"``: the exact top k. ``mode="ivf"``: the scanned lists' exact top k
        (``nprobe`` lists nearest to the query, default ``max(8, nlist / 32)``, at least
        ``min_scan`` rows). ``certify=False``: only the ``2k + 10`` nearest by the embedding
        are re-scored (a candidate list, not guaranteed exact: where the embedding bounds
        the distance loosely, certifying re-scores many more rows).
        """
        q = np.asarray(q, dtype=np.float64).reshape(-1)
        if len(q) != self.d:
            raise InvalidOptionError(f"query descriptor has {len(q)} values, the stored ones {self.d}")
        k = min(int(k), self.n)
        if k <= 0:
            return np.zeros(0, np.int64), np.zeros(0)
        with _one_blas_thread():
            return self._search(q, k, mode, nprobe, min_scan, certify)

    def _search(self, q, k, mode, nprobe, min_scan, certify=True):
        qe = embed(self.metric, q[None])[0]
        qn = float(qe @ qe)
        if mode == "ivf" and self.nlist > 1 and self.n > min_scan:
            if nprobe is None:
                nprobe = max(8, -(-self.nlist // 32))
            C, loff = np.asarray(self.C), np.asarray(self.loff)
            if self._cn is None:
                self._cn = np.einsum("ij,ij->i", C, C)
            order = np.argsort(self._cn - 2.0 * (C @ qe), kind="stable")
            sizes = np.diff(loff)[order]
            need = max(int(nprobe), int(np.searchsorted(np.cumsum(sizes), min(min_scan, self.n))) + 1)
            chosen = np.sort(order[:need])
            spans = list(zip(loff[chosen].tolist(), loff[chosen + 1].tolist(), strict=True))
            rows = np.concatenate([np.arange(a, b) for a, b in spans])
            # one product per list: the scanned rows are never copied together
            p2 = np.concatenate([self.E[a:b] @ qe for a, b in spans])
            sq = np.asarray(self.sqn)[rows]
        else:
            rows = None
            p2 = np.asarray(self.E @ qe)
            sq = np.asarray(self.sqn)
        p2 *= -2.0
        p2 += sq  # squared embedding distances minus the query's squared norm (float32)
        m = len(p2)
        k = min(k, m)
        k1 = min(m, 2 * k + 10)
        cand = _smallest(p2, k1)
        glob = cand if rows is None else rows[cand]
        dc = pair_distances(self.metric, q, np.asarray(self.X[glob]))
        if certify and len(cand) < m:  # every row whose lower bound may beat the k-th exact distance
            delta = np.partition(dc, k - 1)[k - 1]
            limit = float(_p2_threshold(self.metric, delta) + self._eps(qn)) - qn
            more = np.flatnonzero(p2 <= limit)
            more = np.setdiff1d(more, cand, assume_unique=True)
            if len(more):
                gm = more if rows is None else rows[more]
                glob = np.concatenate([glob, gm])
                dc = np.concatenate([dc, pair_distances(self.metric, q, np.asarray(self.X[gm]))])
        return self._top_by_path(glob, dc, k)

    def _top_by_path(self, rows, dist, k) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` smallest distances, ties (including all tied at the k-th) by path."""
        order = np.argsort(dist, kind="stable")
        cut = dist[order[k - 1]]
        last = int(np.searchsorted(dist[order], cut, side="right"))
        pick = order[:last]
        if last > k or len(np.unique(dist[pick])) < len(pick):
            keyed = sorted(pick.tolist(), key=lambda i: (dist[i], self.path(int(rows[i]))))
            pick = np.asarray(keyed[:k], dtype=np.int64)
        return np.asarray(rows)[pick].astype(np.int64), dist[pick]

    # -- graph -------------------------------------------------------------------------
    def build_graph(self) -> None:
        """The exact k-nearest-neighbour graph from scratch.

        Above :data:`GRAPH_IVF_MIN` rows, block by block of IVF lists: candidates from the
        lists nearest to each row, then only the lists whose lower bound (distance to the
        centroid minus the list's radius) may beat a row's K-th exact distance are scanned;
        the same graph as the all-pairs search, at a cost that depends on how clustered the
        rows are. Otherwise all pairs: O(N² d) (float32 BLAS blocks).
        """
        n = self.n
        self.X, self.E = np.asarray(self.X), np.asarray(self.E)
        self.nbr = np.full((n, GRAPH_K), -1, dtype=np.int64)
        self.nbd = np.full((n, GRAPH_K), np.inf)
        if n > GRAPH_IVF_MIN and self.nlist > 1:
            self._build_graph_ivf()
            return
        block = int(max(1, min(1024, (1 << 24) // max(n, 1))))
        for s in range(0, n, block):
            rows = np.arange(s, min(n, s + block))
            self._knn_rows(rows, self._gram(rows))

    def _gram(self, rows) -> np.ndarray:
        """Squared embedding distances of ``rows`` to every row (float32, len(rows) x N)."""
        G = np.asarray(self.E)[rows] @ np.asarray(self.E).T
        G *= -2.0
        G += np.asarray(self.sqn)[None, :]
        G += np.asarray(self.sqn)[rows][:, None]
        G[np.arange(len(rows)), rows] = np.inf  # not its own neighbour
        return G

    def _knn_rows(self, rows, P) -> None:
        """Exact K nearest other rows of each of ``rows`` (P: their :meth:`_gram` block),
        vectorised over the block: candidates below a per-row sampled threshold scored
        exactly, then every row whose lower bound may beat the K-th exact distance."""
        n, K = self.n, GRAPH_K
        if n <= 1:
            return
        rows = np.asarray(rows, dtype=np.int64)
        X = self.X
        kk = min(K, n - 1)
        ti, tj = _row_candidates(P, min(n - 1, K + 10))
        d = pair_distances(self.metric, X[rows[ti]], X[tj])
        o = np.lexsort((d, ti))
        ti, tj, d = ti[o], tj[o], d[o]
        starts = np.searchsorted(ti, np.arange(len(rows)))
        delta = d[starts + kk - 1]  # every row has at least kk candidates
        mask = P <= (_p2_threshold(self.metric, delta) + self._eps(np.asarray(self.sqn)[rows]))[:, None]
        mask[ti, tj] = False  # scored already
        ei, ej = np.nonzero(mask)
        del mask
        if len(ei):
            ti = np.concatenate([ti, ei])
            tj = np.concatenate([tj, ej])
            d = np.concatenate([d, pair_distances(self.metric, X[rows[ei]], X[ej])])
        self._store_knn(rows, ti, tj, d)

    def _store_knn(self, rows, ti, tj, d) -> None:
        """Keep, for each of ``rows``, the K scored pairs (row ``rows[ti]``, column ``tj``,
        distance ``d``) first by (distance, path hash)."""
        h = np.asarray(self.hashes)
        o = np.lexsort((h[tj], d, ti))
        ti, tj, d = ti[o], tj[o], d[o]
        rank = np.arange(len(ti)) - np.searchsorted(ti, np.arange(len(rows)))[ti]
        keep = rank < GRAPH_K
        self.nbr[rows] = -1
        self.nbd[rows] = np.inf
        self.nbr[rows[ti[keep]], rank[keep]] = tj[keep]
        self.nbd[rows[ti[keep]], rank[keep]] = d[keep]

    def _build_graph_ivf(self) -> None:
        """:meth:`build_graph` over blocks of IVF lists (rows are stored list by list)."""
        n, K = self.n, GRAPH_K
        E, sqn, X = self.E, np.asarray(self.sqn), self.X
        C = np.asarray(self.C, dtype=np.float64)
        loff = np.asarray(self.loff)
        lists = np.asarray(self.lists)
        nlist = len(C)
        rad = np.zeros(nlist)  # each list's radius in the embedding (float64, exact geometry)
        for s in range(0, n, 1 << 16):
            e = E[s : s + (1 << 16)].astype(np.float64) - C[lists[s : s + (1 << 16)]]
            np.maximum.at(rad, lists[s : s + (1 << 16)], np.einsum("ij,ij->i", e, e))
        rad = np.sqrt(rad)
        cn = np.einsum("ij,ij->i", C, C)
        kk, k1 = min(K, n - 1), min(n - 1, K + 10)
        sizes = np.diff(loff)
        j = 0
        while j < nlist:
            j1 = j + 1
            while j1 < nlist and loff[j1] - loff[j] < 256:
                j1 += 1
            rows = np.arange(loff[j], loff[j1])
            j = j1
            if not len(rows):
                continue
            Er = E[rows].astype(np.float64)
            Dc = np.maximum(np.einsum("ij,ij->i", Er, Er)[:, None] + cn[None, :] - 2.0 * (Er @ C.T), 0.0)
            # stage 1: each row's 2 nearest lists (and more until there are enough columns)
            near = np.argpartition(Dc, min(2, nlist) - 1, axis=1)[:, : min(2, nlist)]
            first = np.zeros(nlist, dtype=bool)
            first[near.ravel()] = True
            first[lists[rows]] = True
            for extra in np.argsort(Dc.min(axis=0), kind="stable"):
                if sizes[first].sum() > k1 + 1:
                    break
                first[extra] = True
            cols0 = _list_rows(loff, np.flatnonzero(first))
            P0 = self._gram_cols(rows, cols0)
            ti, tl = _row_candidates(P0, k1)
            tj = cols0[tl]
            d = pair_distances(self.metric, X[rows[ti]], X[tj])
            o = np.lexsort((d, ti))
            delta = d[o][np.searchsorted(ti[o], np.arange(len(rows))) + kk - 1]
            thr = _p2_threshold(self.metric, delta) + self._eps(sqn[rows])
            # stage 2: lists that may hold a row within the threshold of some row of the block
            lb = np.maximum(np.sqrt(Dc) - rad[None, :] - 1e-9 * (np.sqrt(Dc) + rad[None, :]), 0.0) ** 2
            more = np.flatnonzero((lb <= thr[:, None]).any(axis=0) & ~first)
            mask = P0 <= thr[:, None]
            mask[ti, tl] = False
            ei, el = np.nonzero(mask)
            ti, tj = np.concatenate([ti, ei]), np.concatenate([tj, cols0[el]])
            if len(more):
                cols1 = _list_rows(loff, more)
                fi, fl = np.nonzero(self._gram_cols(rows, cols1) <= thr[:, None])
                ti, tj = np.concatenate([ti, fi]), np.concatenate([tj, cols1[fl]])
            new = slice(len(d), None)
            d = np.concatenate([d, pair_distances(self.metric, X[rows[ti[new]]], X[tj[new]])])
            self._store_knn(rows, ti, tj, d)

    def _gram_cols(self, rows, cols) -> np.ndarray:
        """Squared embedding distances of ``rows`` to the rows ``cols`` (float32), self = inf."""
        G = np.asarray(self.E)[rows] @ np.asarray(self.E)[cols].T
        G *= -2.0
        G += np.asarray(self.sqn)[cols][None, :]
        G += np.asarray(self.sqn)[rows][:, None]
        G[rows[:, None] == cols[None, :]] = np.inf
        return G

    def _update_graph(self, dirty, new) -> None:
        """Bring the graph up to date after rows ``new`` were appended (their lists empty) and
        rows ``dirty`` lost a neighbour: exact, equal to :meth:`build_graph`."""
        n, K = self.n, GRAPH_K
        if n <= 1:
            self.nbr[:] = -1
            self.nbd[:] = np.inf
            return
        X, sqn, h = self.X, np.asarray(self.sqn), np.asarray(self.hashes)
        is_new = np.zeros(n, dtype=bool)
        is_new[new] = True
        is_dirty = np.zeros(n, dtype=bool)
        is_dirty[dirty] = True
        clean = ~(is_new | is_dirty)
        full = (self.nbr >= 0).sum(axis=1) >= min(K, n - 1)
        kth = np.where(full, self.nbd[:, K - 1 if K <= n - 1 else n - 2], np.inf)
        block = int(max(1, min(1024, (1 << 24) // n)))
        improve: dict[int, list] = {}
        for s in range(0, len(new), block):
            rows = np.asarray(new[s : s + block])
            P = self._gram(rows)
            # a clean row's list changes only if a new row comes before its K-th neighbour
            thr = _p2_threshold(self.metric, kth) + self._eps(sqn)
            ti, tj = np.nonzero((P <= thr[None, :]) & clean[None, :])
            if len(ti):
                a, r = rows[ti], tj
                d = pair_distances(self.metric, X[a], X[r])
                for aa, rr, dd in zip(a.tolist(), r.tolist(), d.tolist(), strict=True):
                    improve.setdefault(rr, []).append((aa, dd))
            self._knn_rows(rows, P)
        for r, extra in improve.items():
            c = np.concatenate([self.nbr[r][self.nbr[r] >= 0], [a for a, _ in extra]]).astype(np.int64)
            d = np.concatenate([self.nbd[r][self.nbr[r] >= 0], [v for _, v in extra]])
            o = np.lexsort((h[c], d))[:K]
            self.nbr[r, :] = -1
            self.nbd[r, :] = np.inf
            self.nbr[r, : len(o)] = c[o]
            self.nbd[r, : len(o)] = d[o]
        dirty = np.asarray(dirty, dtype=np.int64)
        for s in range(0, len(dirty), block):
            rows = dirty[s : s + block]
            self._knn_rows(rows, self._gram(rows))
