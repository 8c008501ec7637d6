"""Timing primitives of the benchmarks."""

from __future__ import annotations


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its finished (joined) children.

    The difference across a stage is the work it did, whichever other jobs share the machine
    (its wall seconds grow with their load). The ``processes`` backend's workers count: its
    pool is shut down, and its workers joined, before :func:`geoshape.parallel.run_map`
    returns; a Dask cluster's workers do not.
    """
    import resource

    return sum(getattr(resource.getrusage(who), field)
               for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
               for field in ("ru_utime", "ru_stime"))
