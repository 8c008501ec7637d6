"""One runner for every batch job: serial, local processes, or Dask distributed.

:func:`run_map` applies a function to a list of items and returns the results in input
order, whatever the backend; :func:`pairwise_matrix` fills an all-pairs matrix in blocks
so that each item (e.g. a precomputed descriptor) is sent to a worker once per block,
not once per pair.

Backends
--------
``"serial"``
    A plain loop in this process. No overhead; use it to debug.
``"processes"``
    ``concurrent.futures.ProcessPoolExecutor`` with the *spawn* start method (safe with
    threads, BLAS and Dask in the parent; the same on every OS). ``func`` and the items
    must be picklable: a function defined at module top level, not a lambda or closure.
    Overhead: about 0.5–1 s to start each worker (it re-imports NumPy and geoshape) and
    one pickle round trip per chunk of items.
``"dask"``
    ``distributed.Client.submit`` on a cluster named by ``scheduler`` (an address such as
    ``"tcp://host:port"`` or an existing ``distributed.Client``); without ``scheduler`` a
    temporary local cluster of ``n_jobs`` single-threaded worker processes is started and
    closed afterwards (several seconds). Overhead: a few milliseconds per task on top of
    pickling; functions are shipped with cloudpickle, so closures work too.

Work is sent in chunks of ``chunksize`` items (default: about four chunks per worker) to
keep the per-task overhead small. Ctrl-C cancels pending work, shuts the pool or the
temporary cluster down and re-raises :class:`KeyboardInterrupt`; local workers are
terminated at once rather than awaited, and die with their parent (Linux).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import sys
import threading
import traceback
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError, MissingDependencyError

__all__ = ["BACKENDS", "ON_ERROR", "run_map", "pairwise_matrix", "default_n_jobs", "blas_threads",
           "single_thread_blas", "beside", "map_beside", "map_beside_after", "stage_processes",
           "can_run_beside"]

log = logging.getLogger(__name__)

#: files this process is writing that would be left half-done if it were stopped now (the
#: temporaries of geoshape.io.atomic, which adds and removes them): a pool worker removes
#: them when it is terminated (:func:`remove_unfinished_files_on_sigterm`)
UNFINISHED_FILES: set = set()

#: The registry of backends, in the order the CLI lists them.
BACKENDS = ("processes", "serial", "dask")
#: What :func:`run_map` does when one item raises.
ON_ERROR = ("raise", "return")


def default_n_jobs() -> int:
    """Number of worker processes used when ``n_jobs`` is ``None``: ``os.cpu_count()``."""
    return max(1, os.cpu_count() or 1)


def blas_threads(n: int | None = 1, *, openmp: bool = False):
    """Context manager limiting the BLAS thread pools to ``n`` threads (threadpoolctl).

    Inside a parallel task the work is already spread over processes, and the many small
    dense products and eigenproblems of this library run several times slower with
    threaded BLAS on busy cores (measured: one CCD of an 800-vertex mesh 15 s instead of
    0.3 s; a correspondence 5x slower on 2 cores). One thread also gives the same bits
    whichever runner computes a result.

    Parameters
    ----------
    n : int or None
        Threads per pool; ``None`` leaves the setting alone (a null context).
    openmp : bool
        Limit the OpenMP pools too (threadpoolctl's ``user_api=None``: every pool).

    Returns
    -------
    context manager

    >>> with blas_threads(1):
    ...     pass
    """
    if n is None:
        return contextlib.nullcontext()
    import scipy.linalg  # noqa: F401  (threadpoolctl limits only the libraries already loaded)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=n, user_api=None if openmp else "blas")


def single_thread_blas():
    """``blas_threads(1)``: one BLAS thread while the context lasts."""
    return blas_threads(1)


# ---------------------------------------------------------------------------------------
# Top-level task functions (picklable by reference under spawn)
# ---------------------------------------------------------------------------------------


def _portable_exception(exc: BaseException) -> BaseException:
    """``exc`` with its formatted traceback attached, or a picklable stand-in."""
    import pickle

    tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:  # an exception that cannot cross a process boundary
        exc = RuntimeError(f"{type(exc).__name__}: {exc}")
    exc.geoshape_traceback = tb  # type: ignore[attr-defined]
    return exc


def _run_chunk(func: Callable, chunk: Sequence, on_error: str) -> list:
    """Apply ``func`` to each item of ``chunk``; with ``on_error="return"`` keep exceptions."""
    out = []
    for item in chunk:
        if on_error == "raise":
            out.append(func(item))
            continue
        try:
            out.append(func(item))
        except Exception as exc:
            out.append(_portable_exception(exc))
    return out


def _worker_chunk(func: Callable, chunk: Sequence, on_error: str) -> list:
    """:func:`_run_chunk` in a worker process of :func:`run_map`: no stage of ``func`` runs
    :func:`beside` another (every core already runs a chunk)."""
    with stage_processes(False):
        return _run_chunk(func, chunk, on_error)


def _pair_block(
    func: Callable,
    items_i: Sequence,
    items_j: Sequence,
    same_block: bool,
    symmetric: bool,
    vectorized: bool,
    diagonal: float | None,
) -> np.ndarray:
    """Dissimilarities of one block ``items_i`` × ``items_j`` as a float64 array."""
    if vectorized:
        block = np.asarray(func(items_i, items_j), dtype=np.float64)
        if block.shape != (len(items_i), len(items_j)):
            raise InvalidOptionError(
                f"a vectorized pairwise function must return shape "
                f"({len(items_i)}, {len(items_j)}), got {block.shape}"
            )
        block = block.copy()
        if same_block and symmetric:
            block = np.triu(block) + np.triu(block, 1).T
        if same_block and diagonal is not None:
            np.fill_diagonal(block, diagonal)
        return block
    block = np.zeros((len(items_i), len(items_j)), dtype=np.float64)
    for a, x in enumerate(items_i):
        for b, y in enumerate(items_j):
            if same_block and a == b:
                block[a, b] = func(x, y) if diagonal is None else diagonal
            elif same_block and symmetric and b < a:
                block[a, b] = block[b, a]
            else:
                block[a, b] = func(x, y)
    return block


def _call_packed(args: tuple) -> Any:
    """Unpack ``(func, *args)`` — lets :func:`run_map` run multi-argument tasks."""
    func, *rest = args
    return func(*rest)


# ---------------------------------------------------------------------------------------
# The runner
# ---------------------------------------------------------------------------------------


def _progress_bar(total: int, desc: str | None, progress: bool):
    from tqdm.auto import tqdm

    enabled = bool(progress) and hasattr(sys.stderr, "isatty") and sys.stderr.isatty()
    return tqdm(total=total, desc=desc, disable=not enabled, leave=False)


def _chunks(n: int, chunksize: int) -> list[range]:
    return [range(s, min(s + chunksize, n)) for s in range(0, n, chunksize)]


def _resolve_backend(backend: str | None, scheduler: Any) -> str:
    if backend is None:
        backend = "dask" if scheduler is not None else "processes"
    check_choice("backend", backend, BACKENDS)
    if scheduler is not None and backend != "dask":
        raise InvalidOptionError(
            f"a Dask scheduler was given ({scheduler!r}) but backend={backend!r}; "
            "use backend='dask' (or leave backend unset)"
        )
    return backend


def run_map(
    func: Callable[[Any], Any],
    items: Iterable,
    *,
    backend: str | None = None,
    n_jobs: int | None = None,
    scheduler: Any = None,
    desc: str | None = None,
    progress: bool = True,
    chunksize: int | None = None,
    on_error: str = "raise",
) -> list:
    """Apply ``func`` to every item; results in input order, identical on every backend.

    Parameters
    ----------
    func : callable
        ``func(item) -> result``. For ``"processes"`` it must be picklable (defined at the
        top level of an importable module); results must be picklable for both parallel
        backends.
    items : iterable
        Materialised into a list first.
    backend : {"processes", "serial", "dask"} or None
        ``None`` (default) means ``"dask"`` when ``scheduler`` is given, else
        ``"processes"``.
    n_jobs : int or None
        Worker processes (``"processes"``, or the temporary local Dask cluster);
        default :func:`default_n_jobs`. ``n_jobs=1`` runs in this process.
    scheduler : str or distributed.Client or None
        Dask scheduler address (``"tcp://host:port"``) or a connected client. A client
        passed in is left open; one created here is closed on return.
    desc : str or None
        Label of the progress bar.
    progress : bool
        Show a tqdm bar on stderr (only when stderr is a terminal).
    chunksize : int or None
        Items per task; default ``ceil(len(items) / (4 * workers))``.
    on_error : {"raise", "return"}
        ``"raise"``: the first exception aborts the batch (pending work is cancelled) and
        is re-raised. ``"return"``: an item that raises an ``Exception`` gets the
        exception object as its result (with the formatted traceback in its attribute
        ``geoshape_traceback``), so a batch can report a bad file and go on.

    Returns
    -------
    list
        ``[func(item) for item in items]`` (or exceptions, see ``on_error``).

    Raises
    ------
    InvalidOptionError
        Unknown ``backend`` or ``on_error``, ``n_jobs < 1``, ``chunksize < 1``, or a
        scheduler given with a non-Dask backend.
    MissingDependencyError
        ``backend="dask"`` without ``dask[distributed]`` installed.
    KeyboardInterrupt
        Re-raised after cancelling pending work on Ctrl-C.

    Notes
    -----
    Time: ``len(items)`` calls of ``func`` spread over the workers, plus the backend
    overhead described in the module docstring. Memory: all results are held at once.

    Examples
    --------
    >>> run_map(abs, [-1, 2, -3], backend="serial")
    [1, 2, 3]
    """
    backend = _resolve_backend(backend, scheduler)
    check_choice("on_error", on_error, ON_ERROR)
    if n_jobs is not None and (not isinstance(n_jobs, (int, np.integer)) or n_jobs < 1):
        raise InvalidOptionError(f"n_jobs must be a positive integer or None; got {n_jobs!r}")
    if chunksize is not None and (
        not isinstance(chunksize, (int, np.integer)) or chunksize < 1
    ):
        raise InvalidOptionError(f"chunksize must be a positive integer or None; got {chunksize!r}")
    items = list(items)
    n = len(items)
    if n == 0:
        return []
    workers = int(n_jobs) if n_jobs is not None else default_n_jobs()
    if backend == "processes" and workers == 1:
        backend = "serial"
    if chunksize is None:
        chunksize = max(1, math.ceil(n / (4 * workers)))
    chunks = _chunks(n, int(chunksize))

    results: list = [None] * n
    with _progress_bar(n, desc, progress) as bar:
        if backend == "serial":
            for rng_ in chunks:
                out = _run_chunk(func, [items[i] for i in rng_], on_error)
                results[rng_.start : rng_.stop] = out
                bar.update(len(rng_))
        elif backend == "processes":
            _run_processes(func, items, chunks, on_error, workers, results, bar)
        else:
            _run_dask(func, items, chunks, on_error, workers, scheduler, results, bar)
    return results


def die_with_parent(parent_pid: int | None = None) -> None:
    """Ask the kernel to send this process SIGTERM when its parent dies (Linux
    ``PR_SET_PDEATHSIG``; a no-op elsewhere), so no worker outlives a killed command. With
    ``parent_pid``, exit at once if that parent already died before the request was made."""
    import os
    import sys

    if sys.platform.startswith("linux"):
        import contextlib
        import ctypes
        import signal

        with contextlib.suppress(Exception):
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)


def _start_worker(parent_pid: int) -> None:
    """Initializer of a pool worker: :func:`die_with_parent` and
    :func:`remove_unfinished_files_on_sigterm` (SIGTERM is how :func:`_stop_now` and a dying
    parent stop it)."""
    die_with_parent(parent_pid)
    remove_unfinished_files_on_sigterm()


def remove_unfinished_files_on_sigterm() -> None:
    """From now on SIGTERM first removes this process's :data:`UNFINISHED_FILES`, then ends
    the process as SIGTERM does: a pool worker stopped by Ctrl-C of a batch leaves no
    temporary of the output it was writing. Call from the main thread."""
    import signal

    def handler(signum, _frame):
        for path in list(UNFINISHED_FILES):
            with contextlib.suppress(OSError):
                os.unlink(path)
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)

    signal.signal(signal.SIGTERM, handler)


def _stop_now(executor) -> None:
    """Terminate a pool's workers at once (Ctrl-C): running tasks are abandoned, not awaited."""
    import contextlib

    procs = list(getattr(executor, "_processes", {}).values())
    for proc in procs:
        with contextlib.suppress(Exception):
            proc.terminate()
    for proc in procs:  # reaped, so their queues and semaphores are released (no leak warnings)
        with contextlib.suppress(Exception):
            proc.join(timeout=2.0)
    with contextlib.suppress(Exception):
        executor.shutdown(wait=True, cancel_futures=True)


def _run_processes(func, items, chunks, on_error, workers, results, bar) -> None:
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    ctx = mp.get_context("spawn")
    executor = ProcessPoolExecutor(max_workers=min(workers, len(chunks)), mp_context=ctx,
                                   initializer=_start_worker, initargs=(os.getpid(),))
    futures: dict = {}
    try:
        for rng_ in chunks:
            fut = executor.submit(_worker_chunk, func, [items[i] for i in rng_], on_error)
            futures[fut] = rng_
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                rng_ = futures[fut]
                results[rng_.start : rng_.stop] = fut.result()
                bar.update(len(rng_))
    except KeyboardInterrupt:
        # Ctrl-C: stop within a moment; what finished was already returned to the caller's
        # results (and, for batches, written atomically), the rest is abandoned.
        _stop_now(executor)
        raise
    except BaseException:
        # The first failing item: drop what has not started, let running items finish.
        for fut in futures:
            fut.cancel()
        executor.shutdown(wait=True, cancel_futures=True)
        raise
    executor.shutdown(wait=True)


def _dask_client(scheduler, workers):
    """``(client, owned)``: a connected client and whether we must close it."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise MissingDependencyError(
            "backend='dask' needs dask[distributed]: pip install 'geoshape[dask]'"
        ) from exc
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
        return Client(cluster), True
    if isinstance(scheduler, str):
        return Client(scheduler), True
    if isinstance(scheduler, Client):
        return scheduler, False
    raise InvalidOptionError(
        f"scheduler must be an address like 'tcp://host:port' or a distributed.Client; "
        f"got {type(scheduler).__name__}"
    )


def _run_dask(func, items, chunks, on_error, workers, scheduler, results, bar) -> None:
    client, owned = _dask_client(scheduler, workers)
    from distributed import as_completed

    futures: dict = {}
    try:
        for rng_ in chunks:
            fut = client.submit(
                _worker_chunk, func, [items[i] for i in rng_], on_error, pure=False
            )
            futures[fut] = rng_
        for fut in as_completed(list(futures)):
            rng_ = futures[fut]
            results[rng_.start : rng_.stop] = fut.result()
            bar.update(len(rng_))
    except BaseException:
        client.cancel(list(futures))
        raise
    finally:
        if owned:
            cluster = getattr(client, "cluster", None)
            client.close()
            if cluster is not None:
                cluster.close()


# ---------------------------------------------------------------------------------------
# All-pairs matrices
# ---------------------------------------------------------------------------------------


def pairwise_matrix(
    func: Callable,
    items: Sequence,
    *,
    symmetric: bool = True,
    vectorized: bool = False,
    diagonal: float | None = None,
    block_size: int | None = None,
    backend: str | None = None,
    n_jobs: int | None = None,
    scheduler: Any = None,
    desc: str | None = None,
    progress: bool = True,
) -> np.ndarray:
    """All-pairs dissimilarity matrix ``D[i, j] = func(items[i], items[j])``, in blocks.

    The index range is cut into blocks of ``block_size`` items; one task computes one
    block pair and receives each of its items once, so per-item data (descriptors,
    meshes) is pickled ``O(N / block_size)`` times in total rather than once per pair.

    Parameters
    ----------
    func : callable
        ``func(a, b) -> float``; or, with ``vectorized=True``,
        ``func(list_a, list_b) -> (len(list_a), len(list_b))`` array.
    items : sequence
        The N items (e.g. per-shape descriptors), picklable for parallel backends.
    symmetric : bool
        ``True``: only blocks on and above the diagonal are computed (``func(a, b)``
        with ``i <= j``) and mirrored, about half the work. ``False``: every ordered
        pair is computed.
    vectorized : bool
        Call ``func`` once per block on two lists instead of once per pair.
    diagonal : float or None
        Value written on the diagonal instead of calling ``func(a, a)``; ``None``
        (default) computes it.
    block_size : int or None
        Items per block side; default ``ceil(N / (2 * workers))`` clipped to [1, 256],
        which gives several tasks per worker.
    backend, n_jobs, scheduler, desc, progress
        As in :func:`run_map`.

    Returns
    -------
    D : (N, N) float64
        Symmetric when ``symmetric=True`` (the upper triangle is copied down).

    Raises
    ------
    InvalidOptionError
        Bad backend or block size, or a vectorized ``func`` returning the wrong shape.

    Notes
    -----
    Time: ``N (N + 1) / 2`` (symmetric) or ``N^2`` calls of ``func`` over the workers.
    Memory: the ``(N, N)`` float64 result (8 N^2 bytes) plus one block per task.

    Examples
    --------
    >>> pairwise_matrix(lambda a, b: abs(a - b), [0.0, 1.0, 3.0], backend="serial").tolist()
    [[0.0, 1.0, 3.0], [1.0, 0.0, 2.0], [3.0, 2.0, 0.0]]
    """
    backend = _resolve_backend(backend, scheduler)
    items = list(items)
    n = len(items)
    if block_size is not None and (
        not isinstance(block_size, (int, np.integer)) or block_size < 1
    ):
        raise InvalidOptionError(
            f"block_size must be a positive integer or None; got {block_size!r}"
        )
    if n == 0:
        return np.zeros((0, 0), dtype=np.float64)
    workers = int(n_jobs) if n_jobs is not None else default_n_jobs()
    if block_size is None:
        block_size = int(np.clip(math.ceil(n / (2 * workers)), 1, 256))
    blocks = _chunks(n, int(block_size))
    tasks = []
    for bi, ri in enumerate(blocks):
        for bj, rj in enumerate(blocks):
            if symmetric and bj < bi:
                continue
            tasks.append((ri, rj))
    packed = [
        (
            _pair_block,
            [items[i] for i in ri],
            [items[j] for j in rj],
            ri == rj,
            symmetric,
            vectorized,
            diagonal,
        )
        for ri, rj in tasks
    ]
    # Re-pack so that the function travels with its block: (func, *args) per task.
    packed = [(p[0], func, *p[1:]) for p in packed]
    out = run_map(
        _call_packed,
        packed,
        backend=backend,
        n_jobs=n_jobs,
        scheduler=scheduler,
        desc=desc,
        progress=progress,
        chunksize=1,
    )
    D = np.zeros((n, n), dtype=np.float64)
    for (ri, rj), block in zip(tasks, out, strict=True):
        D[ri.start : ri.stop, rj.start : rj.stop] = block
        if symmetric and ri != rj:
            D[rj.start : rj.stop, ri.start : ri.stop] = block.T
    return D


# ---------------------------------------------------------------------------------------
# One job's independent stages on a second core
# ---------------------------------------------------------------------------------------

#: whether :func:`beside` may fork, per thread (switched off by :func:`stage_processes`,
#: e.g. in the workers of :func:`run_map`, where every core already runs an item, and in a
#: forked child itself)
_STAGE_SETTING = threading.local()
#: environment switch: ``GEOSHAPE_STAGE_PROCESSES=0`` runs every stage in this process
STAGE_PROCESSES_ENV = "GEOSHAPE_STAGE_PROCESSES"
#: children of :func:`beside` forked by this process that have not answered yet (one slot, mutable)
_LIVE_CHILDREN = [0]
#: children that answered and are exiting: reaped without waiting (:func:`_reap_exited`), so
#: the caller goes on while the kernel tears a child's copy of the address space down (about
#: 5 ms on a 5k-vertex correspondence, six times a pair)
_EXITING: list[int] = []


def _reap_exited() -> None:
    """Reap the children of :data:`_EXITING` that have exited, without blocking."""
    for pid in list(_EXITING):
        try:
            done, _ = os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:  # SIGCHLD ignored, or another child watcher was first
            done = pid
        if done:
            _EXITING.remove(pid)


@contextlib.contextmanager
def stage_processes(enabled: bool):
    """Context manager allowing (``True``) or forbidding (``False``) :func:`beside` to run a
    stage in a forked process while it lasts, in this thread; restores the previous setting.
    Wrap work you parallelise yourself (your own process pool) in ``stage_processes(False)``."""
    before = getattr(_STAGE_SETTING, "enabled", True)
    _STAGE_SETTING.enabled = bool(enabled)
    try:
        yield
    finally:
        _STAGE_SETTING.enabled = before


def _other_threads() -> list:
    """Live threads other than this one, except tqdm's monitor (it only sleeps and polls)."""
    me = threading.current_thread()
    return [t for t in threading.enumerate() if t is not me and type(t).__name__ != "TMonitor"]


def can_run_beside() -> bool:
    """Whether :func:`beside` forks: on Linux, from the main thread of a non-daemon process
    with no other live thread (a lock held by another thread at the fork would stay held in
    the child), no child of an earlier :func:`beside` still running (two processes for two
    cores: a stage nested in another runs here) and at least two usable cores, unless
    :func:`stage_processes` (``False``) or ``GEOSHAPE_STAGE_PROCESSES=0`` says not to."""
    import multiprocessing

    if not getattr(_STAGE_SETTING, "enabled", True) or os.environ.get(STAGE_PROCESSES_ENV, "1") == "0":
        return False
    if _LIVE_CHILDREN[0]:
        return False
    _reap_exited()
    if not sys.platform.startswith("linux") or not hasattr(os, "fork"):
        return False  # macOS: fork is unsafe with system frameworks; Windows: none
    if threading.current_thread() is not threading.main_thread() or multiprocessing.current_process().daemon:
        return False
    if _other_threads():
        return False
    try:
        return len(os.sched_getaffinity(0)) >= 2
    except (AttributeError, OSError):
        return (os.cpu_count() or 1) >= 2


class Beside:
    """The result of ``fn()`` computed by :func:`beside`: in a forked child process while the
    caller goes on, or already computed here. :meth:`result` returns it (re-raising the
    child's exception); :meth:`cancel` kills an unfinished child."""

    def __init__(self, fn: Callable[[], Any], fork: bool | None = None):
        self._fn = fn
        self._owner = os.getpid()
        self._pid: int | None = None
        self._fd: int | None = None
        self._done = False
        self._value: Any = None
        self._error: BaseException | None = None
        if (can_run_beside() if fork is None else fork) and self._fork():
            return
        self._run_here()

    def _run_here(self) -> None:
        try:
            self._value = self._fn()
        except Exception as exc:
            self._error = exc
        self._done = True

    def _fork(self) -> bool:
        """Start the child; False (nothing started, nothing left open) if the system refuses."""
        try:
            read_fd, write_fd = os.pipe()
        except OSError as exc:
            log.warning("cannot run a stage beside the others (%s); running it here", exc)
            return False
        for stream in (sys.stdout, sys.stderr):  # nothing buffered is written twice
            with contextlib.suppress(Exception):
                stream.flush()
        parent = os.getpid()
        try:
            pid = os.fork()
        except OSError as exc:  # e.g. a process limit, or no memory for the page tables
            os.close(read_fd)
            os.close(write_fd)
            log.warning("cannot fork to run a stage beside the others (%s); running it here", exc)
            return False
        if pid == 0:
            self._child(read_fd, write_fd, parent)
        self._pid, self._fd = pid, read_fd
        _LIVE_CHILDREN[0] += 1
        os.close(write_fd)
        return True

    def _child(self, read_fd: int, write_fd: int, parent: int) -> None:
        """In the child: compute, send the pickled outcome (or the error), leave at once."""
        import pickle
        import signal

        code = 1
        try:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the parent's handlers
            signal.signal(signal.SIGINT, signal.default_int_handler)
            die_with_parent(parent)
            _STAGE_SETTING.enabled = False  # no grandchildren
            os.close(read_fd)
            try:
                data = pickle.dumps((True, self._fn()), protocol=pickle.HIGHEST_PROTOCOL)
            except Exception as exc:  # the stage's error, or a result that cannot be pickled
                data = pickle.dumps((False, _portable_exception(exc)), protocol=pickle.HIGHEST_PROTOCOL)
            with os.fdopen(write_fd, "wb") as f:
                f.write(data)
            code = 0
        finally:
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            os._exit(code)  # no atexit handlers, no flush of buffers copied from the parent

    def result(self) -> Any:
        """The value of ``fn()``, or its exception raised here. Only a child killed before it
        answered (by a signal, e.g. out of memory) is replaced by computing ``fn()`` here."""
        if not self._done:
            import pickle

            with os.fdopen(self._fd, "rb") as f:
                self._fd = None
                data = f.read()
            try:
                ok, value = pickle.loads(data)
            except Exception:
                log.warning("a stage run beside the others ended without a result (wait status %s); "
                            "computing it here", self._reap())
                self._run_here()
            else:
                self._release()
                self._done = True
                self._value, self._error = (value, None) if ok else (None, value)
        if self._error is not None:
            raise self._error
        return self._value

    def _release(self) -> None:
        """The child answered and only has to exit: it no longer counts as running, and
        :func:`_reap_exited` reaps it later without waiting."""
        _EXITING.append(self._pid)
        self._pid = None
        _LIVE_CHILDREN[0] -= 1

    def _reap(self) -> int | None:
        """Wait for the child; its wait status (None if something else reaped it)."""
        pid, self._pid = self._pid, None
        _LIVE_CHILDREN[0] -= 1
        try:
            return os.waitpid(pid, 0)[1]
        except ChildProcessError:  # SIGCHLD ignored, or another child watcher was first
            return None

    def cancel(self) -> None:
        """Kill the child if it still runs (e.g. after Ctrl-C or an error in the caller)."""
        import signal

        if os.getpid() != self._owner:  # a copy inside some forked process: not ours to kill
            return
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self._pid is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self._pid, signal.SIGKILL)
            self._reap()

    def __enter__(self) -> Beside:
        return self

    def __exit__(self, *exc) -> None:
        self.cancel()

    def __del__(self):
        with contextlib.suppress(Exception):
            self.cancel()


def beside(fn: Callable, *args, fork: bool | None = None, **kwargs) -> Beside:
    """Run ``fn(*args, **kwargs)`` on another core while the caller goes on, for a stage of one
    job that does not depend on what the caller does meanwhile (one mesh's eigenproblem
    while another's is solved). The child is a fork: it starts with every array and
    cache as they are now, without copying them up front (pages are copied only when one
    side writes to them), and only its result travels back (pickled through a pipe,
    O(result size)). Changes the child makes to caches stay in the child: return what the
    caller needs.

    ``fork=None`` forks where that is safe and useful (:func:`can_run_beside`); ``fork=False``
    runs ``fn`` here and now (e.g. when there is nothing to share the work with). Either way
    the result is the same. Use as a context manager, or call :meth:`Beside.cancel` in a
    ``finally``, so that an error or Ctrl-C in the caller does not leave the child running.

    >>> with beside(sum, [1, 2, 3]) as total:
    ...     total.result()
    6
    """
    return Beside(lambda: fn(*args, **kwargs), fork=None if fork is not False else False)


#: tokens of one :func:`map_beside_after` pipe at most: 4096 bytes, one page, which every pipe
#: holds (Linux gives a pipe as little as one page once a user has many); longer lists are
#: handed out in runs of several items per token
_MAX_TOKENS = 1024


def _token_pipe(n: int) -> int:
    """The read end of a pipe holding the numbers ``0 … n−1`` (``n`` ≤ :data:`_MAX_TOKENS`) as
    4-byte tokens, its write end closed, so that reading returns the next token or ``b""``
    once every one was taken."""
    read_fd, write_fd = os.pipe()
    try:
        os.write(write_fd, np.arange(n, dtype="<u4").tobytes())
    finally:
        os.close(write_fd)
    return read_fd


def _take(fd: int) -> int | None:
    """The next token of :func:`_token_pipe`, None when none is left. Every read asks for one
    whole token and the pipe only ever holds whole ones, so two processes reading the same
    pipe each get whole, distinct tokens (Linux reads a pipe under its lock)."""
    data = os.read(fd, 4)
    if not data:
        return None
    if len(data) != 4:
        raise RuntimeError(f"a token pipe returned {len(data)} bytes instead of 4")
    return int.from_bytes(data, "little")


def _take_runs(fd: int, runs: list[range], fn: Callable, items: Sequence) -> dict:
    """``{index: fn(items[index])}`` for every run of indices taken from ``fd`` until none is left."""
    done = {}
    while (token := _take(fd)) is not None:
        for i in runs[token]:
            done[i] = fn(items[i])
    return done


def map_beside_after(first: Callable[[], Any] | None, fn: Callable[[Any], Any], items: Sequence, *,
                     here: Callable[[Any], Any] | None = None) -> tuple[Any, list]:
    """``(first(), [fn(x) for x in items])`` computed by this process and a child
    :func:`beside` it together. The child runs ``first`` (None: nothing), then both take the
    next item nobody has taken yet (a token read from one pipe) until none is left, so the
    work balances itself whatever each item and ``first`` cost. ``here`` replaces ``fn``
    for the items this process takes: ``fn`` plus a step whose caches should stay in this
    process (e.g. a measurement stored on the item); it must return what ``fn`` returns.

    Without a child to share with (:func:`can_run_beside` false, or nothing to share: fewer
    than two items, or no item besides ``first``) ``first`` and then every item through
    ``fn`` run here, in item order, and an error stops at once. Items of a child that dies
    before it answers are computed here. The result never depends on who computed what.
    Tokens: one per item, or per run of items beyond :data:`_MAX_TOKENS`.
    """
    items = list(items)
    shareable = len(items) >= 2 or (first is not None and len(items) >= 1)
    if not (shareable and can_run_beside()):
        return (first() if first is not None else None), [fn(x) for x in items]
    here = fn if here is None else here
    per_run = max(1, -(-len(items) // _MAX_TOKENS))
    runs = _chunks(len(items), per_run)
    fd = _token_pipe(len(runs))
    try:
        def child():
            return (first() if first is not None else None), _take_runs(fd, runs, fn, items)

        with beside(child) as side:
            done = _take_runs(fd, runs, here, items)
            first_value, done_beside = side.result()
    finally:
        os.close(fd)
    done.update(done_beside)
    return first_value, [done[i] if i in done else here(x) for i, x in enumerate(items)]


def map_beside(fn: Callable[[Any], Any], items: Sequence) -> list:
    """``[fn(x) for x in items]``, shared with a child :func:`beside` this process (each takes
    the next item left; :func:`map_beside_after` without ``first``); the same list either
    way. For a few costly, independent steps of one job, e.g. refining candidate maps.

    >>> map_beside(abs, [-1, 2, -3])
    [1, 2, 3]
    """
    return map_beside_after(None, fn, items)[1]
