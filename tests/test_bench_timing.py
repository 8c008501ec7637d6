"""CPU seconds of a stage (what the rule of ``bench mirror2d`` budgets): the process pool's
workers count once ``run_map`` returns."""

from __future__ import annotations

import time

from geoshape.bench.timing import cpu_seconds
from geoshape.parallel import run_map

#: CPU seconds each task burns.
BURN = 0.3


def burn_cpu(_item) -> float:
    """Spin until this process has used ``BURN`` more CPU seconds; return them."""
    start = time.process_time()
    while time.process_time() - start < BURN:
        pass
    return time.process_time() - start


def test_cpu_seconds_count_the_pool_workers():
    before = cpu_seconds()
    used = run_map(burn_cpu, range(4), backend="processes", n_jobs=2, chunksize=1)
    spent = cpu_seconds() - before
    assert sum(used) >= 4 * BURN
    assert spent >= sum(used)  # the workers' CPU time, not only this process's waiting


def test_cpu_seconds_count_this_process():
    before = cpu_seconds()
    burn_cpu(None)
    assert cpu_seconds() - before >= BURN
