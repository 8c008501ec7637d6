"""Descriptors of many mesh files on the parallel runner, and all-pairs 3D retrieval.

:func:`compute_descriptors` loads and describes files on the runner of
:mod:`geoshape.parallel` (local processes by default, Dask with a scheduler); a file that
cannot be read or described yields an error naming it, without stopping the batch. Meshes
already in memory (trimesh, Open3D, pymeshlab, ``(V, F)`` pairs) may stand among the files;
they are named ``mesh <i>`` (their position) in errors.
:func:`retrieval3d_on_folder` is the library side of ``geoshape retrieval3d``.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from geoshape.errors import GeoshapeError, InvalidMeshError
from geoshape.parallel import single_thread_blas

__all__ = ["describe_file", "compute_descriptors", "retrieval3d_matrix",
           "retrieval3d_on_folder", "DEFAULT_RERANK_K"]

#: shortlist size of EVD → CCD re-ranking
DEFAULT_RERANK_K = 20


def describe_file(item) -> tuple[np.ndarray, float]:
    """Load one mesh file and compute one descriptor (the task of the parallel runner).

    Parameters
    ----------
    item : tuple
        ``(path, name, affinity, seed)``; ``path`` may also be ``(label, V, F)``, a mesh
        already in memory (nothing is read; errors start with ``label``). ``name`` may be a
        tuple of descriptor names: they are computed together, sharing one Laplace–Beltrami
        eigen-solve (:func:`geoshape.retrieval.descriptors.compute_descriptor_set`).

    Returns
    -------
    (descriptor, seconds)
        ``seconds``: descriptor computation time, file reading excluded. For a tuple of
        names, both are dicts by name.

    Raises
    ------
    InvalidMeshError
        The file cannot be read, or the descriptor fails on it; the message starts with
        the file name.
    """
    from geoshape.io.mesh_io import load_mesh
    from geoshape.retrieval.descriptors import compute_descriptor, compute_descriptor_set

    path, name, affinity, seed = item
    if isinstance(path, tuple):
        path, V, F = path
    else:
        V, F = load_mesh(path)
    if len(F) == 0:
        raise InvalidMeshError(f"{path}: has no faces (a triangle mesh is needed)")
    t0 = time.perf_counter()
    try:
        if isinstance(name, tuple):
            return compute_descriptor_set(V, F, name, affinity=affinity, seed=seed, check=False)
        with single_thread_blas():
            desc = compute_descriptor(V, F, name, affinity=affinity, seed=seed, check=False)
    except GeoshapeError as exc:
        msg = str(exc)
        raise InvalidMeshError(msg if str(path) in msg else f"{path}: {msg}") from None
    except (ValueError, ArithmeticError, RuntimeError, IndexError) as exc:
        what = "+".join(name) if isinstance(name, tuple) else name
        raise InvalidMeshError(f"{path}: {what} descriptor failed: {type(exc).__name__}: {exc}") from None
    return desc, time.perf_counter() - t0


def compute_descriptors(paths, name: str, *, affinity: str | None = None, seed: int = 0,
                        backend: str | None = None, n_jobs: int | None = None,
                        scheduler=None, progress: bool = True) -> list:
    """Descriptor ``name`` of every mesh file, in order, on the parallel runner.

    Parameters
    ----------
    paths : sequence of path or mesh
        Mesh files, or meshes in memory (trimesh / Open3D / pymeshlab / ``(V, F)``).
    name : str or tuple of str
        Registered descriptor (:data:`geoshape.retrieval.descriptors.MESH_DESCRIPTORS`), or
        several computed together per mesh (one shared Laplace–Beltrami eigen-solve; each
        result is then a pair of dicts by name, see :func:`describe_file`).
    affinity, seed
        See :func:`geoshape.retrieval.descriptors.compute_descriptor`.
    backend, n_jobs, scheduler, progress
        See :func:`geoshape.parallel.run_map`.

    Returns
    -------
    list
        Per file, ``(descriptor, seconds)`` or the exception (a :class:`GeoshapeError`
        naming the file) it raised.
    """
    from geoshape.parallel import run_map
    from geoshape.retrieval.descriptors import descriptor_params

    names = name if isinstance(name, tuple) else (name,)
    for nm in names:  # options checked before any work
        descriptor_params(nm, affinity, seed)
    items = [(_source(p, i), name, affinity, seed) for i, p in enumerate(paths)]
    return run_map(describe_file, items, backend=backend, n_jobs=n_jobs, scheduler=scheduler,
                   desc="+".join(names), progress=progress, on_error="return")


def _source(item, i: int):
    """What :func:`describe_file` takes: a path as text, or ``(label, V, F)`` for a mesh object."""
    from geoshape.io.interop import as_arrays, is_mesh_object

    if is_mesh_object(item):
        label = f"mesh {i}"
        return (label, *as_arrays(item, name=label, allow_no_faces=True, min_vertices=1))
    return str(item)


def _raise_failures(paths, results) -> None:
    bad = [(p, r) for p, r in zip(paths, results, strict=True) if isinstance(r, BaseException)]
    if not bad:
        return
    lines = "; ".join(str(r) if isinstance(r, GeoshapeError) else f"{p}: {type(r).__name__}: {r}"
                      for p, r in bad[:5])
    more = f" (and {len(bad) - 5} more)" if len(bad) > 5 else ""
    raise InvalidMeshError(f"{len(bad)} of {len(paths)} meshes failed: {lines}{more}")


def retrieval3d_matrix(paths, method: str, *, affinity: str | None = None, seed: int = 0,
                       rerank_k: int = DEFAULT_RERANK_K, backend: str | None = None,
                       n_jobs: int | None = None, scheduler=None,
                       progress: bool = True) -> dict:
    """All-pairs dissimilarity matrix of mesh files under a descriptor or re-ranking scheme.

    Parameters
    ----------
    paths : sequence of path or mesh
        As :func:`compute_descriptors`.
    method : str
        One of :data:`geoshape.retrieval.descriptors.RETRIEVAL_METHODS` (a descriptor;
        ``"evd_ccd"``: EVD, then each query's top ``rerank_k`` re-ranked by CCD; ``"fused"``,
        the default (:data:`geoshape.retrieval.descriptors.DEFAULT_RETRIEVAL_METHOD`): its
        components computed together per mesh (one shared Laplace–Beltrami eigen-solve),
        their all-pairs matrices fused by :func:`geoshape.retrieval.fusion.fuse_distances`
        with :data:`geoshape.retrieval.fusion.FUSED_WEIGHTS`).
    affinity, seed, backend, n_jobs, scheduler, progress
        As :func:`compute_descriptors`.

    Returns
    -------
    dict
        ``D`` (N, N), ``seconds_descriptors`` (wall), ``seconds_per_mesh`` (mean
        per-mesh compute time, per descriptor; for a fusion the shared eigen-solve is split
        evenly among the descriptors that read it, so the values sum to the method's cost),
        ``seconds_matrix``, ``seconds``, ``descriptors`` (per name, one per mesh).

    Raises
    ------
    InvalidMeshError
        Any file unreadable or failing — all failures named, nothing returned.
    """
    from geoshape._options import check_choice
    from geoshape.retrieval.descriptors import (
        FUSIONS,
        RERANKERS,
        RETRIEVAL_METHODS,
        descriptor_distance_matrix,
        descriptor_params,
        method_descriptors,
        rerank,
    )

    check_choice("descriptor", method, RETRIEVAL_METHODS)
    names = method_descriptors(method)
    for nm in names:
        descriptor_params(nm, affinity, seed)
    from geoshape.io.interop import is_mesh_object

    paths = [p if is_mesh_object(p) else Path(p) for p in paths]
    t0 = time.perf_counter()
    descs, per_mesh = {}, {}
    if method in FUSIONS:  # one task per mesh: its components share one eigen-solve
        res = compute_descriptors(paths, tuple(names), affinity=affinity, seed=seed, backend=backend,
                                  n_jobs=n_jobs, scheduler=scheduler, progress=progress)
        _raise_failures(paths, res)
        for nm in names:
            descs[nm] = [r[0][nm] for r in res]
            per_mesh[nm] = float(np.mean([r[1][nm] for r in res]))
    for nm in names if method not in FUSIONS else ():
        res = compute_descriptors(paths, nm, affinity=affinity, seed=seed, backend=backend,
                                  n_jobs=n_jobs, scheduler=scheduler, progress=progress)
        _raise_failures(paths, res)
        descs[nm] = [r[0] for r in res]
        per_mesh[nm] = float(np.mean([r[1] for r in res]))
    t1 = time.perf_counter()
    if method in RERANKERS:
        first, second = names
        D0 = descriptor_distance_matrix(first, descs[first])
        D = rerank(D0, descs[second], k=rerank_k, backend=backend, n_jobs=n_jobs,
                   scheduler=scheduler)
    elif method in FUSIONS:
        from geoshape.retrieval.fusion import fuse_distances

        mats = {nm: descriptor_distance_matrix(nm, descs[nm]) for nm in names}
        D = fuse_distances(mats, {nm: FUSIONS[method][nm] for nm in names})
    else:
        D = descriptor_distance_matrix(method, descs[method], backend=backend, n_jobs=n_jobs,
                                       scheduler=scheduler, progress=progress)
    t2 = time.perf_counter()
    return {"D": D, "seconds_descriptors": t1 - t0, "seconds_per_mesh": per_mesh,
            "seconds_matrix": t2 - t1, "seconds": t2 - t0, "descriptors": descs}


def retrieval3d_on_folder(folder: str | os.PathLike, method: str, *, affinity: str | None = None,
                          seed: int = 0, rerank_k: int = DEFAULT_RERANK_K,
                          backend: str | None = None, n_jobs: int | None = None,
                          scheduler=None, progress: bool = True) -> dict:
    """:func:`retrieval3d_matrix` on the meshes of ``folder/labels.csv``, with the scores.

    Returns
    -------
    dict
        As :func:`retrieval3d_matrix` plus ``files`` (relative to ``folder``), ``labels``
        and ``metrics`` (:func:`geoshape.metrics.retrieval.retrieval_metrics`).
    """
    from geoshape.io.datasets import read_labels
    from geoshape.metrics.retrieval import retrieval_metrics

    items = read_labels(folder)
    out = retrieval3d_matrix([it.path for it in items], method, affinity=affinity, seed=seed,
                             rerank_k=rerank_k, backend=backend, n_jobs=n_jobs,
                             scheduler=scheduler, progress=progress)
    labels = [it.label for it in items]
    out["files"] = [str(Path(it.path).relative_to(folder)) for it in items]
    out["labels"] = labels
    out["metrics"] = retrieval_metrics(out["D"], labels) if len(items) >= 2 else {}
    return out
