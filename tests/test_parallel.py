"""Tests of the batch runner: same results on every backend, errors kept or raised."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.errors import InvalidOptionError
from geoshape.parallel import pairwise_matrix, run_map


def square_or_fail(x):
    """Top-level (picklable) task: x**2, but item 3 is a 'bad file'."""
    if x == 3:
        raise ValueError(f"bad item {x}")
    return x * x


def seeded_vector(seed):
    """A result that depends only on the item, never on the worker."""
    return np.random.default_rng(seed).normal(size=4)


def l1(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).sum())


def l1_block(A, B):
    A, B = np.asarray(A), np.asarray(B)
    return np.abs(A[:, None, :] - B[None, :, :]).sum(axis=2)


def ordered_diff(a, b):
    return float(a[0] - 2.0 * b[0])


ITEMS = [np.array([0.0, 1.0]), np.array([2.0, -1.0]), np.array([0.5, 0.5]),
         np.array([3.0, 3.0]), np.array([-1.0, 4.0])]
EXPECTED_L1 = np.array([[l1(a, b) for b in ITEMS] for a in ITEMS])


# the tests using a LocalCluster (two worker processes, ~5 s in all) are in the slow tier
@pytest.fixture(scope="module")
def dask_client():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    )
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_serial_order_and_values():
    assert run_map(square_or_fail, [0, 1, 2, 4], backend="serial", chunksize=3) == [0, 1, 4, 16]


def test_processes_match_serial():
    items = list(range(10))
    serial = run_map(seeded_vector, items, backend="serial")
    procs = run_map(seeded_vector, items, backend="processes", n_jobs=2, chunksize=3)
    assert len(procs) == 10
    for a, b in zip(serial, procs, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
def test_dask_matches_serial(dask_client):
    items = list(range(7))
    serial = run_map(seeded_vector, items, backend="serial")
    dsk = run_map(seeded_vector, items, scheduler=dask_client, chunksize=2)
    for a, b in zip(serial, dsk, strict=True):
        np.testing.assert_array_equal(a, b)
    # an address works as well as a client
    addr = run_map(square_or_fail, [5, 6], backend="dask", scheduler=dask_client.scheduler.address)
    assert addr == [25, 36]


@pytest.mark.parametrize("backend", ["serial", "processes"])
def test_on_error_return_collects_exception(backend):
    out = run_map(square_or_fail, [1, 2, 3, 4], backend=backend, n_jobs=2, on_error="return",
                  chunksize=2)
    assert out[0] == 1 and out[1] == 4 and out[3] == 16
    assert isinstance(out[2], ValueError)
    assert "bad item 3" in str(out[2])
    assert "square_or_fail" in out[2].geoshape_traceback


@pytest.mark.slow
def test_on_error_return_dask(dask_client):
    out = run_map(square_or_fail, [3, 2], scheduler=dask_client, on_error="return")
    assert isinstance(out[0], ValueError) and out[1] == 4


@pytest.mark.parametrize("backend", ["serial", "processes"])
def test_on_error_raise(backend):
    with pytest.raises(ValueError, match="bad item 3"):
        run_map(square_or_fail, [1, 3, 4], backend=backend, n_jobs=2, chunksize=1)


def test_bad_options():
    with pytest.raises(InvalidOptionError, match="backend must be one of.*'threads'"):
        run_map(abs, [1], backend="threads")
    with pytest.raises(InvalidOptionError, match="on_error"):
        run_map(abs, [1], backend="serial", on_error="ignore")
    with pytest.raises(InvalidOptionError, match="n_jobs"):
        run_map(abs, [1], backend="serial", n_jobs=0)
    with pytest.raises(InvalidOptionError, match="scheduler"):
        run_map(abs, [1], backend="serial", scheduler="tcp://127.0.0.1:1")
    with pytest.raises(InvalidOptionError, match="backend"):
        pairwise_matrix(l1, ITEMS, backend="gpu")


def test_empty():
    assert run_map(abs, [], backend="processes") == []
    assert pairwise_matrix(l1, [], backend="serial").shape == (0, 0)


@pytest.mark.parametrize("block_size", [1, 2, 5])
def test_pairwise_symmetric_serial(block_size):
    D = pairwise_matrix(l1, ITEMS, backend="serial", block_size=block_size)
    np.testing.assert_array_equal(D, EXPECTED_L1)
    Dv = pairwise_matrix(l1_block, ITEMS, vectorized=True, backend="serial",
                         block_size=block_size, diagonal=-1.0)
    expected = EXPECTED_L1.copy()
    np.fill_diagonal(expected, -1.0)
    np.testing.assert_array_equal(Dv, expected)


@pytest.mark.slow
def test_pairwise_asymmetric_backends(dask_client):
    expected = np.array([[ordered_diff(a, b) for b in ITEMS] for a in ITEMS])
    for kw in ({"backend": "serial"}, {"backend": "processes", "n_jobs": 2},
               {"scheduler": dask_client}):
        D = pairwise_matrix(ordered_diff, ITEMS, symmetric=False, block_size=2, **kw)
        np.testing.assert_array_equal(D, expected)
    D = pairwise_matrix(l1, ITEMS, backend="processes", n_jobs=2, block_size=2)
    np.testing.assert_array_equal(D, EXPECTED_L1)


# ---------------------------------------------------------------------------------------
# beside: one job's independent stage on a second core
# ---------------------------------------------------------------------------------------

def _forkable_here() -> bool:
    """Whether beside would fork in this process (other threads aside: see no_other_threads)."""
    from unittest import mock

    import geoshape.parallel

    with mock.patch.object(geoshape.parallel, "_other_threads", lambda: []):
        return geoshape.parallel.can_run_beside()


def _pid_and_square(x):
    import os

    return os.getpid(), x * x


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_beside_runs_in_another_process_and_returns_the_value():
    import os

    from geoshape.parallel import beside

    with beside(_pid_and_square, 7) as stage:
        pid, value = stage.result()
    assert value == 49 and pid != os.getpid()


@pytest.mark.parametrize("enabled", [True, False])
@pytest.mark.parametrize("n", [0, 1, 2, 5])
@pytest.mark.usefixtures("no_other_threads")
def test_map_beside_returns_every_value_in_order_whether_or_not_it_forks(enabled, n):
    import os

    from geoshape.parallel import map_beside, stage_processes

    with stage_processes(enabled):
        out = map_beside(_pid_and_square, range(n))
    assert [value for _, value in out] == [x * x for x in range(n)]
    if not enabled:
        assert all(pid == os.getpid() for pid, _ in out)


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_map_beside_after_shares_the_items_with_a_child_that_runs_first():
    import os
    import select

    from geoshape.parallel import map_beside_after

    to_child, to_parent = os.pipe(), os.pipe()

    def meet(say, hear):  # whoever holds an item waits until the other process holds the other one
        os.write(say[1], b"x")
        assert select.select([hear[0]], [], [], 60)[0], "the other process never took an item"
        return os.getpid()

    def child_item(x):
        return meet(to_parent, to_child), x * x

    def here_item(x):
        return meet(to_child, to_parent), x * x

    try:
        first, out = map_beside_after(os.getpid, child_item, [3, 4], here=here_item)
    finally:
        for fd in (*to_child, *to_parent):
            os.close(fd)
    assert [value for _, value in out] == [9, 16]
    assert first != os.getpid() and {pid for pid, _ in out} == {os.getpid(), first}


@pytest.mark.usefixtures("no_other_threads")
@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_map_beside_after_computes_here_what_a_killed_child_took():
    import os
    import select
    import signal

    from geoshape.parallel import can_run_beside, map_beside_after

    took = os.pipe()

    def dies(x):  # the child says it took an item, then dies without answering
        os.write(took[1], b"x")
        os.kill(os.getpid(), signal.SIGKILL)

    def here(x):  # this process waits until the child has taken an item
        assert select.select([took[0]], [], [], 60)[0], "the child never took an item"
        return x + 1

    try:
        first, out = map_beside_after(None, dies, range(6), here=here)
    finally:
        os.close(took[0]), os.close(took[1])
    assert first is None and out == [1, 2, 3, 4, 5, 6]
    assert can_run_beside()  # the dead child was reaped


def _fails_if_negative(x):
    if x < 0:
        raise InvalidOptionError(f"item {x}: must not be negative")
    return x


def test_map_beside_without_a_child_stops_at_the_first_error():
    from geoshape.parallel import map_beside_after, stage_processes

    seen = []

    def first():
        raise InvalidOptionError("first: no descriptors")

    with stage_processes(False):
        with pytest.raises(InvalidOptionError, match="item -1: must not be negative"):
            map_beside_after(None, lambda x: seen.append(x) or _fails_if_negative(x), [1, -1, 2])
        assert seen == [1, -1]
        with pytest.raises(InvalidOptionError, match="first: no descriptors"):
            map_beside_after(first, seen.append, [3, 4])
        assert seen == [1, -1]


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
@pytest.mark.parametrize("where", ["child item", "child first", "here"])
def test_map_beside_after_reraises_an_error_wherever_it_happens(where):
    import os
    import select

    from geoshape.parallel import can_run_beside, map_beside_after

    to_child, to_parent = os.pipe(), os.pipe()

    def meet(say, hear):  # each process holds an item until the other holds one (or failed first)
        os.write(say[1], b"x")
        assert select.select([hear[0]], [], [], 60)[0], "the other process never took an item"

    def child_item(x):
        meet(to_parent, to_child)
        return _fails_if_negative(-x if where == "child item" else x)

    def first():
        if where == "child first":
            os.write(to_parent[1], b"x")
            raise InvalidOptionError("item -0: must not be negative (first)")

    def here(x):
        meet(to_child, to_parent)
        return _fails_if_negative(-x if where == "here" else x)

    try:
        with pytest.raises(InvalidOptionError, match=r"item -\d: must not be negative"):
            map_beside_after(first, child_item, [1, 2], here=here)
    finally:
        for fd in (*to_child, *to_parent):
            os.close(fd)
    assert can_run_beside()  # the child was reaped or killed


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_a_stage_nested_in_a_running_beside_runs_here():
    import os

    from geoshape.parallel import beside, can_run_beside

    with beside(_pid_and_square, 2) as outer:
        assert not can_run_beside()  # one child at a time: two processes for two cores
        with beside(_pid_and_square, 3) as inner:
            assert inner.result() == (os.getpid(), 9)
        assert outer.result()[0] != os.getpid()
    assert can_run_beside()
    with beside(_pid_and_square, 4) as cancelled:
        cancelled.cancel()
    assert can_run_beside()


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_a_child_that_answered_is_reaped_without_waiting_for_its_exit():
    import os
    import time

    import geoshape.parallel
    from geoshape.parallel import beside, can_run_beside

    with beside(_pid_and_square, 5) as stage:
        child, _ = stage.result()
    assert child != os.getpid()
    assert can_run_beside()  # an answered child no longer holds the second core
    deadline = time.monotonic() + 30
    while child in geoshape.parallel._EXITING and time.monotonic() < deadline:
        time.sleep(0.01)
        can_run_beside()  # reaps the children that have exited
    assert child not in geoshape.parallel._EXITING
    with pytest.raises(ChildProcessError):  # reaped: no zombie of that id is left
        os.waitpid(child, os.WNOHANG)


def test_beside_runs_here_when_stage_processes_are_off():
    import os

    from geoshape.parallel import beside, can_run_beside, stage_processes

    with stage_processes(False):
        assert not can_run_beside()
        with beside(_pid_and_square, 3) as stage:
            assert stage.result() == (os.getpid(), 9)


@pytest.mark.parametrize("enabled", [True, False])
def test_beside_reraises_the_stage_error_with_its_type(enabled):
    from geoshape.parallel import beside, stage_processes

    def bad():
        raise InvalidOptionError("stage: k must be positive, got -1")

    with stage_processes(enabled), beside(bad) as stage, pytest.raises(InvalidOptionError, match="k must be"):
        stage.result()


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_beside_cancel_kills_an_unfinished_child():
    import os
    import time

    from geoshape.parallel import beside

    stage = beside(time.sleep, 60)
    pid = stage._pid
    stage.cancel()
    with pytest.raises(ChildProcessError):  # reaped: no process of that id is left to wait for
        os.waitpid(pid, os.WNOHANG)


def _can_run_beside(_):
    from geoshape.parallel import can_run_beside

    return can_run_beside()


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_run_map_workers_do_not_fork_stages_but_a_serial_run_does():
    assert run_map(_can_run_beside, [0, 1], backend="processes", n_jobs=2, progress=False) == [False, False]
    assert run_map(_can_run_beside, [0], backend="serial", progress=False) == [True]


def test_beside_runs_here_when_the_system_refuses_to_fork(monkeypatch):
    import os

    from geoshape.parallel import beside

    def refuse():
        raise BlockingIOError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(os, "fork", refuse)
    before = len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else None
    with beside(_pid_and_square, 5) as stage:
        assert stage.result() == (os.getpid(), 25)
    if before is not None:
        assert len(os.listdir("/proc/self/fd")) == before  # both pipe ends closed


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_beside_reports_a_result_that_cannot_cross_the_process_boundary():
    from geoshape.parallel import beside

    with beside(lambda: (lambda: 1)) as stage, pytest.raises(Exception, match="pickle"):
        stage.result()


def _can_fork_in_child():
    from geoshape.parallel import can_run_beside

    return can_run_beside()


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
@pytest.mark.usefixtures("no_other_threads")
def test_no_fork_inside_a_child():
    from geoshape.parallel import beside, can_run_beside

    assert can_run_beside()
    with beside(_can_fork_in_child) as stage:
        assert stage.result() is False


@pytest.mark.skipif(not _forkable_here(), reason="beside forks only on Linux with 2+ cores")
def test_no_fork_beside_another_live_thread():
    import threading

    from geoshape.parallel import can_run_beside

    stop = threading.Event()
    worker = threading.Thread(target=stop.wait)
    worker.start()
    try:
        assert not can_run_beside()
    finally:
        stop.set()
        worker.join()
