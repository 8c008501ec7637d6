"""Correspondences for every pair of a ``pairs.csv``, reusing per-mesh work.

Pairs are processed in file order on the parallel runner (:mod:`geoshape.parallel`);
each worker process keeps the last few :class:`PreparedMesh` objects (embeddings,
geodesic solvers, Laplacian bases), so a mesh that appears in consecutive pairs is
prepared once per worker. A pair that fails (missing mesh, bad coordinates, too few
vertices) is reported and skipped; every other map is still written, atomically.
"""

from __future__ import annotations

import os
import time
from collections import OrderedDict
from pathlib import Path

from geoshape.errors import GeoshapeError
from geoshape.io.atomic import write_text_atomic

_PREPARED: OrderedDict = OrderedDict()
_CACHE_SIZE = 6


def _prepared(path: str):
    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.io.mesh_io import load_mesh

    if path in _PREPARED:
        _PREPARED.move_to_end(path)
        return _PREPARED[path], 0.0
    t = time.perf_counter()
    mesh = PreparedMesh(*load_mesh(path), name=path)
    _PREPARED[path] = mesh
    while len(_PREPARED) > _CACHE_SIZE:
        _PREPARED.popitem(last=False)
    return mesh, time.perf_counter() - t


def _one_pair(task: dict) -> dict:
    from geoshape.correspondence.map_io import write_map
    from geoshape.correspondence.mesh_matching import correspond

    t0 = time.perf_counter()
    try:
        m1, load1 = _prepared(task["source"])
        m2, load2 = _prepared(task["target"])
        result = correspond(m1, None, m2, None, method=task["method"], seed=task["seed"])
        write_map(task["out"], result.p2p_12)
    except GeoshapeError as exc:
        return {**task, "ok": False, "error": str(exc)}
    return {**task, "ok": True, "seconds": time.perf_counter() - t0, "load_seconds": load1 + load2,
            "timings": result.timings}


def _refuse_colliding_names(tasks: list[dict], pairs_file: str) -> None:
    """Two different pairs whose files share stems would write one map file: refuse before
    any work (the ``<source_stem>__<target_stem>.txt`` names are a contract, so they are not
    renamed), naming both pairs. A pair listed twice is computed twice into the same file."""
    first: dict[str, tuple[str, str]] = {}
    for task in tasks:
        pair = (task["source"], task["target"])
        seen = first.setdefault(task["out"], pair)
        if seen != pair:
            from geoshape.errors import DatasetError

            raise DatasetError(
                f"{pairs_file}: pairs {seen[0]} -> {seen[1]} and {pair[0]} -> {pair[1]} would both write "
                f"{Path(task['out']).name}; rename one of the meshes or split the pairs file"
            )


def correspond_batch(folder: str | os.PathLike, out_dir: str | os.PathLike, *, pairs_file: str = "pairs.csv",
                     method: str = "geoshape", seed: int = 0, backend: str | None = None,
                     n_jobs: int | None = None, scheduler=None, progress: bool = True) -> dict:
    """Write ``out_dir/<source_stem>__<target_stem>.txt`` for every pair, and ``timings.json``.

    Returns a dict with ``written`` (count), ``failed`` (list of dicts with source, target,
    error) and ``timings_file``. Raises :class:`~geoshape.errors.DatasetError` if the pairs
    file itself cannot be read; a bad pair only lands in ``failed``.
    """
    import json

    from geoshape._options import check_choice
    from geoshape.correspondence.mesh_matching import CORRESPONDENCE_METHODS
    from geoshape.io.datasets import mesh_stem, read_pairs
    from geoshape.parallel import run_map

    check_choice("correspondence method", method, CORRESPONDENCE_METHODS)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    pairs = read_pairs(folder, pairs_file, check_files=False)
    tasks = [{"source": str(p.source), "target": str(p.target), "method": method, "seed": seed,
              "out": str(out / f"{mesh_stem(p.source)}__{mesh_stem(p.target)}.txt")} for p in pairs]
    _refuse_colliding_names(tasks, pairs_file)
    # chunks of consecutive pairs share meshes in a worker's cache
    chunksize = max(1, len(tasks) // (4 * (n_jobs or os.cpu_count() or 1)))
    results = run_map(_one_pair, tasks, backend=backend, n_jobs=n_jobs, scheduler=scheduler,
                      desc="correspond", progress=progress, chunksize=chunksize, on_error="return")
    written, failed, timing_rows = 0, [], []
    for task, res in zip(tasks, results, strict=True):
        if isinstance(res, BaseException):
            failed.append({"source": task["source"], "target": task["target"], "error": repr(res)})
        elif not res["ok"]:
            failed.append({"source": task["source"], "target": task["target"], "error": res["error"]})
        else:
            written += 1
            timing_rows.append({"source": task["source"], "target": task["target"], "map": task["out"],
                                "seconds": res["seconds"], "load_seconds": res["load_seconds"],
                                "stages": res["timings"]})
    timings_file = out / "timings.json"
    write_text_atomic(timings_file, json.dumps({"method": method, "pairs": timing_rows, "failed": failed},
                                               indent=2))
    return {"written": written, "failed": failed, "timings_file": str(timings_file)}
