"""All-pairs dissimilarity matrix of 2D contours (shape retrieval).

Descriptors are computed once per shape (:func:`contour_signature`), then every unordered
pair is matched once; the matrix is symmetric by construction. For the asymmetric
``best``/``proximity`` matchers (the faithful ``gsc``) the distance of a pair is the average
of the matching costs in both directions; ``hungarian`` and ``dp`` are symmetric already.
With ``mirror`` (the ``default`` method) the distance is the smaller of the distances to the
shape and to its mirror image.

Coarse-to-fine search (``search="coarse_to_fine"``; what ``"auto"``, the default, picks for the
cyclic-DP methods on collections of more than ``4 · refine_k`` shapes): matching every pair
exactly is O(N²) expensive matchings, but retrieval only looks at each query's nearest
shapes. So

1. a cheap first pass matches every pair with the same matcher on every ``COARSE_STEP``-th
   contour point (descriptors unchanged: a quarter of the cost matrix, a quarter of each DP)
   in single precision, with at most ``COARSE_STARTS`` DP starts per orientation (about a
   tenth of the exact cost per pair with the default);
2. each query's ``refine_k`` nearest shapes by that pass (the union over rows, so the set is
   symmetric) are matched exactly, with the same arithmetic as ``search="exact"`` (the same
   bits);
3. every other entry is ``offset + coarse`` with ``offset`` just above the largest exact entry
   of the matrix: it ranks after every exact entry of its row, keeps the first pass's order
   among the rest, and the matrix stays symmetric.

So each row's refined entries are the exact distances, ranked exactly; a shape whose exact
distance would place it among a query's first ranks but which the first pass puts below its
``refine_k`` nearest is the approximation's only error. ``refine_k`` was chosen by measuring
that recall (docs/RESULTS.md, "2D coarse-to-fine all-pairs").
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

from geoshape._options import check_choice
from geoshape.contour.methods import (
    DEFAULT_METHOD,
    ContourSignature,
    contour_signature,
    contour_tracing,
    method_spec,
    pair_costs,
    spread_scale,
    stack_signatures,
)
from geoshape.errors import InvalidOptionError
from geoshape.parallel import single_thread_blas

__all__ = ["shape_distance_matrix", "contour_signatures", "load_contours", "nearest_mask",
           "first_pass_matrix", "refined_matrix", "SEARCH_MODES"]

#: How :func:`shape_distance_matrix` searches: every pair exactly, or a cheap first pass and
#: exact matching of each query's nearest; ``auto`` picks (see the module docstring).
SEARCH_MODES = ("auto", "exact", "coarse_to_fine")
#: First pass: every ``COARSE_STEP``-th contour point, at most ``COARSE_STARTS`` DP starts per
#: orientation (the method's own if fewer). Both chosen by the recall of each query's exact
#: first ranks (docs/RESULTS.md, "2D coarse-to-fine all-pairs").
COARSE_STEP = 2
COARSE_STARTS = 4
#: Shapes per query matched exactly after the first pass (chosen by measured recall).
REFINE_K = 150
#: ``search="auto"`` goes coarse-to-fine above this many × ``refine_k`` shapes.
AUTO_COARSE_FACTOR = 4


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
                          progress: bool = False, search: str = "auto", refine_k: int | None = None,
                          **options) -> np.ndarray:
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
    search : {"auto", "exact", "coarse_to_fine"}
        ``exact``: every pair matched exactly. ``coarse_to_fine``: a cheap first pass over
        all pairs, then exact matching of each query's ``refine_k`` nearest (module
        docstring; cyclic-DP methods with the squared-Euclidean cost only). ``auto``:
        ``coarse_to_fine`` for those methods when N > 4 · ``refine_k``, else ``exact``.
    refine_k : int, optional
        Shapes per query matched exactly by ``coarse_to_fine`` (default :data:`REFINE_K`).
    **options
        Method overrides (``matcher``, ``mirror``, ``skip_cost``, ``n_starts``, ``c1``, ``c2``).

    Returns
    -------
    D : (N, N) float64
        Zero diagonal, ``D[i, j] = D[j, i]`` ≥ 0. With ``coarse_to_fine``, the entries not
        matched exactly are larger than every exact one (they rank last in their rows).

    Notes
    -----
    Time (exact): N descriptor computations plus N(N − 1)/2 matchings, each O(N_pts² K) for
    the cost matrix plus the matcher (O(n_starts · N_pts²) for ``dp``, O(N_pts³) for
    ``hungarian``). ``coarse_to_fine``: N(N − 1)/2 first-pass matchings (about a tenth of an
    exact one each with the default) plus at most N · ``refine_k`` exact ones.
    Memory: O(N²) for the result, O(256 · N_pts²) per worker for a batch of cost matrices.
    """
    from geoshape.errors import InvalidContourError

    check_choice("search", search, SEARCH_MODES)
    if refine_k is None:
        refine_k = REFINE_K
    if isinstance(refine_k, bool) or not isinstance(refine_k, (int, np.integer)) or refine_k < 1:
        raise InvalidOptionError(f"refine_k must be an integer ≥ 1, got {refine_k!r}")
    spec = method_spec(method, **options)
    fast = spec["matcher"] == "dp" and spec["metric"] == "sqeuclidean"
    if search == "coarse_to_fine" and not fast:
        raise InvalidOptionError(
            f"search='coarse_to_fine' needs the 'dp' matcher with the 'sqeuclidean' cost; method "
            f"{method!r} uses {spec['matcher']!r} with {spec['metric']!r} (use search='exact')"
        )
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
    if search == "auto":
        search = "coarse_to_fine" if fast and n > AUTO_COARSE_FACTOR * refine_k else "exact"
    if search == "exact" or refine_k >= n - 1:  # every pair would be refined anyway
        return _exact_matrix(signatures, spec, backend, n_jobs, progress)
    return _coarse_to_fine_matrix(signatures, spec, int(refine_k), backend, n_jobs, progress)


def _block_size(n: int, n_jobs: int | None, tasks_per_worker: int, largest: int) -> int:
    workers = n_jobs or os.cpu_count() or 1
    return int(np.clip(np.ceil(n / (tasks_per_worker * workers)), 8, largest))


def _exact_matrix(signatures, spec, backend, n_jobs, progress) -> np.ndarray:
    """Every pair matched exactly (``search="exact"``)."""
    from geoshape.parallel import pairwise_matrix

    n = len(signatures)
    if backend == "serial" or n < 16:
        D = np.zeros((n, n))
        for i in range(n - 1):
            D[i, i + 1:] = _block_costs([signatures[i]], signatures[i + 1:], spec)[0]
        return D + D.T
    D = pairwise_matrix(functools.partial(_block_costs, spec=spec), signatures, symmetric=True,
                        vectorized=True, diagonal=0.0, block_size=_block_size(n, n_jobs, 4, 200),
                        backend=backend, n_jobs=n_jobs, progress=progress, desc="pairs")
    return 0.5 * (D + D.T)


# --- coarse-to-fine ----------------------------------------------------------------------------


def _coarse_item(sig: ContourSignature, step: int) -> tuple[np.ndarray, np.ndarray]:
    """First-pass data of one shape: every ``step``-th point of each orientation's embedding
    in single precision, ``(V, M', K)``, and its squared row norms ``(V, M')``."""
    views = [sig.X] if sig.X_mirror is None else [sig.X, sig.X_mirror]
    XV = np.ascontiguousarray(np.stack([X[::step] for X in views]), dtype=np.float32)
    return XV, (XV.astype(np.float64) ** 2).sum(axis=2)


def _coarse_block(items_a, items_b, skip_cost: float, n_starts: int) -> np.ndarray:
    """First-pass distances of a block (as :func:`_block_costs`: a diagonal block fills only
    its upper triangle). Cyclic DP with ``n_starts`` starts per orientation."""
    from geoshape.contour.matching import cyclic_dp_gram_costs
    from geoshape.contour.methods import _GRAM_CHUNK

    out = np.zeros((len(items_a), len(items_b)))
    same = len(items_a) == len(items_b) and all(a is b for a, b in zip(items_a, items_b, strict=True))
    XV = np.stack([it[0] for it in items_b])  # (B, V, M, K)
    norms = np.stack([it[1] for it in items_b])
    B, V, M, _ = XV.shape
    with single_thread_blas():
        buf = np.empty((min(B, _GRAM_CHUNK), V, M, items_a[0][0].shape[1]), dtype=np.float32)
        for r, (XV1, n1) in enumerate(items_a):
            X1T = np.ascontiguousarray(XV1[0].T)
            for c in range(r + 1 if same else 0, B, _GRAM_CHUNK):
                G = buf[:min(_GRAM_CHUNK, B - c)]
                np.matmul(XV[c:c + len(G)], X1T, out=G)
                out[r, c:c + len(G)] = cyclic_dp_gram_costs(G, n1[0], norms[c:c + len(G)],
                                                            skip_cost=skip_cost,
                                                            n_starts=V * n_starts)
    return out


def _refine_block(items_a, items_b, spec: dict, refine: np.ndarray) -> np.ndarray:
    """Exact distances of the pairs ``i < j`` of a block marked in ``refine (N, N)``; items are
    ``(index, signature)``; the other entries are 0."""
    out = np.zeros((len(items_a), len(items_b)))
    index_b = np.array([j for j, _ in items_b])
    stack = stack_signatures([sig for _, sig in items_b])
    with single_thread_blas():
        for r, (i, sig) in enumerate(items_a):
            cols = np.flatnonzero(refine[i, index_b] & (index_b > i))
            if len(cols):
                out[r, cols] = pair_costs(sig, stack, spec, cols)
    return out


def nearest_mask(A: np.ndarray, k: int) -> np.ndarray:
    """``(N, N)`` bool: ``j`` is among the ``k`` nearest of ``i`` in ``A`` (diagonal excluded,
    ties by index) or ``i`` among those of ``j``. O(N² log N)."""
    n = len(A)
    A = np.array(A, dtype=np.float64)
    np.fill_diagonal(A, np.inf)
    order = np.argsort(A, axis=1, kind="stable")[:, :min(k, n - 1)]
    mask = np.zeros((n, n), dtype=bool)
    mask[np.arange(n)[:, None], order] = True
    return mask | mask.T


def first_pass_matrix(signatures, skip_cost: float, n_starts: int, *, spread_power: float,
                      backend: str | None = None, n_jobs: int | None = None,
                      progress: bool = False) -> np.ndarray:
    """First-pass distances of all pairs, ``(N, N)`` symmetric with a zero diagonal: the cyclic DP
    with ``skip_cost`` and ``n_starts`` starts per orientation on every ``COARSE_STEP``-th point
    of each embedding, in single precision, divided by the pair's
    :func:`~geoshape.contour.methods.spread_scale` with ``spread_power`` (required: the method's,
    as for the exact main term it estimates, so both rank on one scale).
    O(N² · (N_pts/step)² · (K + n_starts))."""
    from geoshape.parallel import pairwise_matrix

    items = [_coarse_item(sig, COARSE_STEP) for sig in signatures]
    coarse = functools.partial(_coarse_block, skip_cost=skip_cost, n_starts=n_starts)
    if backend == "serial":
        A = np.triu(coarse(items, items), 1)
        A = A + A.T
    else:
        A = pairwise_matrix(coarse, items, symmetric=True, vectorized=True, diagonal=0.0,
                            block_size=_block_size(len(items), n_jobs, 4, 400), backend=backend,
                            n_jobs=n_jobs, progress=progress, desc="first pass")
        A = 0.5 * (A + A.T)
    if spread_power:
        spread = np.array([sig.spread for sig in signatures])
        A /= spread_scale(spread[:, None], spread[None, :], spread_power)
    return A


def refined_matrix(exact: np.ndarray, first_pass: np.ndarray, refine: np.ndarray) -> np.ndarray:
    """The coarse-to-fine matrix from its parts: ``exact`` where ``refine`` (bool, symmetric),
    elsewhere ``offset + first_pass`` with ``offset`` just above the largest refined entry (so
    those rank after every refined one, in the first pass's order); zero diagonal."""
    offset = np.nextafter(exact[refine].max(), np.inf) if refine.any() else 0.0
    D = np.where(refine, exact, offset + first_pass)
    np.fill_diagonal(D, 0.0)
    return D


def _coarse_to_fine_matrix(signatures, spec, refine_k, backend, n_jobs, progress) -> np.ndarray:
    """``search="coarse_to_fine"`` (module docstring)."""
    from geoshape.parallel import pairwise_matrix

    opts = spec["matcher_options"]
    A = first_pass_matrix(signatures, opts.get("skip_cost", 0.3),
                          min(opts.get("n_starts", COARSE_STARTS), COARSE_STARTS),
                          spread_power=spec.get("spread_power", 0.0), backend=backend,
                          n_jobs=n_jobs, progress=progress)
    refine = nearest_mask(A, refine_k)
    fine = functools.partial(_refine_block, spec=spec, refine=refine)
    indexed = list(enumerate(signatures))
    if backend == "serial":
        E = fine(indexed, indexed)
    else:
        E = pairwise_matrix(fine, indexed, symmetric=True, vectorized=True, diagonal=0.0,
                            block_size=_block_size(len(indexed), n_jobs, 2, 400), backend=backend,
                            n_jobs=n_jobs, progress=progress, desc="exact pairs")
    E = np.triu(E, 1)
    return refined_matrix(E + E.T, A, refine)


def load_contours(paths, n_points: int = 100, **tracing) -> list[np.ndarray]:
    """Contours of silhouette image files, in order; the first bad file raises, naming it.

    ``tracing``: the tracer's ``part_fraction`` and ``smoothing``
    (:func:`geoshape.geometry.contour.extract_contour`; a method's are
    :func:`~geoshape.contour.methods.contour_tracing`).
    Raises :class:`geoshape.errors.InvalidImageError` (missing, unreadable, empty image…).
    """
    from geoshape.geometry.contour import contour_from_image

    return [contour_from_image(Path(p), n_points, **tracing) for p in paths]


def retrieval_on_folder(folder, method: str = DEFAULT_METHOD, *, n_points: int | None = None,
                        backend: str | None = None, n_jobs: int | None = None,
                        search: str = "auto", **options) -> dict:
    """Run 2D retrieval on a folder of silhouettes listed in ``labels.csv``.

    Every image is read before any matching starts; the first missing or unreadable file
    raises (:class:`geoshape.errors.DatasetError` / :class:`~geoshape.errors.InvalidImageError`)
    naming it, so no partial result exists. Contours are traced as the method says
    (:func:`~geoshape.contour.methods.contour_tracing`; ``n_points`` overrides its point
    count). ``search`` is passed to :func:`shape_distance_matrix`.

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
    contours = load_contours([it.path for it in items], **contour_tracing(method, n_points))
    labels = [it.label for it in items]
    t0 = time.perf_counter()
    sigs = contour_signatures(contours, spec=spec, backend=backend, n_jobs=n_jobs)
    t1 = time.perf_counter()
    D = shape_distance_matrix(None, method, backend=backend, n_jobs=n_jobs, signatures=sigs,
                              search=search, **options)
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
