"""All-pairs dissimilarity matrix of 2D contours (shape retrieval).

Descriptors are computed once per shape (:func:`contour_signature`), then every unordered
pair is matched once; the matrix is symmetric by construction. For the asymmetric
``best``/``proximity`` matchers (the faithful ``gsc``) the distance of a pair is the average
of the matching costs in both directions; ``hungarian`` and ``dp`` are symmetric already.
With ``mirror`` (the ``default`` method) the distance is the smaller of the distances to the
shape and to its mirror image.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

from geoshape.contour.methods import (
    DEFAULT_METHOD,
    contour_signature,
    method_spec,
    pair_costs,
    stack_signatures,
)
from geoshape.parallel import single_thread_blas

__all__ = ["shape_distance_matrix", "contour_signatures", "load_contours"]


def _signature_task(P, spec):
    return contour_signature(P, spec=spec)


def contour_signatures(contours, method: str = DEFAULT_METHOD, *, backend: str | None = None,
                       n_jobs: int | None = None, spec: dict | None = None, **options) -> list:
    """Signatures of many contours (in parallel with ``backend``); see :func:`contour_signature`."""
    from geoshape.parallel import run_map

    spec = spec if spec is not None else method_spec(method, **options)
    contours = list(contours)
    if backend == "serial" or len(contours) < 64:
        return [contour_signature(P, spec=spec, name=f"contour {k}") for k, P in enumerate(contours)]
    return run_map(functools.partial(_signature_task, spec=spec), contours, backend=backend,
                   n_jobs=n_jobs, progress=False)


def _block_costs(sigs_a, sigs_b, spec):
    """Distances of a block ``sigs_a × sigs_b``, ``(len(sigs_a), len(sigs_b))``.

    ``sigs_b`` is stacked once per block. When both are the same signatures (a diagonal
    block of :func:`geoshape.parallel.pairwise_matrix`, which keeps the upper triangle) only
    the pairs above the diagonal are matched; the rest is left at 0.
    """
    out = np.zeros((len(sigs_a), len(sigs_b)))
    same = len(sigs_a) == len(sigs_b) and all(a is b for a, b in zip(sigs_a, sigs_b, strict=True))
    batch = 256
    with single_thread_blas():  # small products: several BLAS threads on busy cores spin
        for c in range(0, len(sigs_b), batch):
            stack = stack_signatures(list(sigs_b[c:c + batch]))
            for r, sig in enumerate(sigs_a):
                first = max(0, r + 1 - c) if same else 0
                if first < len(stack):
                    part = stack if first == 0 else stack.tail(first)
                    out[r, c + first:c + len(stack)] = pair_costs(sig, part, spec)
    return out


def shape_distance_matrix(contours, method: str = DEFAULT_METHOD, *, backend: str | None = None,
                          n_jobs: int | None = None, signatures: list | None = None,
                          progress: bool = False, **options) -> np.ndarray:
    """Symmetric N×N matrix of retrieval distances between closed contours.

    Parameters
    ----------
    contours : sequence of (n, 2) arrays
        Closed counter-clockwise contours, all with the same number of points (the
        matching is batched over stacked descriptors).
    method : str
        A key of :data:`geoshape.contour.methods.CONTOUR_METHODS`.
    backend : {"processes", "serial", "dask"} or None
        How the work is spread (:mod:`geoshape.parallel`); ``None`` = processes on all cores.
    n_jobs : int, optional
        Workers (default: all cores).
    signatures : list, optional
        Precomputed signatures for ``method`` (skips the descriptor stage).
    **options
        Method overrides (``matcher``, ``mirror``, ``skip_cost``, ``n_starts``, ``c1``, ``c2``).

    Returns
    -------
    D : (N, N) float64
        Zero diagonal, ``D[i, j] = D[j, i]`` ≥ 0.

    Notes
    -----
    Time: N descriptor computations plus N(N − 1)/2 matchings, each O(N_pts² K) for the cost
    matrix plus the matcher (O(n_starts · N_pts²) for ``dp``, O(N_pts³) for ``hungarian``).
    Memory: O(N²) for the result, O(256 · N_pts²) per worker for a batch of cost matrices.
    """
    from geoshape.errors import InvalidContourError
    from geoshape.parallel import pairwise_matrix

    spec = method_spec(method, **options)
    if signatures is None:
        contours = list(contours)
        sizes = {len(np.asarray(P)) for P in contours}
        if len(sizes) > 1:
            raise InvalidContourError(
                f"all contours must have the same number of points, got sizes {sorted(sizes)}"
            )
        signatures = contour_signatures(contours, spec=spec, backend=backend, n_jobs=n_jobs)
    n = len(signatures)
    if n == 0:
        return np.zeros((0, 0))
    if backend == "serial" or n < 16:
        D = np.zeros((n, n))
        for i in range(n - 1):
            D[i, i + 1:] = _block_costs([signatures[i]], signatures[i + 1:], spec)[0]
        return D + D.T
    workers = n_jobs or os.cpu_count() or 1
    block = int(np.clip(np.ceil(n / (4 * workers)), 8, 200))
    D = pairwise_matrix(functools.partial(_block_costs, spec=spec), signatures, symmetric=True,
                        vectorized=True, diagonal=0.0, block_size=block, backend=backend,
                        n_jobs=n_jobs, progress=progress, desc="pairs")
    return 0.5 * (D + D.T)


def load_contours(paths, n_points: int = 100) -> list[np.ndarray]:
    """Contours of silhouette image files, in order; the first bad file raises, naming it.

    Raises :class:`geoshape.errors.InvalidImageError` (missing, unreadable, empty image…).
    """
    from geoshape.geometry.contour import contour_from_image

    return [contour_from_image(Path(p), n_points) for p in paths]


def retrieval_on_folder(folder, method: str = DEFAULT_METHOD, *, n_points: int = 100,
                        backend: str | None = None, n_jobs: int | None = None,
                        **options) -> dict:
    """Run 2D retrieval on a folder of silhouettes listed in ``labels.csv``.

    Every image is read before any matching starts; the first missing or unreadable file
    raises (:class:`geoshape.errors.DatasetError` / :class:`~geoshape.errors.InvalidImageError`)
    naming it, so no partial result exists.

    Returns
    -------
    dict
        ``D`` (N, N) in ``labels.csv`` row order, ``files``, ``labels``, ``metrics``
        (:func:`geoshape.metrics.retrieval.retrieval_metrics`), ``seconds`` (wall time of
        the descriptors plus all-pairs matching, image reading excluded), ``method``.
    """
    import time

    from geoshape.io.datasets import read_labels
    from geoshape.metrics.retrieval import retrieval_metrics

    spec = method_spec(method, **options)
    items = read_labels(folder)
    contours = load_contours([it.path for it in items], n_points)
    labels = [it.label for it in items]
    t0 = time.perf_counter()
    sigs = contour_signatures(contours, spec=spec, backend=backend, n_jobs=n_jobs)
    t1 = time.perf_counter()
    D = shape_distance_matrix(None, method, backend=backend, n_jobs=n_jobs, signatures=sigs,
                              **options)
    t2 = time.perf_counter()
    return {
        "method": method,
        "files": [it.path.name for it in items],
        "labels": labels,
        "D": D,
        "metrics": retrieval_metrics(D, labels) if len(set(labels)) < len(labels) else {},
        "seconds": t2 - t0,
        "seconds_descriptors": t1 - t0,
        "seconds_matching": t2 - t1,
    }
