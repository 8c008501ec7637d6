"""A persistent shape index: descriptors of mesh files in one SQLite file.

Each row holds one descriptor of one file: the absolute path, the SHA-256 of the file's
bytes, the descriptor name, its full parameter record (canonical JSON, see
:func:`geoshape.retrieval.descriptors.descriptor_params`), the array (float64 bytes and
shape) and the compute time. A mesh added from memory (trimesh, Open3D, pymeshlab,
``(V, F)``) is stored the same way under its name instead of a path, with the SHA-256 of
its arrays (:func:`geoshape.io.interop.mesh_content_sha256`); names are never absolute
paths, so such rows are never taken for missing files.

Robustness
----------
- **Resumable.** :meth:`ShapeIndex.add` computes descriptors in batches on the parallel
  runner and commits each batch in one transaction. A run that is killed loses at most the
  batch in flight; re-running skips every file whose (path, descriptor, parameters) row
  exists with the same content hash, so nothing is computed twice and nothing duplicated
  (the triple is the primary key).
- **Consistent readers.** The database is in WAL mode: readers see the last committed
  batch, never half of one, and are not blocked by a writer.
- **Bad files** are reported by name and skipped; the batch goes on.
- **Only its own files.** A database is recognised by ``PRAGMA application_id``; any other
  SQLite file (or any other file) is refused and never written to. A first ``add`` that
  fails before storing anything leaves no database file behind.
- **Concurrent adds.** Opening waits on locks (also while a fresh database is being set
  up by another process), and each batch first *claims* its (file, descriptor, parameters)
  rows in one transaction: a second ``add`` of the same files skips the claimed ones
  instead of computing them again. Claims of a process that died are ignored.
- **Missing files.** A query never returns a file that no longer exists;
  :meth:`ShapeIndex.prune` deletes its rows (``geoshape index prune``).

Search
------
Descriptors that are fixed-length vectors with a vector distance (χ², L1, L2: ``evd``,
``d2``, ``shapedna``, ``gsv``, ``shd`` …) are searched through a *sidecar*: one file per
(descriptor, parameters) set in the folder ``DB.ann`` beside the database, holding the rows
as a memory-mapped float64 matrix, a float32 embedding whose distances bound the
descriptor's from below, an IVF (k-means lists) and, once diffusion re-ranking has asked
for it, the k-nearest-neighbour graph (:mod:`geoshape.retrieval.ann`). ``search="auto"``
answers exactly by certified brute force up to :data:`IVF_MIN_VALUES` stored values (N x d)
and through the IVF (approximate, recall measured by ``geoshape bench index``) above.

The sidecar is a cache of the SQLite rows, never the truth. Triggers log every insert,
replacement and deletion of a row in the table ``changes`` (a global ``AUTOINCREMENT``
sequence), whatever process or version of geoshape writes; the *version* of a set is the
last sequence number that touched it. A sidecar records the index's id and the version it
mirrors; one of an older version is brought up to date from the logged changes (new rows
appended, deleted and changed ones dropped, the graph updated), one that cannot be (another
index, a newer version, log entries already trimmed) is rebuilt from SQLite. Sidecars are
written to a temporary file and renamed under a file lock, so readers never see half of
one and two writers never both rebuild; ``add`` and ``prune`` refresh the sidecars of the
sets they change and trim the log up to the version saved. A folder that cannot be written
only costs speed: the sidecar is then kept in memory.

Descriptors that are not vectors (CCD, LFD, pcavox), or ``search="memory"``, load the
stored descriptors of one set into memory once (re-loaded when the index changes) and rank
them with the descriptor's metric: O(N) descriptor distances per query. A non-vector
descriptor with cheap lower-bound rows (pcavox:
:func:`geoshape.retrieval.descriptors.lower_bound_rows`) also gets a sidecar of those rows,
the same machinery with their own metric, which the fused default searches for
candidates above :data:`FUSED_SCAN_MAX` stored shapes (:meth:`ShapeIndex._fused_candidates`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import socket
import sqlite3
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from geoshape.errors import DatasetError, InvalidOptionError
from geoshape.io.interop import mesh_input
from geoshape.retrieval.fusion import FUSED_WEIGHTS

__all__ = ["ShapeIndex", "AddReport", "Hit", "file_sha256", "expand_mesh_inputs",
           "DEFAULT_INDEX_DESCRIPTORS", "DEFAULT_QUERY_METHOD", "SCHEMA_VERSION", "SEARCH_MODES",
           "IVF_MIN_VALUES", "rerank_choices", "check_rerank", "query_methods", "check_query_method"]

SCHEMA_VERSION = 2  # 2: sets, changes and the triggers that log every change of entries
#: ``PRAGMA application_id`` of a geoshape index (the bytes "GSHP")
APPLICATION_ID = 0x47534850
#: Seconds after which a claim of a process on another host is considered abandoned.
CLAIM_LIFETIME = 3600.0
#: descriptors stored by ``index add`` when none is named: the components of the fused
#: default (:data:`geoshape.retrieval.descriptors.DEFAULT_RETRIEVAL_METHOD`), which ``query``
#: ranks by when no descriptor is named
DEFAULT_INDEX_DESCRIPTORS = tuple(n for n, w in FUSED_WEIGHTS.items() if w > 0)
#: what ``query`` ranks by when no descriptor is named
DEFAULT_QUERY_METHOD = "fused"
#: how queries search: ``auto`` (exact brute force over the sidecar, IVF above
#: :data:`IVF_MIN_VALUES`), ``brute`` (always exact), ``ivf`` (always the IVF), ``memory``
#: (no sidecar: every stored descriptor loaded from SQLite, O(N) distances). The fused
#: default above :data:`FUSED_SCAN_MAX` shapes scores a candidate list in every mode but
#: ``memory``.
SEARCH_MODES = ("auto", "brute", "ivf", "memory")
#: ``search="auto"`` uses the IVF above this many stored values (rows x descriptor length):
#: 400,000 EVD rows; exact brute force costs about 4 ms there (``geoshape bench index``)
IVF_MIN_VALUES = 8_000_000
#: first-stage distances up to this are a stored copy of the query (unit-free fused and
#: normalised distances; exact copies give 0 up to rounding): ranked first after re-ranking
DUPLICATE_DISTANCE = 1e-12

#: threads (each with its own read-only connection) reading the candidates' rows of a
#: non-vector component in a large fused query: random disk reads overlap
READ_THREADS = 4
#: diffusion re-ranking gathers the shortlist's neighbours and theirs from the stored graph
DIFFUSION_HOPS = 2
#: a fused query scans every stored shape exactly up to this many (all components' distances,
#: exact medians); above, it scores a candidate list (:meth:`ShapeIndex._fused_candidates`:
#: about FUSED_SAMPLE + 5 FUSED_CANDIDATES = 416 shapes, so the two cost the same order here)
FUSED_SCAN_MAX = 1000
#: above :data:`FUSED_SCAN_MAX`: nearest stored shapes taken from each vector component
FUSED_CANDIDATES = 32
#: above :data:`FUSED_SCAN_MAX`: stored shapes whose distances give each component's median
FUSED_SAMPLE = 256
#: above :data:`FUSED_SCAN_MAX`: candidates of a lower-bounded component (pcavox) read first,
#: its best by the bound (their exact distances give its nearest items), and then per round
#: of the branch and bound
FUSED_LB_SEED = 8

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS entries (
    path TEXT NOT NULL,
    descriptor TEXT NOT NULL,
    params TEXT NOT NULL,
    sha256 TEXT NOT NULL,
    shape TEXT NOT NULL,
    data BLOB NOT NULL,
    seconds REAL,
    added REAL NOT NULL,
    PRIMARY KEY (path, descriptor, params)
);
CREATE INDEX IF NOT EXISTS entries_by_descriptor ON entries (descriptor, params);
CREATE TABLE IF NOT EXISTS claims (
    path TEXT NOT NULL,
    descriptor TEXT NOT NULL,
    params TEXT NOT NULL,
    host TEXT NOT NULL,
    pid INTEGER NOT NULL,
    since REAL NOT NULL,
    PRIMARY KEY (path, descriptor, params)
);
CREATE TABLE IF NOT EXISTS sets (
    id INTEGER PRIMARY KEY,
    descriptor TEXT NOT NULL,
    params TEXT NOT NULL,
    floor INTEGER NOT NULL DEFAULT 0,
    UNIQUE (descriptor, params)
);
CREATE TABLE IF NOT EXISTS changes (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    set_id INTEGER NOT NULL,
    path TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS changes_by_set ON changes (set_id, seq);
"""

# Every change of a row is logged with its set (created on first use: a plain INSERT guarded
# by NOT EXISTS, since an outer INSERT OR REPLACE would turn an INSERT OR IGNORE in a trigger
# into a REPLACE that renumbers the set). ``floor``: log entries up to it were trimmed.
_LOG = """INSERT INTO sets (descriptor, params) SELECT {r}.descriptor, {r}.params
        WHERE NOT EXISTS (SELECT 1 FROM sets WHERE descriptor = {r}.descriptor AND params = {r}.params);
    INSERT INTO changes (set_id, path) SELECT id, {r}.path FROM sets
        WHERE descriptor = {r}.descriptor AND params = {r}.params;"""
_TRIGGERS = [
    f"CREATE TRIGGER IF NOT EXISTS entries_log_{event.lower()} AFTER {event} ON entries BEGIN {body} END"
    for event, body in (("INSERT", _LOG.format(r="NEW")), ("DELETE", _LOG.format(r="OLD")),
                        ("UPDATE", _LOG.format(r="OLD") + " " + _LOG.format(r="NEW")))
]


def file_sha256(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's bytes (streamed, O(size))."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def expand_mesh_inputs(inputs) -> list[Path]:
    """Mesh files named directly, plus the mesh files found (recursively) in folders.

    Order: inputs in the order given, folder contents sorted; duplicates removed. A named
    file is kept whatever its extension (so an unsupported one is reported, not ignored).

    Raises
    ------
    DatasetError
        An input that does not exist.
    """
    from geoshape.io.mesh_io import is_mesh_file

    out: list[Path] = []
    seen: set[Path] = set()
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.rglob("*") if q.is_file() and is_mesh_file(q))
        elif p.is_file():
            found = [p]
        else:
            raise DatasetError(f"{p}: no such file or folder")
        for q in found:
            r = q.resolve()
            if r not in seen:
                seen.add(r)
                out.append(r)
    return out


@dataclass(eq=False)
class _MemoryMesh:
    """A mesh added from memory: its key in the index, the hash of its arrays, the arrays."""

    name: str
    sha256: str
    V: np.ndarray
    F: np.ndarray

    def __str__(self) -> str:
        return self.name


def _is_gone(key: str) -> bool:
    """A stored file that no longer exists (a mesh added from memory, stored under a name
    that is not an absolute path, never is)."""
    return os.path.isabs(key) and not Path(key).is_file()


@dataclass
class AddReport:
    """What :meth:`ShapeIndex.add` did: rows added, skipped as unchanged, failures."""

    added: int = 0
    skipped: int = 0
    failed: list[tuple[str, str]] = field(default_factory=list)  # (path or name, message)
    batches: int = 0
    seconds: float = 0.0
    claimed_elsewhere: int = 0  # rows another concurrent add was computing


@dataclass(frozen=True)
class Hit:
    """One query result."""

    rank: int
    path: str  # the file's absolute path, or the name of a mesh added from memory
    distance: float
    first_distance: float | None = None  # before re-ranking


class ShapeIndex:
    """Descriptors of mesh files stored in SQLite (WAL); add, skip unchanged, query.

    Parameters
    ----------
    path : str or PathLike
        The database file (created if missing).
    timeout : float
        Seconds to wait for a lock held by another writer.
    search : {"auto", "brute", "ivf", "memory"}
        How queries of vector descriptors search (:data:`SEARCH_MODES`).
    nprobe : int or None
        IVF lists scanned per query (default ``max(8, lists / 32)``).
    min_scan : int or None
        An IVF query scans at least this many rows (default
        :data:`geoshape.retrieval.ann.MIN_SCAN`; smaller sets are searched exactly).

    Examples
    --------
    >>> idx = ShapeIndex("shapes.db")  # doctest: +SKIP
    >>> idx.add(["meshes/"], descriptors=["evd"])  # doctest: +SKIP
    >>> idx.add([trimesh_mesh, (V, F)], names=["bunny", "cat"])  # doctest: +SKIP
    >>> idx.query_mesh(V, F, "evd", top=10)  # doctest: +SKIP
    >>> idx.add(["meshes/"])  # doctest: +SKIP
    >>> idx.query_mesh(V, F, top=10)  # doctest: +SKIP
    """

    def __init__(self, path: str | os.PathLike, *, timeout: float = 60.0, search: str = "auto",
                 nprobe: int | None = None, min_scan: int | None = None):
        from geoshape._options import check_choice
        from geoshape.retrieval.ann import MIN_SCAN

        self.search_mode = check_choice("search", search, SEARCH_MODES)
        self.nprobe = nprobe
        self.min_scan = MIN_SCAN if min_scan is None else int(min_scan)
        self.timeout = timeout
        self.path = Path(path)
        if self.path.parent and not self.path.parent.exists():
            raise DatasetError(f"{self.path}: folder {self.path.parent} does not exist")
        if self.path.is_dir():
            raise DatasetError(f"{self.path}: is a folder, not an index file")
        self._pre_existing = self.path.exists() and self.path.stat().st_size > 0
        self._created = False  # set by _set_up when this object initialised the database
        try:
            self._conn = sqlite3.connect(str(self.path), timeout=timeout, isolation_level=None)
        except sqlite3.Error as exc:
            raise DatasetError(f"{self.path}: cannot open: {exc}") from None
        deadline = time.monotonic() + timeout
        while True:  # a fresh database set up by two processes at once: wait, then re-check
            try:
                self._set_up()
                break
            except sqlite3.OperationalError as exc:
                if "locked" not in str(exc) and "busy" not in str(exc) or time.monotonic() > deadline:
                    self._abandon()
                    raise DatasetError(f"{self.path}: cannot open the index: {exc}") from None
                time.sleep(0.05)
            except sqlite3.DatabaseError as exc:
                self._abandon()
                raise DatasetError(f"{self.path}: not a geoshape index ({exc})") from None
            except BaseException:
                self._abandon()
                raise
        self._cache: dict = {}
        self._vectors_cache: dict = {}  # params key -> (version, VectorSet or None when ragged)
        self._pool = None  # threads of _stored_rows, started on first use
        self._local = threading.local()
        self._thread_conns: list[sqlite3.Connection] = []

    def _set_up(self) -> None:
        """Check that the file is a geoshape index (or empty), then create the schema.

        Raises :class:`DatasetError` for any other database, before writing anything.
        """
        conn = self._conn
        conn.execute("BEGIN IMMEDIATE")  # one process sets a fresh database up at a time
        try:
            app_id = conn.execute("PRAGMA application_id").fetchone()[0]
            tables = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
            if app_id != APPLICATION_ID and (app_id != 0 or tables):
                raise DatasetError(
                    f"{self.path}: not a geoshape index (a SQLite database with tables "
                    f"{', '.join(tables) or 'none'}); refusing to write into it")
            if app_id == 0:
                conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                self._created = True
            for statement in filter(str.strip, _SCHEMA.split(";")):
                conn.execute(statement)
            for statement in _TRIGGERS:
                conn.execute(statement)
            conn.execute("INSERT INTO meta VALUES ('schema_version', ?) ON CONFLICT (key) DO UPDATE "
                         "SET value = excluded.value WHERE CAST(value AS INTEGER) < ?",
                         (str(SCHEMA_VERSION), SCHEMA_VERSION))
            conn.execute("INSERT OR IGNORE INTO meta VALUES ('index_id', ?)", (os.urandom(16).hex(),))
        except BaseException:
            self._created = False
            _rollback(conn)
            raise
        conn.execute("COMMIT")
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=NORMAL")

    # -- context manager -----------------------------------------------------------------
    def close(self) -> None:
        if getattr(self, "_pool", None) is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
        for conn in getattr(self, "_thread_conns", []):
            with contextlib.suppress(sqlite3.Error):
                conn.close()
        with contextlib.suppress(sqlite3.Error):
            self._conn.close()

    def _abandon(self) -> None:
        """Close after a failed setup; a file that did not exist before and into which
        nothing was written (e.g. a full disk) is removed again."""
        self.close()
        if not self._pre_existing and self.path.exists() and self.path.stat().st_size == 0:
            self._remove_files()

    def _discard_if_new_and_empty(self) -> None:
        """Close and delete the database this object initialised, if it stores nothing and no
        other process holds a claim in it (a concurrent add may be writing into it)."""
        if not self._created:
            return
        try:
            busy = self.count() > 0 or self._conn.execute(
                "SELECT COUNT(*) FROM claims WHERE NOT (host = ? AND pid = ?)",
                (socket.gethostname(), os.getpid())).fetchone()[0] > 0
        except sqlite3.Error:
            busy = True
        if not busy:
            self.close()
            self._remove_files()

    def _remove_files(self) -> None:
        """Delete the database file, SQLite's companions of it (WAL, shared memory, journal)
        and the folder of vector sidecars."""
        for suffix in ("", "-wal", "-shm", "-journal"):
            Path(str(self.path) + suffix).unlink(missing_ok=True)
        shutil.rmtree(self._sidecar_folder(), ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        if exc_type is not None:  # nothing stored by a failed first use: leave no file
            self._discard_if_new_and_empty()
        self.close()

    # -- contents ------------------------------------------------------------------------
    def count(self, descriptor: str | None = None) -> int:
        """Number of stored rows (of one descriptor, if given)."""
        if descriptor is None:
            return int(self._conn.execute("SELECT COUNT(*) FROM entries").fetchone()[0])
        return int(self._conn.execute("SELECT COUNT(*) FROM entries WHERE descriptor = ?",
                                      (descriptor,)).fetchone()[0])

    def summary(self) -> list[dict]:
        """One dict per stored (descriptor, params): ``descriptor``, ``params``, ``rows``."""
        rows = self._conn.execute(
            "SELECT descriptor, params, COUNT(*) FROM entries GROUP BY descriptor, params "
            "ORDER BY descriptor").fetchall()
        return [{"descriptor": d, "params": json.loads(p), "rows": int(c)} for d, p, c in rows]

    def _existing(self, descriptor: str, pkey: str) -> dict[str, str]:
        rows = self._conn.execute("SELECT path, sha256 FROM entries WHERE descriptor = ? AND params = ?",
                                  (descriptor, pkey)).fetchall()
        return dict(rows)

    def insert_rows(self, rows) -> None:
        """Insert (or replace) rows in one transaction.

        Parameters
        ----------
        rows : iterable of (path, descriptor, params_key, sha256, array, seconds)
        """
        now = time.time()
        packed = [(str(p), d, pk, sha, json.dumps(list(np.shape(a))),
                   np.ascontiguousarray(a, dtype=np.float64).tobytes(), s, now)
                  for p, d, pk, sha, a, s in rows]
        if not packed:
            return
        with self._writing():
            self._conn.executemany(
                "INSERT OR REPLACE INTO entries (path, descriptor, params, sha256, shape, data, "
                "seconds, added) VALUES (?, ?, ?, ?, ?, ?, ?, ?)", packed)

    @contextlib.contextmanager
    def _writing(self):
        """One write transaction (``BEGIN IMMEDIATE`` … ``COMMIT``, rolled back on any error);
        an SQLite error — a full disk, a read-only file — becomes one DatasetError line."""
        try:
            self._conn.execute("BEGIN IMMEDIATE")
            try:
                yield self._conn
            except BaseException:
                _rollback(self._conn)
                raise
            self._conn.execute("COMMIT")
        except sqlite3.Error as exc:
            raise DatasetError(f"{self.path}: cannot write to the index: {exc}") from None

    # -- claims (concurrent adds) --------------------------------------------------------
    def _claim(self, tasks: list[tuple[str, str, str]], shas: list[str]) -> set[tuple[str, str, str]]:
        """Claim ``(path, descriptor, params)`` rows that are neither stored with the same
        content hash ``shas`` nor claimed by a live process; return the ones this process may
        compute. One transaction, so two adds never both win."""
        host, pid, now = socket.gethostname(), os.getpid(), time.time()
        mine = set()
        with self._writing() as conn:
            for task, sha in zip(tasks, shas, strict=True):
                stored = conn.execute("SELECT sha256 FROM entries "
                                      "WHERE path = ? AND descriptor = ? AND params = ?", task).fetchone()
                if stored is not None and stored[0] == sha:  # another add finished it
                    continue
                row = conn.execute("SELECT host, pid, since FROM claims "
                                   "WHERE path = ? AND descriptor = ? AND params = ?", task).fetchone()
                if row is not None and (row[0], row[1]) != (host, pid) and _claim_alive(*row, host, now):
                    continue
                conn.execute("INSERT OR REPLACE INTO claims VALUES (?, ?, ?, ?, ?, ?)",
                             (*task, host, pid, now))
                mine.add(task)
        return mine

    def _release(self, tasks) -> None:
        host, pid = socket.gethostname(), os.getpid()
        try:
            self._conn.executemany(
                "DELETE FROM claims WHERE path = ? AND descriptor = ? AND params = ? "
                "AND host = ? AND pid = ?", [(*t, host, pid) for t in tasks])
        except sqlite3.Error:
            pass  # stale claims of a dead process are ignored by the next add

    def _describe(self, tasks, pkeys, affinity, seed, backend, n_jobs, client):
        """Rows for ``(file, sha, descriptor)`` tasks on the runner, and the files that failed;
        a file that failed one descriptor is stored for none (all or nothing per file).

        One runner task per file: its descriptors are computed together, so the ones that
        read Laplace–Beltrami eigenpairs share one eigen-solve
        (:func:`geoshape.retrieval.descriptors.compute_descriptor_set`)."""
        from geoshape.parallel import run_map
        from geoshape.retrieval.meshes import describe_file

        per_file: dict[str, tuple] = {}  # path or name -> (file, sha, [descriptors])
        for f, sha, nm in tasks:
            per_file.setdefault(str(f), (f, sha, []))[2].append(nm)
        groups = list(per_file.values())
        items = [((f.name, f.V, f.F) if isinstance(f, _MemoryMesh) else str(f), tuple(names), affinity, seed)
                 for f, _, names in groups]
        results = run_map(describe_file, items, backend=backend, n_jobs=n_jobs, scheduler=client,
                          progress=False, on_error="return")
        rows, bad = [], {}
        for (f, sha, names), res in zip(groups, results, strict=True):
            if isinstance(res, BaseException):
                bad.setdefault(str(f), str(res) if str(f) in str(res) else f"{f}: {res}")
            else:
                rows.extend((f, nm, pkeys[nm], sha, res[0][nm], res[1][nm]) for nm in names)
        return [r for r in rows if str(r[0]) not in bad], bad

    def prune(self) -> list[str]:
        """Delete the rows of files that no longer exist; return their paths (meshes added
        from memory stay)."""
        paths = [r[0] for r in self._conn.execute("SELECT DISTINCT path FROM entries")]
        gone = [p for p in paths if _is_gone(p)]
        if gone:
            with self._writing() as conn:
                sets = conn.execute("SELECT DISTINCT descriptor, params FROM entries").fetchall()
                conn.executemany("DELETE FROM entries WHERE path = ?", [(p,) for p in gone])
            self._cache.clear()
            for descriptor, pkey in sets:
                self._refresh_sidecar(descriptor, pkey)
        return gone

    # -- adding --------------------------------------------------------------------------
    def add(self, inputs, descriptors=DEFAULT_INDEX_DESCRIPTORS, *, names=None,
            affinity: str | None = None, seed: int = 0, backend: str | None = None,
            n_jobs: int | None = None, scheduler=None, batch_size: int | None = None,
            progress=None) -> AddReport:
        """Describe mesh files (or meshes in memory) and store the descriptors, skipping unchanged ones.

        Parameters
        ----------
        inputs : sequence of path or mesh, a single mesh, or a mapping name -> mesh
            Mesh files and/or folders (searched recursively for mesh files), and/or meshes
            in memory: trimesh / Open3D / pymeshlab meshes (a ``MeshSet``: its current mesh)
            or ``(V, F)`` pairs, described exactly as the same mesh read from a file.
        descriptors : sequence of str
            Registered descriptor names; a fusion (``"fused"``) stands for its components.
            Default: the components of the fused default (:data:`DEFAULT_INDEX_DESCRIPTORS`).
        names : sequence of str or None, optional
            One entry per item of ``inputs``: the name a mesh in memory is stored and
            returned under (:attr:`Hit.path`); ``None`` for files and folders, whose key is
            their absolute path. A mesh without a name is stored as
            ``mesh-<first 16 hex digits of the SHA-256 of its arrays>``, so adding the same
            geometry again finds it. Names are unique, non-empty and not absolute paths; a
            name added again with other geometry is described again and replaced, like an
            edited file.
        affinity : str or None
            For the spectral/embedding descriptors (default geodesic); ignored by the others.
        seed : int
        backend, n_jobs, scheduler
            As :func:`geoshape.parallel.run_map` (local processes by default, Dask with a
            scheduler address). One Dask client is opened for the whole run.
        batch_size : int or None
            Files per committed batch; default ``4 x workers`` (at least 4).
        progress : callable, optional
            ``progress(done_files, total_files)`` after each batch.

        Returns
        -------
        AddReport

        Raises
        ------
        InvalidOptionError
            Bad ``names`` (wrong length, a name for a file, duplicates, an absolute path).
        InvalidMeshError
            An item that is neither a path nor a mesh. A mesh that fails validation is
            reported in :attr:`AddReport.failed` and skipped, like a bad file.

        Notes
        -----
        Each file is read and hashed once in this process (O(size)), then described on the
        runner; one transaction per batch. A mesh in memory is hashed here and its arrays
        sent to the runner.
        """
        from geoshape.parallel import _dask_client, _resolve_backend, default_n_jobs
        from geoshape.retrieval.descriptors import (
            FUSIONS,
            descriptor_params,
            get_descriptor,
            method_descriptors,
            params_key,
        )

        t0 = time.perf_counter()
        if isinstance(descriptors, str):
            descriptors = [descriptors]
        wanted = list(dict.fromkeys(x for nm in descriptors
                                    for x in (method_descriptors(nm) if nm in FUSIONS else (nm,))))
        if not wanted:
            raise InvalidOptionError("no descriptor named")
        pkeys = {}
        for nm in wanted:
            spec = get_descriptor(nm)
            pkeys[nm] = params_key(descriptor_params(nm, affinity if spec.uses_affinity else None, seed))
        backend = _resolve_backend(backend, scheduler)
        workers = n_jobs or default_n_jobs()
        if batch_size is None:
            batch_size = max(4, 4 * workers)
        if not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
            raise InvalidOptionError(f"batch_size must be a positive integer, got {batch_size!r}")
        report = AddReport()
        paths, in_memory = _split_inputs(inputs, names, report)
        files = expand_mesh_inputs(paths)
        existing = {nm: self._existing(nm, pkeys[nm]) for nm in wanted}
        todo = []  # (path or _MemoryMesh, sha, [descriptors to compute])
        for f in files:
            try:
                sha = file_sha256(f)
            except OSError as exc:
                report.failed.append((str(f), f"{f}: cannot read: {exc}"))
                continue
            need = [nm for nm in wanted if existing[nm].get(str(f)) != sha]
            report.skipped += len(wanted) - len(need)
            if need:
                todo.append((f, sha, need))
        for m in in_memory:
            need = [nm for nm in wanted if existing[nm].get(m.name) != m.sha256]
            report.skipped += len(wanted) - len(need)
            if need:
                todo.append((m, m.sha256, need))
        client, owned = (None, False)
        if backend == "dask":
            client, owned = _dask_client(scheduler, workers)
        try:
            for start in range(0, len(todo), batch_size):
                batch = todo[start : start + batch_size]
                tasks = [(f, sha, nm) for f, sha, need in batch for nm in need]
                keys = [(str(f), nm, pkeys[nm]) for f, _, nm in tasks]
                mine = self._claim(keys, [sha for _, sha, _ in tasks])
                try:
                    report.claimed_elsewhere += len(keys) - len(mine)
                    tasks = [t for t, key in zip(tasks, keys, strict=True) if key in mine]
                    if not tasks:
                        report.batches += 1
                        continue
                    rows, bad = self._describe(tasks, pkeys, affinity, seed, backend, n_jobs, client)
                    self.insert_rows(rows)
                finally:
                    self._release(mine)
                report.added += len(rows)
                report.failed.extend(bad.items())
                report.batches += 1
                if progress is not None:
                    progress(min(start + batch_size, len(todo)), len(todo))
        except BaseException:
            self._discard_if_new_and_empty()
            raise
        finally:
            if owned and client is not None:
                cluster = getattr(client, "cluster", None)
                client.close()
                if cluster is not None:
                    cluster.close()
        self._cache.clear()
        if report.added:
            for nm in wanted:
                self._refresh_sidecar(nm, pkeys[nm])
        report.seconds = time.perf_counter() - t0
        return report

    # -- vector sidecars (see the module docstring and geoshape.retrieval.ann) ------------
    @contextlib.contextmanager
    def _reading(self):
        """One read transaction: every SELECT inside sees the same committed state."""
        self._conn.execute("BEGIN")
        try:
            yield self._conn
        finally:
            with contextlib.suppress(sqlite3.Error):
                self._conn.execute("COMMIT")

    def _set_version(self, descriptor: str, pkey: str) -> tuple[int | None, int, int]:
        """``(set id, version, floor)`` of a set: version = the last logged change of its rows
        (0 when none was logged), floor = the log of the set is complete after it."""
        row = self._conn.execute("SELECT id, floor FROM sets WHERE descriptor = ? AND params = ?",
                                 (descriptor, pkey)).fetchone()
        if row is None:
            return None, 0, 0
        last = self._conn.execute("SELECT MAX(seq) FROM changes WHERE set_id = ?", (row[0],)).fetchone()[0]
        return int(row[0]), max(int(last or 0), int(row[1])), int(row[1])

    def _index_id(self) -> str:
        row = self._conn.execute("SELECT value FROM meta WHERE key = 'index_id'").fetchone()
        return row[0] if row else ""

    def _sidecar_folder(self) -> Path:
        return Path(str(self.path) + ".ann")

    def _sidecar_path(self, descriptor: str, pkey: str, lower_bound: bool = False) -> Path:
        kind = "-lb" if lower_bound else ""
        digest = hashlib.sha256(pkey.encode()).hexdigest()[:16]
        return self._sidecar_folder() / f"{descriptor}{kind}-{digest}.vec"

    def _load_sidecar(self, descriptor: str, pkey: str, index_id: str, lower_bound: bool = False):
        """The sidecar file of a set if it is whole and belongs to this index and set."""
        from geoshape.retrieval.ann import VectorSet

        try:
            vs = VectorSet.load(self._sidecar_path(descriptor, pkey, lower_bound))
        except (OSError, ValueError, KeyError, TypeError):
            return None
        from geoshape.retrieval.descriptors import get_descriptor, lower_bound_rows

        if lower_bound:
            _, metric, tag = lower_bound_rows(descriptor)
        else:
            metric, tag = get_descriptor(descriptor).metric, False
        m = vs.meta
        if (m.get("index_id"), m.get("descriptor"), m.get("params"), m.get("lower_bound", False),
                m.get("metric")) != (index_id, descriptor, pkey, tag, metric):
            return None
        return vs

    def _vectors(self, descriptor: str, pkey: str, *, graph: bool = False, persist: bool = True,
                 trim: bool = False, lower_bound: bool = False):
        """The up-to-date :class:`~geoshape.retrieval.ann.VectorSet` of a set, or None for a set
        that is not searched through a sidecar (not a vector metric, ragged shapes, or
        ``search="memory"``). ``graph``: with its k-nearest-neighbour graph. ``persist``: save
        it (under the file lock); ``trim``: then drop the log up to the saved version.
        ``lower_bound``: instead, the set of the descriptor's lower-bound rows
        (:func:`~geoshape.retrieval.descriptors.lower_bound_rows`; None for a descriptor
        without them), a candidate generator for a descriptor that is not a vector."""
        from geoshape.retrieval.ann import VECTOR_METRICS, file_lock
        from geoshape.retrieval.descriptors import get_descriptor, lower_bound_rows

        if self.search_mode == "memory":
            return None
        if lower_bound:
            if lower_bound_rows(descriptor) is None:
                return None
        elif get_descriptor(descriptor).metric not in VECTOR_METRICS:
            return None
        cache_key = (pkey, "lower bound") if lower_bound else pkey
        with self._reading():
            set_id, version, floor = self._set_version(descriptor, pkey)
            index_id = self._index_id()

        def usable(vs):
            return (vs is not None and vs.meta.get("index_id") == index_id and vs.version == version
                    and (vs.has_graph or not graph))

        cached = self._vectors_cache.get(cache_key)
        if cached is not None and cached[0] == (index_id, version) and cached[1] is None:
            return None  # ragged at this version
        vs = cached[1] if cached is not None else None
        if usable(vs) and not trim:
            return vs
        disk = self._load_sidecar(descriptor, pkey, index_id, lower_bound)
        if usable(disk) and not trim:
            self._vectors_cache[cache_key] = ((index_id, version), disk)
            return disk
        folder = self._sidecar_folder()
        try:
            if persist:
                folder.mkdir(exist_ok=True)
        except OSError:
            persist = False
        lock = file_lock(folder / ".lock", self.timeout) if persist else contextlib.nullcontext(False)
        with lock as locked:
            if locked:  # another process may have brought it up to date meanwhile
                disk = self._load_sidecar(descriptor, pkey, index_id, lower_bound)
            # the base to bring up to date: one that can be, keeping a graph once there is one
            bases = [b for b in (vs, disk) if b is not None and b.meta.get("index_id") == index_id]
            base = max(bases, key=lambda b: (floor <= b.version <= version, b.has_graph, b.version),
                       default=None)
            out, version = self._synced(descriptor, pkey, base, lower_bound)
            if out is not None and graph and not out.has_graph:
                out.build_graph()
            key = (index_id, version)
            self._vectors_cache[cache_key] = (key, out)
            if out is None or not locked:
                return out
            saved = disk is not None and disk.version == out.version and (disk.has_graph or not out.has_graph)
            if not saved:
                try:
                    out.save(self._sidecar_path(descriptor, pkey, lower_bound))
                    saved = True
                except OSError:
                    pass
        if saved and trim and set_id is not None:
            with contextlib.suppress(DatasetError):
                with self._writing() as conn:
                    conn.execute("DELETE FROM changes WHERE set_id = ? AND seq <= ?", (set_id, out.version))
                    conn.execute("UPDATE sets SET floor = MAX(floor, ?) WHERE id = ?", (out.version, set_id))
        return out

    def _synced(self, descriptor: str, pkey: str, base, lower_bound: bool = False):
        """``(VectorSet or None, version)``: ``base`` brought up to the current version from
        the logged changes, or the set rebuilt from SQLite when ``base`` cannot be.
        ``lower_bound``: the rows are the descriptor's lower-bound vectors (read and
        embedded 10,000 rows at a time: the stored rows are never all in memory)."""
        from geoshape.retrieval.ann import VectorSet
        from geoshape.retrieval.descriptors import get_descriptor, lower_bound_rows

        embed_rows, metric, tag = lower_bound_rows(descriptor) if lower_bound else (None, None, False)
        paths, shapes, parts = [], set(), []

        def take(cursor):  # rows -> paths, shapes, (embedded) float64 blocks, 10,000 at a time
            while batch := cursor.fetchmany(10_000):
                shapes.update(r[1] for r in batch)
                if len(shapes) > 1:  # ragged: nothing to build
                    return
                paths.extend(r[0] for r in batch)
                X = np.frombuffer(b"".join(r[2] for r in batch), dtype=np.float64).reshape(len(batch), -1)
                parts.append(embed_rows(X) if embed_rows is not None else X)

        with self._reading() as conn:
            set_id, version, floor = self._set_version(descriptor, pkey)
            index_id = self._index_id()
            if base is not None and floor <= base.version <= version:
                if base.version == version:
                    return base, version
                changed = [r[0] for r in conn.execute(
                    "SELECT DISTINCT path FROM changes WHERE set_id = ? AND seq > ?", (set_id, base.version))]
                for s in range(0, len(changed), 500):
                    chunk = changed[s : s + 500]
                    take(conn.execute(
                        f"SELECT path, shape, data FROM entries WHERE descriptor = ? AND params = ? "
                        f"AND path IN ({', '.join('?' * len(chunk))}) ORDER BY path",
                        (descriptor, pkey, *chunk)))
                full = False
            else:
                # sorted here rather than by SQLite, whose ORDER BY would build a temporary
                # B-tree of every row (blobs included)
                take(conn.execute("SELECT path, shape, data FROM entries WHERE descriptor = ? "
                                  "AND params = ?", (descriptor, pkey)))
                full = True
        if full and not paths:
            return None, version
        shape = json.loads(next(iter(shapes))) if paths else (base.meta["shape"] if base is not None else [])
        if len(shapes) > 1 or (not full and base is not None and paths and shape != base.meta["shape"]):
            if full:
                return None, version
            return self._synced(descriptor, pkey, None, lower_bound)  # another shape: rebuild (ragged)
        X = np.concatenate(parts) if parts else np.zeros((0, base.d))
        if full:
            order = sorted(range(len(paths)), key=paths.__getitem__)
            paths, X = [paths[i] for i in order], X[order]
            meta = {"index_id": index_id, "descriptor": descriptor, "params": pkey, "version": version,
                    "metric": metric or get_descriptor(descriptor).metric, "shape": shape,
                    "lower_bound": tag}
            return VectorSet.build(meta, paths, X), version
        return base.updated(changed, paths, X, version), version

    def _refresh_sidecar(self, descriptor: str, pkey: str) -> None:
        """Bring a set's sidecar up to date after this process changed the set (best effort: a
        failure only means the next query does it)."""
        with contextlib.suppress(OSError, sqlite3.Error, DatasetError, ValueError):
            self._vectors(descriptor, pkey, persist=True, trim=True)
            self._vectors(descriptor, pkey, persist=True, trim=True, lower_bound=True)

    def vector_set(self, descriptor: str, *, affinity: str | None = None, seed: int = 0,
                   graph: bool = False, lower_bound: bool = False):
        """The up-to-date sidecar of a stored vector descriptor set (for benchmarks and
        inspection), or None when that set is searched in memory. ``lower_bound``: the set
        of a non-vector descriptor's lower-bound vectors (``pcavox``) instead."""
        from geoshape.retrieval.descriptors import descriptor_params, get_descriptor, params_key

        spec = get_descriptor(descriptor)
        pkey = params_key(descriptor_params(descriptor, affinity if spec.uses_affinity else None, seed))
        return self._vectors(descriptor, pkey, graph=graph, lower_bound=lower_bound)

    # -- querying ------------------------------------------------------------------------
    def _state(self) -> tuple:
        return tuple(self._conn.execute("SELECT COUNT(*), MAX(rowid), MAX(added) FROM entries").fetchone())

    def load(self, descriptor: str, params: dict) -> tuple[list[str], np.ndarray]:
        """Stored paths and stacked descriptors of one (descriptor, parameters) set.

        Returns
        -------
        paths : list of str
        X : (M, *shape) float64
            Cached until the index changes.

        Raises
        ------
        DatasetError
            Nothing stored for this descriptor and these parameters.
        """
        from geoshape.retrieval.descriptors import params_key

        pkey = params_key(params)
        state = self._state()
        hit = self._cache.get(pkey)
        if hit is not None and hit[0] == state:
            return hit[1], hit[2]
        rows = self._conn.execute("SELECT path, shape, data FROM entries WHERE descriptor = ? "
                                  "AND params = ? ORDER BY path", (descriptor, pkey)).fetchall()
        if not rows:
            stored = ", ".join(f"{s['descriptor']} {json.dumps(s['params'])}" for s in self.summary())
            raise DatasetError(f"{self.path}: no {descriptor!r} descriptors with parameters "
                               f"{pkey} (stored: {stored or 'nothing'})")
        shapes = {r[1] for r in rows}
        paths = [r[0] for r in rows]
        if len(shapes) == 1:
            shape = tuple(json.loads(rows[0][1]))
            X = np.frombuffer(b"".join(r[2] for r in rows), dtype=np.float64).reshape(len(rows), *shape)
        else:  # ragged (e.g. CCD of meshes with fewer points than requested): object array
            X = np.empty(len(rows), dtype=object)
            for k, r in enumerate(rows):
                X[k] = np.frombuffer(r[2], dtype=np.float64).reshape(json.loads(r[1]))
        self._cache[pkey] = (state, paths, X)
        return paths, X

    def query_descriptor(self, q, descriptor: str, *, top: int = 10, affinity: str | None = None,
                         seed: int = 0, rerank: str | None = None, rerank_q=None,
                         rerank_k: int | None = None, skip_missing: bool = False,
                         nprobe: int | None = None) -> list[Hit]:
        """Rank the stored shapes against a query descriptor already computed.

        Parameters
        ----------
        q : ndarray or dict
            The query's descriptor ``descriptor``; for a fusion (``"fused"``), its component
            descriptors by name.
        descriptor : str
            A stored descriptor, or a fusion (:data:`geoshape.retrieval.descriptors.FUSIONS`):
            its components' distances to every stored shape holding all of them, fused as one
            query row (exact scan, no sidecar).
        top : int
            Number of hits returned.
        affinity, seed
            Select the stored parameter set (as when adding).
        rerank : str or None
            Re-rank the first ``rerank_k`` hits either by a second stored descriptor
            (``"ccd"``; its query descriptor is ``rerank_q``) or by a diffusion method of
            :mod:`geoshape.retrieval.rerank` (``"lcdp"``) over the stored k-nearest-neighbour
            graph (see Notes). :func:`rerank_choices` lists the names.
        rerank_k : int or None
            Shortlist size; default ``max(top, 20)``.
        skip_missing : bool
            Never return a file that no longer exists (only the shortlist is checked on disk;
            meshes added from memory are always returned).
        nprobe : int or None
            IVF lists scanned (``ivf`` search); default the index's.

        Returns
        -------
        list of :class:`Hit`, best first.

        Notes
        -----
        Vector descriptors (sidecar): exact brute force O(N d) float32 + a few hundred exact
        distances; IVF O(√N d + scanned rows x d). Others: O(M) descriptor distances plus
        O(M) for the partial sort. Re-ranking by a descriptor adds ``rerank_k`` of its
        distances. Diffusion: the shortlist, its neighbours in the stored graph and theirs
        (:data:`DIFFUSION_HOPS` hops of the method's ``k`` neighbours, so at most
        ``1 + rerank_k (1 + k + k²)`` items: 421 for the defaults) with the query form a local
        collection whose all-pairs matrix (O(L² d)) is re-ranked (O(L² k iterations)) and
        the query's row re-scores the shortlist; a few ms. The graph is built on the first
        such query of a set (all pairs, O(N² d) float32 BLAS, pruned by IVF lists above
        20,000 rows) and then kept up to date by ``add`` and ``prune`` (O(N d) per changed
        row). Descriptors without a sidecar (CCD, LFD) use the shortlist alone as the local
        collection.
        """
        from geoshape.retrieval.descriptors import (
            FUSIONS,
            descriptor_distances,
            descriptor_params,
            get_descriptor,
            params_key,
        )
        from geoshape.retrieval.rerank import RERANK_METHODS

        if not isinstance(top, (int, np.integer)) or top < 1:
            raise InvalidOptionError(f"top must be a positive integer, got {top!r}")
        if rerank is not None:
            check_rerank(rerank)
        diffusion = rerank in RERANK_METHODS
        want = max(top, rerank_k or 20) if rerank else top
        fused = descriptor in FUSIONS
        vs = None
        if not fused:
            spec = get_descriptor(descriptor)
            params = descriptor_params(descriptor, affinity if spec.uses_affinity else None, seed)
            vs = self._vectors(descriptor, params_key(params), graph=diffusion)
        if fused:
            short, rows = self._fused_shortlist(q, descriptor, want, affinity=affinity, seed=seed,
                                                skip_missing=skip_missing)
        elif vs is None:
            paths, X = self.load(descriptor, params)
            d = descriptor_distances(descriptor, [q], list(X) if X.dtype == object else X)[0]
            cand = _existing_nearest(d, paths, want, skip_missing, self.path)
            short = [(paths[i], float(d[i])) for i in cand]
            rows = [X[i] for i in cand]
        else:
            mode = self._mode(vs)
            k = min(vs.n, want)
            asked = k
            while True:
                pos, dist = vs.search(q, asked, mode=mode, nprobe=nprobe or self.nprobe,
                                      min_scan=self.min_scan)
                if not skip_missing:
                    break
                present = [j for j, p in enumerate(pos.tolist()) if not _is_gone(vs.path(p))]
                if len(present) >= k or asked >= vs.n:
                    pos, dist = pos[present], dist[present]
                    break
                asked = min(vs.n, 2 * asked + k)
            if skip_missing and not len(pos):
                raise DatasetError(f"{self.path}: none of the stored files exists any more "
                                   "(run 'geoshape index prune')")
            pos, dist = pos[:k], dist[:k]
            short = [(vs.path(p), float(x)) for p, x in zip(pos.tolist(), dist.tolist(), strict=True)]
            rows = None
        if not rerank:
            return [Hit(r + 1, p, x) for r, (p, x) in enumerate(short[:top])]
        if diffusion:
            return self._diffusion_rerank(q, descriptor, rerank, short, top,
                                          vs=vs, pos=pos if vs is not None else None, rows=rows)
        rspec = get_descriptor(rerank)
        rparams = descriptor_params(rerank, affinity if rspec.uses_affinity else None, seed)
        rpaths, RX = self.load(rerank, rparams)
        where = {p: i for i, p in enumerate(rpaths)}
        keep = [(p, x) for p, x in short if p in where]
        if rerank_q is None:
            raise InvalidOptionError(f"re-ranking by {rerank!r} needs the query's {rerank} descriptor")
        rd = descriptor_distances(rerank, [rerank_q], [RX[where[p]] for p, _ in keep])[0]
        order = np.lexsort((np.arange(len(keep)), rd))
        return [Hit(r + 1, keep[o][0], float(rd[o]), keep[o][1]) for r, o in enumerate(order[:top])]

    def _fused_shortlist(self, q, method: str, want: int, *, affinity, seed: int, skip_missing: bool):
        """The ``want`` nearest stored shapes under the fusion ``method``: ``(short, rows)``.

        ``q``: the query's component descriptors by name. Each component's distances from
        the query to every stored shape holding all components (O(M) distances each) are
        fused as one query row (:func:`geoshape.retrieval.fusion.fuse_distances`, the
        ``(1, M)`` case: medians and nearest items over the stored shapes, no symmetrisation),
        so the ranking is that of the query's row of the all-pairs fused matrix up to the
        symmetrisation. ``rows``: the shortlist's component descriptors (dicts by name)."""
        from geoshape.retrieval.descriptors import (
            FUSIONS,
            descriptor_distances,
            descriptor_params,
            get_descriptor,
            params_key,
        )
        from geoshape.retrieval.fusion import fuse_distances

        weights = {c: w for c, w in FUSIONS[method].items() if w > 0}
        if not isinstance(q, Mapping) or any(c not in q for c in weights):
            raise InvalidOptionError(f"a {method!r} query needs the descriptors {', '.join(weights)} "
                                     "of the query, by name")
        pkeys = {c: params_key(descriptor_params(c, affinity if get_descriptor(c).uses_affinity else None,
                                                 seed)) for c in weights}
        sets = {c: self._vectors(c, pkeys[c]) for c in weights}
        if max((vs.n for vs in sets.values() if vs is not None), default=0) > FUSED_SCAN_MAX:
            bounds = {c: self._vectors(c, pkeys[c], lower_bound=True) for c in weights if sets[c] is None}
            found = self._fused_candidates(q, weights, want, sets, bounds, pkeys, skip_missing)
            if found is not None:
                return found
        stored = {}
        for c in weights:
            spec = get_descriptor(c)
            try:
                paths, X = self.load(c, descriptor_params(c, affinity if spec.uses_affinity else None, seed))
            except DatasetError as exc:
                raise DatasetError(f"{exc}; ranking by {method!r} needs {', '.join(weights)} stored "
                                   f"('geoshape index add' stores them by default)") from None
            stored[c] = ({p: i for i, p in enumerate(paths)}, X, paths)
        first = next(iter(weights))
        common = [p for p in stored[first][2] if all(p in stored[c][0] for c in weights)]
        if not common:
            raise DatasetError(f"{self.path}: no stored shape has all of {', '.join(weights)}")
        mats = {}
        for c in weights:
            where, X, _ = stored[c]
            Xc = [X[where[p]] for p in common]
            mats[c] = descriptor_distances(c, [q[c]], Xc if X.dtype == object else np.asarray(Xc))
        d = fuse_distances(mats, weights, all_pairs=False)[0] if len(common) > 1 else np.zeros(1)
        cand = _existing_nearest(d, common, want, skip_missing, self.path)
        short = [(common[i], float(d[i])) for i in cand]
        rows = [{c: stored[c][1][stored[c][0][common[i]]] for c in weights} for i in cand]
        return short, rows

    def _mode(self, vs) -> str:
        """The search mode for one vector set (``auto``: IVF above :data:`IVF_MIN_VALUES`)."""
        if self.search_mode == "auto":
            return "ivf" if vs.n * vs.d > IVF_MIN_VALUES else "brute"
        return self.search_mode

    def _fused_candidates(self, q, weights: dict, want: int, sets: dict, bounds: dict, pkeys: dict,
                          skip_missing: bool):
        """:meth:`_fused_shortlist` for a large index: ``(short, rows)`` from a candidate list.

        Candidates: the :data:`FUSED_CANDIDATES` (at least ``want``) nearest stored shapes of
        each component searched through a sidecar (``sets[c]``; brute force or IVF as the
        index searches, without certification: a candidate list), as many nearest by the
        lower-bound rows of each component that has them instead (``bounds[c]``: ``pcavox``),
        plus a fixed sample of :data:`FUSED_SAMPLE` stored shapes (:meth:`_fused_sample`).
        The vector components' distances to them come from their sidecar rows (the sample's
        rows of every component are cached per set version); they are fused with the
        coefficients of :func:`geoshape.retrieval.fusion.estimated_coefficients`: each
        component's median over the sample, its nearest distances from its own search. So
        even ``search="brute"`` is approximate here; ``search="memory"`` scans exactly. A
        lower-bounded component's descriptor is read from SQLite (primary key) only where it
        can matter — a random read of a 32 KB pcavox row is the slowest step on a large,
        uncached index: first its
        :data:`FUSED_LB_SEED` best candidates by the bound (their exact distances, with the
        sample's, give its nearest items and so the query's weights), then, branch and bound,
        best first, :data:`FUSED_LB_SEED` at a time, every candidate whose fused distance with
        the bound in place of the exact one does not exceed the ``want``-th exact fused
        distance so far (of existing files, with ``skip_missing``), until none is left. So
        the list is exactly the ``want`` best candidates for those weights. ``None`` when the
        sample holds no shape with every component (the exact scan then decides). A shape that is in no
        component's candidate list is missed, and the sampled medians and the bounded
        component's nearest items are estimates: the ranking approximates the exact scan
        (recall measured by ``geoshape bench index``).

        Cost: per component one search (exact O(N d), IVF O(√N d + scanned d)), then
        O((C K + S) d) distances for C components, K candidates and S samples, and a few
        rows read by primary key; nothing else is O(N).
        """
        from geoshape.retrieval.ann import pair_distances
        from geoshape.retrieval.descriptors import descriptor_distances, lower_bound_rows
        from geoshape.retrieval.fusion import FUSED_K, estimated_coefficients

        vec = {c: vs for c, vs in sets.items() if vs is not None}
        k = max(int(want), FUSED_CANDIDATES)
        near = {}
        cands: dict[str, None] = {}
        q_bound = {c: lower_bound_rows(c)[0](np.asarray(q[c], dtype=np.float64).reshape(1, -1))[0]
                   for c, b in bounds.items() if b is not None}
        for c, vs in [*vec.items(), *((c, b) for c, b in bounds.items() if b is not None)]:
            pos, dist = vs.search(np.ravel(q[c]) if c in vec else q_bound[c], k, mode=self._mode(vs),
                                  nprobe=self.nprobe, min_scan=self.min_scan, certify=False)
            if c in vec:
                near[c] = dist[:FUSED_K]
            cands.update(dict.fromkeys(vs.paths(pos)))
        held = self._fused_sample(weights, vec, bounds, pkeys)
        if held is None:  # no common shape in the sample, or ragged rows: the exact scan decides
            return None
        sample, sample_rows = held
        in_sample = set(sample)
        paths = [p for p in cands if p not in in_sample]
        bounded = [c for c in weights if c not in vec and bounds.get(c) is not None]
        rows_by_c = {}
        for c in weights:  # the candidates' rows; a shape lacking a component is dropped
            if c in vec or c in bounded:  # sidecar positions (of the bound's rows for bounded ones)
                rows = (vec[c] if c in vec else bounds[c]).rows_of(paths)
                rows_by_c[c] = {p: r for p, r in zip(paths, rows.tolist(), strict=True) if r >= 0}
            else:
                rows_by_c[c] = self._stored_rows(c, pkeys[c], paths)
            paths = [p for p in paths if p in rows_by_c[c]]
        ns = len(sample)
        dists = {}
        for c in weights:  # distances to the sample (first) and to the other candidates
            if c in vec:
                R = np.asarray(vec[c].X[[rows_by_c[c][p] for p in paths]])
                dists[c] = np.concatenate([pair_distances(vec[c].metric, np.ravel(q[c]), S)
                                           for S in (sample_rows[c], R)])
                continue
            dists[c] = np.zeros(ns + len(paths))
            dists[c][:ns] = descriptor_distances(c, [q[c]], sample_rows[c])[0]
            if c in bounded:  # lower bounds until the candidate's row is read
                R = np.asarray(bounds[c].X[[rows_by_c[c][p] for p in paths]])
                dists[c][ns:] = pair_distances(bounds[c].metric, q_bound[c], R)
            elif paths:
                R = np.asarray([rows_by_c[c][p] for p in paths]).reshape(-1, *sample_rows[c].shape[1:])
                dists[c][ns:] = descriptor_distances(c, [q[c]], R)[0]
        scored = sample + paths
        known = np.zeros(len(scored), dtype=bool)
        known[: ns if bounded else len(scored)] = True
        gone = np.zeros(len(scored), dtype=bool)
        read: dict[str, dict] = {c: {} for c in bounded}

        def read_rows(idx):  # exact distances of bounded components for candidates idx
            idx = np.asarray(sorted(set(np.asarray(idx).tolist())), dtype=np.int64)
            if not len(idx):
                return
            want_paths = [scored[i] for i in idx]
            for c in bounded:
                got = self._stored_rows(c, pkeys[c], want_paths)
                read[c].update(got)
                here = np.array([p in got for p in want_paths])
                gone[idx[~here]] = True  # deleted since the sidecar was read: never returned
                R = np.asarray([got[p] for p in want_paths if p in got])
                R = R.reshape(-1, *sample_rows[c].shape[1:])
                if len(R):
                    dists[c][idx[here]] = descriptor_distances(c, [q[c]], R)[0]
            known[idx] = True

        if bounded:  # each bounded component's best candidates by its bound: its nearest items
            first = [ns + np.argsort(dists[c][ns:], kind="stable")[:FUSED_LB_SEED] for c in bounded]
            read_rows(np.concatenate(first))
        for c in weights:
            if c not in vec:
                near[c] = np.sort(dists[c][known & ~gone])[:FUSED_K]
        coef = estimated_coefficients({c: v[:ns] for c, v in dists.items()}, near, weights)
        while True:  # branch and bound, best first: read the rows whose fused lower bound can
            d = sum(a * dists[c] for c, a in coef.items())  # still make the list
            ok = known & ~gone
            if skip_missing:  # a deleted file cannot hold a place in the list
                for i in np.flatnonzero(ok)[np.argsort(d[ok], kind="stable")[: int(want)]]:
                    if _is_gone(scored[i]):
                        gone[i] = True
                ok = known & ~gone
            limit = np.sort(d[ok])[int(want) - 1] if ok.sum() >= want else np.inf
            # (the bound may exceed a zero distance by rounding: a relative allowance)
            todo = np.flatnonzero(~known & (d <= limit * (1 + 1e-9) + 1e-9))
            if not len(todo):
                break
            read_rows(todo[np.argsort(d[todo], kind="stable")[:FUSED_LB_SEED]])
        d = np.where(known & ~gone, d, np.inf)
        cand = _existing_nearest(d, scored, want, skip_missing, self.path)
        cand = [i for i in cand if known[i] and not gone[i]]
        short = [(scored[i], float(d[i])) for i in cand]

        def row(c, i):  # component c's descriptor of scored shape i
            if i < ns:
                return sample_rows[c][i]
            if c in vec:
                return np.asarray(vec[c].X[rows_by_c[c][scored[i]]])
            return read[c][scored[i]] if c in bounded else rows_by_c[c][scored[i]]

        rows = [{c: row(c, i) for c in weights} for i in cand]
        return short, rows

    def _fused_sample(self, weights: dict, vec: dict, bounds: dict, pkeys: dict):
        """The fixed sample of a large index's fused queries, ``(paths, {component: rows})``:
        the :data:`FUSED_SAMPLE` smallest path hashes of the smallest sidecar component, those
        holding every component (fewer when some shapes lack one; None when none has all).
        Cached until one of the sets changes."""
        with self._reading():
            key = (self._index_id(), FUSED_SAMPLE,
                   *((c, pkeys[c], vec[c].version if c in vec else self._set_version(c, pkeys[c])[1])
                     for c in weights))
        held = self._cache.get("fused sample")
        if held is not None and held[0] == key:
            return held[1], held[2]
        first = min(vec.values(), key=lambda vs: vs.n)
        paths = first.paths(first.sample_rows(FUSED_SAMPLE))
        rows = {}
        for c in weights:
            if c in vec:
                r = vec[c].rows_of(paths)
                rows[c] = {p: np.asarray(vec[c].X[i])
                           for p, i in zip(paths, r.tolist(), strict=True) if i >= 0}
            else:
                rows[c] = self._stored_rows(c, pkeys[c], paths)
            paths = [p for p in paths if p in rows[c]]
        if not paths or any(len({np.shape(rows[c][p]) for p in paths}) > 1 for c in weights):
            return None
        arrays = {c: np.stack([rows[c][p] for p in paths]) for c in weights}
        self._cache["fused sample"] = (key, paths, arrays)
        return paths, arrays

    def _stored_rows(self, descriptor: str, pkey: str, paths) -> dict:
        """``{path: row}`` of the stored rows of one set among ``paths`` (primary-key reads,
        500 a statement). More than :data:`READ_THREADS` paths are read by that many threads,
        each with its own read-only connection: a row not in the page cache costs a random
        disk read (about 0.5 ms for a 32 KB pcavox row), and the reads overlap."""
        paths = list(paths)
        if len(paths) <= READ_THREADS:
            return _select_rows(self._conn, descriptor, pkey, paths)
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(READ_THREADS, thread_name_prefix="geoshape-read")
        parts = self._pool.map(lambda part: _select_rows(self._thread_connection(), descriptor, pkey, part),
                               [paths[i::READ_THREADS] for i in range(READ_THREADS)])
        return {p: x for part in parts for p, x in part.items()}

    def _thread_connection(self) -> sqlite3.Connection:
        """This thread's read-only connection to the index (opened once, closed with it)."""
        conn = getattr(self._local, "conn", None)
        if conn is None:
            conn = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True, timeout=self.timeout,
                                   check_same_thread=False)
            self._local.conn = conn
            self._thread_conns.append(conn)
        return conn

    def _diffusion_rerank(self, q, descriptor: str, method: str, short, top: int, *, vs, pos, rows):
        """Re-score the shortlist ``short`` by ``method`` over a local collection: the query,
        the shortlist and (with a sidecar) its stored graph neighbours up to
        :data:`DIFFUSION_HOPS` hops."""
        from geoshape.retrieval.ann import GRAPH_K, pair_distances
        from geoshape.retrieval.descriptors import descriptor_distances
        from geoshape.retrieval.rerank import RERANK_DEFAULTS
        from geoshape.retrieval.rerank import rerank as diffuse

        if len(short) < 2:  # fewer than 3 items with the query: nothing to diffuse over
            return [Hit(r + 1, p, 0.0, x) for r, (p, x) in enumerate(short[:top])]
        k = RERANK_DEFAULTS[method]["k"]
        if vs is not None:
            local = [int(p) for p in pos]
            seen = set(local)
            frontier = np.asarray(local, dtype=np.int64)
            for _ in range(DIFFUSION_HOPS):
                nb = np.asarray(vs.nbr[frontier, : min(k, GRAPH_K)]).ravel()
                fresh = [int(j) for j in dict.fromkeys(nb[nb >= 0].tolist()) if j not in seen]
                seen.update(fresh)
                local += fresh
                frontier = np.asarray(fresh, dtype=np.int64)
                if not fresh:
                    break
            Z = np.vstack([np.asarray(q, dtype=np.float64).reshape(1, -1),
                           np.asarray(vs.X[np.asarray(local, dtype=np.int64)])])
            D = pair_distances(vs.metric, Z[:, None, :], Z[None, :, :])
        elif isinstance(q, Mapping):  # a fusion: its components' local matrices, fused
            from geoshape.retrieval.descriptors import FUSIONS
            from geoshape.retrieval.fusion import fuse_distances

            weights = {c: w for c, w in FUSIONS[descriptor].items() if w > 0}
            D = fuse_distances({c: descriptor_distances(c, [q[c], *(r[c] for r in rows)],
                                                        [q[c], *(r[c] for r in rows)]) for c in weights},
                               weights)
        else:
            Z = [q, *rows]
            D = descriptor_distances(descriptor, Z, Z)
        R = diffuse(D, method)
        score = R[0, 1 : 1 + len(short)]
        first = np.asarray([x for _, x in short])
        # a stored copy of the query (first-stage distance 0) stays first: diffusion scores
        # saturate within a tight group, and a duplicate is the best answer by definition
        copy = first <= DUPLICATE_DISTANCE
        order = np.lexsort((np.arange(len(short)), first, score, ~copy))
        return [Hit(r + 1, short[o][0], float(score[o]), float(first[o])) for r, o in enumerate(order[:top])]

    @mesh_input
    def query_mesh(self, V, F, descriptor: str = DEFAULT_QUERY_METHOD, *, top: int = 10,
                   affinity: str | None = None, seed: int = 0, rerank: str | None = None,
                   rerank_k: int | None = None, skip_missing: bool = True) -> tuple[list[Hit], dict]:
        """Describe a mesh and rank the stored shapes against it.

        ``V, F`` may be replaced by one trimesh / Open3D / pymeshlab mesh (vertex order kept).
        ``descriptor``: a stored descriptor or a fusion, by default ``"fused"`` (its
        components computed together, one shared eigen-solve; see :meth:`query_descriptor`).
        ``rerank``: a second descriptor (``"ccd"``) or a diffusion method (``"lcdp"``), see
        :meth:`query_descriptor`.

        Returns
        -------
        hits : list of :class:`Hit`
        timing : dict
            ``seconds_descriptor`` (query descriptors) and ``seconds_search``.
        """
        from geoshape.parallel import single_thread_blas
        from geoshape.retrieval.descriptors import (
            FUSIONS,
            compute_descriptor,
            compute_descriptor_set,
            get_descriptor,
            method_descriptors,
        )
        from geoshape.retrieval.rerank import RERANK_METHODS

        t0 = time.perf_counter()
        check_query_method(descriptor)
        if rerank is not None:
            check_rerank(rerank)
        with single_thread_blas():  # small dense eigenproblems: threads only spin
            if descriptor in FUSIONS:  # its components, sharing one eigen-solve
                q = compute_descriptor_set(V, F, method_descriptors(descriptor), affinity=affinity,
                                           seed=seed)[0]
            else:
                spec = get_descriptor(descriptor)
                q = compute_descriptor(V, F, descriptor, seed=seed,
                                       affinity=affinity if spec.uses_affinity else None)
            rq = None
            if rerank and rerank not in RERANK_METHODS:
                rspec = get_descriptor(rerank)
                rq = compute_descriptor(V, F, rerank, seed=seed,
                                        affinity=affinity if rspec.uses_affinity else None)
        t1 = time.perf_counter()
        hits = self.query_descriptor(q, descriptor, top=top, affinity=affinity, seed=seed,
                                     rerank=rerank, rerank_q=rq, rerank_k=rerank_k,
                                     skip_missing=skip_missing)
        t2 = time.perf_counter()
        return hits, {"seconds_descriptor": t1 - t0, "seconds_search": t2 - t1}


def query_methods() -> tuple[str, ...]:
    """What ``query_mesh`` / ``index query --descriptor`` ranks by: a stored descriptor, or a
    fusion of stored descriptors (:data:`geoshape.retrieval.descriptors.FUSIONS`)."""
    from geoshape.retrieval.descriptors import FUSIONS, MESH_DESCRIPTORS

    return (*MESH_DESCRIPTORS, *FUSIONS)


def check_query_method(name: str) -> str:
    """``name`` if :func:`query_methods` has it, else :class:`InvalidOptionError` listing them."""
    from geoshape._options import check_choice

    return check_choice("descriptor", name, query_methods())


def rerank_choices() -> tuple[str, ...]:
    """What ``rerank=`` / ``index query --rerank`` accepts: a stored descriptor, or a
    diffusion method of :mod:`geoshape.retrieval.rerank`."""
    from geoshape.retrieval.descriptors import MESH_DESCRIPTORS
    from geoshape.retrieval.rerank import RERANK_METHODS

    return (*MESH_DESCRIPTORS, *RERANK_METHODS)


def check_rerank(name: str) -> str:
    """``name`` if :func:`rerank_choices` has it, else :class:`InvalidOptionError` listing them."""
    from geoshape._options import check_choice

    return check_choice("re-ranking", name, rerank_choices())


def _split_inputs(inputs, names, report: AddReport) -> tuple[list, list[_MemoryMesh]]:
    """Paths (files, folders) and meshes in memory of :meth:`ShapeIndex.add`'s ``inputs``,
    the meshes validated, hashed and named; an invalid mesh goes to ``report.failed``."""
    from geoshape.errors import InvalidMeshError
    from geoshape.io.interop import as_arrays, is_mesh_object, mesh_content_sha256

    if isinstance(inputs, Mapping):
        if names is not None:
            raise InvalidOptionError("give names either as the keys of inputs or as names=, not both")
        names, inputs = list(inputs), list(inputs.values())
    elif isinstance(inputs, (str, os.PathLike)) or is_mesh_object(inputs):
        inputs = [inputs]
    else:
        inputs = list(inputs)
    if names is None:
        names = [None] * len(inputs)
    names = list(names)
    if len(names) != len(inputs):
        raise InvalidOptionError(f"names must have one entry per input: {len(names)} names "
                                 f"for {len(inputs)} inputs")
    paths, meshes, taken = [], {}, set()
    for i, (item, name) in enumerate(zip(inputs, names, strict=True)):
        if isinstance(item, (str, os.PathLike)):
            if name is not None:
                raise InvalidOptionError(f"input {i} ({item}) is a path: a file is stored under its "
                                         f"path, names= applies to meshes only (give None)")
            paths.append(item)
            continue
        if not is_mesh_object(item):
            as_arrays(item, name=f"input {i}")  # raises, naming the type
        if name is not None and (not isinstance(name, str) or not name or os.path.isabs(name)):
            raise InvalidOptionError(f"mesh names must be non-empty text and not absolute paths "
                                     f"(those are files' keys); got {name!r} for input {i}")
        if name is not None and name in taken:
            raise InvalidOptionError(f"mesh name {name!r} is given twice")
        taken.add(name)
        label = name or f"mesh {i}"
        try:
            V, F = as_arrays(item, name=label)
        except InvalidMeshError as exc:
            report.failed.append((label, str(exc)))
            continue
        sha = mesh_content_sha256(V, F)
        key = name or f"mesh-{sha[:16]}"
        if key in meshes and (name is not None or meshes[key].sha256 != sha):
            raise InvalidOptionError(f"mesh name {key!r} is given twice")
        meshes[key] = _MemoryMesh(key, sha, V, F)
    return paths, list(meshes.values())


def _select_rows(conn: sqlite3.Connection, descriptor: str, pkey: str, paths) -> dict:
    """``{path: row}`` of one set's stored rows among ``paths``, 500 a statement."""
    out = {}
    for s in range(0, len(paths), 500):
        chunk = paths[s : s + 500]
        for path, shape, data in conn.execute(
                f"SELECT path, shape, data FROM entries WHERE descriptor = ? AND params = ? "
                f"AND path IN ({', '.join('?' * len(chunk))})", (descriptor, pkey, *chunk)):
            out[path] = np.frombuffer(data, dtype=np.float64).reshape(json.loads(shape))
    return out


def _existing_nearest(d: np.ndarray, paths, want: int, skip_missing: bool, index_path) -> np.ndarray:
    """Positions of the ``want`` smallest of ``d`` (nearest first); with ``skip_missing`` only
    of files that still exist, statting only the candidates and widening the shortlist past
    deleted files. Raises :class:`DatasetError` when none exists. O(m + k log k) per round."""
    m = len(paths)
    k = min(m, want)
    cand = _nearest_first(d, k)
    if not skip_missing:
        return cand
    while True:
        present = [i for i in cand if not _is_gone(paths[i])]
        if len(present) >= k or len(cand) == m:
            break
        cand = _nearest_first(d, min(m, 2 * len(cand) + k))
    if not present:
        raise DatasetError(f"{index_path}: none of the stored files exists any more "
                           "(run 'geoshape index prune')")
    return np.asarray(present[:k], dtype=np.int64)


def _nearest_first(d: np.ndarray, k: int) -> np.ndarray:
    """Indices of the ``k`` smallest entries of ``d``, ascending (ties by index); O(M + k log k)."""
    m = len(d)
    cand = np.argpartition(d, k - 1)[:k] if k < m else np.arange(m)
    return cand[np.lexsort((cand, d[cand]))]


def _claim_alive(host: str, pid: int, since: float, my_host: str, now: float) -> bool:
    """Is a claim still held? Never once older than :data:`CLAIM_LIFETIME`; before that, on
    this host while its process lives, on another host always."""
    if now - since >= CLAIM_LIFETIME:  # old claims lapse (a pid may have been reused)
        return False
    if host != my_host:  # cannot look at another host's processes
        return True
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # a process that died but was not reaped (a zombie) holds nothing
        return Path(f"/proc/{int(pid)}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def _rollback(conn: sqlite3.Connection) -> None:
    """Roll back if a transaction is still open (SQLite may already have rolled back on a
    full disk or an I/O error; a second ROLLBACK would hide that error)."""
    if conn.in_transaction:
        with contextlib.suppress(sqlite3.Error):
            conn.execute("ROLLBACK")
