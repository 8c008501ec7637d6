"""Retrieval scores from an N × N dissimilarity matrix and class labels.

Conventions
-----------
- Row ``i`` of ``D`` ranks every item for query ``i`` (smaller is more similar); the
  matrix need not be symmetric and its diagonal is ignored.
- Ranking is deterministic: a stable sort, so equal dissimilarities keep index order.
- "Query excluded" (Kimia top-k, Princeton Shape Benchmark scores, mAP, precision–recall):
  the query is removed from its own ranked list, whatever ``D[i, i]`` holds.
- "Query included" (MPEG-7 bull's-eye): the query is counted as its own first hit.
- For the Princeton-style scores a query whose class has no other member has nothing to
  retrieve; such queries are left out of those averages (a warning says how many).

All functions cost ``O(N^2 log N)`` time (one sort per row) and ``O(N^2)`` memory.
"""

from __future__ import annotations

import warnings

import numpy as np

from geoshape.errors import InvalidOptionError

__all__ = [
    "ranked_relevance",
    "top_k_counts",
    "bulls_eye",
    "nearest_neighbor",
    "first_tier",
    "first_tier_by_class",
    "second_tier",
    "e_measure",
    "dcg",
    "mean_average_precision",
    "precision_recall_curve",
    "rank_recall",
    "retrieval_metrics",
]


def _check_matrix(D) -> np.ndarray:
    """``D`` as a float (N, N) array, N ≥ 2, finite off the diagonal; else InvalidOptionError."""
    try:
        D = np.asarray(D, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidOptionError(f"dissimilarity matrix is not numeric: {exc}") from None
    if D.ndim != 2 or D.shape[0] != D.shape[1]:
        raise InvalidOptionError(f"dissimilarity matrix must be square (N, N), got {D.shape}")
    if D.shape[0] < 2:
        raise InvalidOptionError(f"dissimilarity matrix needs at least 2 items, got {D.shape}")
    off = ~np.eye(D.shape[0], dtype=bool)
    bad = ~np.isfinite(D) & off
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InvalidOptionError(
            f"dissimilarity matrix has {int(bad.sum())} NaN or infinite off-diagonal entries "
            f"(first: D[{i}, {j}] = {D[i, j]})"
        )
    return D


def _check_inputs(D, labels) -> tuple[np.ndarray, np.ndarray]:
    D = _check_matrix(D)
    labels = np.asarray(labels)
    if labels.ndim != 1 or labels.shape[0] != D.shape[0]:
        raise InvalidOptionError(
            f"labels must be a 1-D array with one label per row of D ({D.shape[0]}), "
            f"got shape {labels.shape}"
        )
    return D, labels


def _ranked_order(D: np.ndarray) -> np.ndarray:
    """``(N, N − 1)``: each row's other items by increasing dissimilarity, the query excluded,
    ties by index (a stable sort of each row). O(N² log N)."""
    n = D.shape[0]
    Dq = D.copy()
    np.fill_diagonal(Dq, np.inf)  # the query sorts last, then is cut off
    return np.argsort(Dq, axis=1, kind="stable")[:, : n - 1]


def ranked_relevance(D, labels) -> tuple[np.ndarray, np.ndarray]:
    """Relevance of each query's ranked list, the query excluded.

    Parameters
    ----------
    D : (N, N) array_like of float
        Dissimilarities; row ``i`` ranks the items for query ``i``.
    labels : (N,) array_like
        Class of each item (any comparable values).

    Returns
    -------
    rel : (N, N - 1) bool
        ``rel[i, r]`` is True when the item at rank ``r + 1`` for query ``i`` has the
        query's class.
    n_relevant : (N,) int64
        Number of other items of the query's class (class size minus one).

    Raises
    ------
    InvalidOptionError
        ``D`` not square, NaN/inf off the diagonal, or a label count that differs from N.

    Notes
    -----
    Time ``O(N^2 log N)`` (stable sort of each row), memory ``O(N^2)``.
    """
    D, labels = _check_inputs(D, labels)
    order = _ranked_order(D)
    rel = labels[order] == labels[:, None]
    _, inverse, counts = np.unique(labels, return_inverse=True, return_counts=True)
    n_relevant = (counts[inverse] - 1).astype(np.int64)
    return rel, n_relevant


def top_k_counts(D, labels, max_rank: int = 10) -> np.ndarray:
    """Kimia-style counts: for each rank r, queries whose r-th neighbour shares their class.

    Parameters
    ----------
    D : (N, N) array_like of float
    labels : (N,) array_like
    max_rank : int
        Ranks 1..``max_rank`` (10 on Kimia-99, whose best total is 99 · 10 = 990).

    Returns
    -------
    counts : (max_rank,) int64
        ``counts[r - 1]`` = number of queries whose r-th nearest neighbour (query
        excluded) has the query's class. Their sum is the usual "total".

    Examples
    --------
    >>> D = [[0, 1, 5, 6], [1, 0, 6, 5], [5, 6, 0, 1], [6, 5, 1, 0]]
    >>> top_k_counts(D, ["a", "a", "b", "b"], max_rank=3).tolist()
    [4, 0, 0]
    """
    rel, _ = ranked_relevance(D, labels)
    if not isinstance(max_rank, (int, np.integer)) or not 1 <= max_rank <= rel.shape[1]:
        raise InvalidOptionError(
            f"max_rank must be an integer in [1, {rel.shape[1]}]; got {max_rank!r}"
        )
    return rel[:, :max_rank].sum(axis=0).astype(np.int64)


def bulls_eye(D, labels) -> float:
    """MPEG-7 bull's-eye score, in percent.

    For each query of class size C, the share of its class found among the 2C nearest
    items, the query itself counted as the first; averaged over queries and × 100.

    Returns
    -------
    float
        In [0, 100]; 100 when every class is retrieved first.
    """
    rel, n_rel = ranked_relevance(D, labels)
    class_size = n_rel + 1
    hits = np.empty(rel.shape[0], dtype=np.float64)
    cum = np.cumsum(rel, axis=1)
    for i, c in enumerate(class_size):
        depth = min(2 * c - 1, rel.shape[1])  # 2C places, one taken by the query
        hits[i] = 1 + cum[i, depth - 1]
    return float(100.0 * np.mean(hits / class_size))


def _psb_rows(rel: np.ndarray, n_rel: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    keep = n_rel > 0
    if not keep.all():
        warnings.warn(
            f"{what}: {int((~keep).sum())} queries have no other item of their class "
            "and are left out of the average",
            stacklevel=3,
        )
    if not keep.any():
        raise InvalidOptionError(f"{what}: no class has two or more items")
    return rel[keep], n_rel[keep]


def _tier(rel, n_rel, k: int) -> float:
    cum = np.cumsum(rel, axis=1)
    depth = np.minimum(k * n_rel, rel.shape[1])
    return float(np.mean(cum[np.arange(len(n_rel)), depth - 1] / n_rel))


def nearest_neighbor(D, labels) -> float:
    """Share of queries whose nearest neighbour (query excluded) shares their class."""
    rel, n_rel = _psb_rows(*ranked_relevance(D, labels), "nearest neighbour")
    return float(rel[:, 0].mean())


def first_tier(D, labels) -> float:
    """Mean recall within the first C − 1 results (C = class size, query excluded)."""
    rel, n_rel = _psb_rows(*ranked_relevance(D, labels), "first tier")
    return _tier(rel, n_rel, 1)


def first_tier_by_class(D, labels) -> dict:
    """First tier averaged over the queries of each class: ``{label: FT}`` (classes of
    one item are left out). Shows which classes a descriptor confuses."""
    rel, n_rel = ranked_relevance(D, labels)
    labels = np.asarray(labels)
    cum = np.cumsum(rel, axis=1)
    out = {}
    for label in sorted(set(labels.tolist())):
        rows = np.flatnonzero((labels == label) & (n_rel > 0))
        if len(rows):
            out[label] = float(np.mean(cum[rows, n_rel[rows] - 1] / n_rel[rows]))
    return out


def second_tier(D, labels) -> float:
    """Mean recall within the first 2 (C − 1) results (query excluded)."""
    rel, n_rel = _psb_rows(*ranked_relevance(D, labels), "second tier")
    return _tier(rel, n_rel, 2)


def _e_measure(rel, n_rel, depth: int) -> float:
    depth = min(depth, rel.shape[1])
    found = rel[:, :depth].sum(axis=1)
    p = found / depth
    r = found / n_rel
    with np.errstate(invalid="ignore", divide="ignore"):
        e = np.where(found > 0, 2 * p * r / (p + r), 0.0)
    return float(e.mean())


def e_measure(D, labels, depth: int = 32) -> float:
    """Princeton E-measure: mean F1 of precision and recall over the first ``depth`` results.

    ``E = 2 P R / (P + R)`` with ``P = found / depth`` and ``R = found / (C − 1)``;
    ``depth`` is 32 in the Princeton Shape Benchmark (clipped to N − 1).
    """
    rel, n_rel = _psb_rows(*ranked_relevance(D, labels), "E-measure")
    return _e_measure(rel, n_rel, depth)


def _dcg(rel, n_rel) -> float:
    m = rel.shape[1]
    disc = np.ones(m)
    disc[1:] = 1.0 / np.log2(np.arange(2, m + 1))  # rank 1 undiscounted, rank i: 1/log2 i
    gains = rel @ disc
    ideal = np.cumsum(disc)[n_rel - 1]
    return float(np.mean(gains / ideal))


def dcg(D, labels) -> float:
    """Normalised discounted cumulative gain (Princeton definition), in [0, 1].

    ``DCG = G_1 + sum_{i >= 2} G_i / log2(i)`` over the whole ranked list (query
    excluded), divided by its value for a perfect ranking of the C − 1 relevant items.
    """
    rel, n_rel = _psb_rows(*ranked_relevance(D, labels), "DCG")
    return _dcg(rel, n_rel)


def _average_precision(rel, n_rel) -> np.ndarray:
    ranks = np.arange(1, rel.shape[1] + 1)
    prec = np.cumsum(rel, axis=1) / ranks
    return (prec * rel).sum(axis=1) / n_rel


def mean_average_precision(D, labels) -> float:
    """Mean over queries of the average precision at the rank of each relevant item."""
    rel, n_rel = _psb_rows(*ranked_relevance(D, labels), "mAP")
    return float(_average_precision(rel, n_rel).mean())


def _pr_curve(rel, n_rel, recall_levels) -> np.ndarray:
    ranks = np.arange(1, rel.shape[1] + 1)
    cum = np.cumsum(rel, axis=1)
    prec = cum / ranks
    recall = cum / n_rel[:, None]
    # interpolated precision: best precision at any recall >= level
    best_after = np.maximum.accumulate(prec[:, ::-1], axis=1)[:, ::-1]
    out = np.zeros(len(recall_levels))
    for k, level in enumerate(recall_levels):
        idx = (recall >= level - 1e-12).argmax(axis=1)  # recall reaches 1 at the end
        out[k] = best_after[np.arange(len(idx)), idx].mean()
    return out


def precision_recall_curve(D, labels, recall_levels=None) -> tuple[np.ndarray, np.ndarray]:
    """Interpolated precision at fixed recall levels, averaged over queries.

    Parameters
    ----------
    recall_levels : (L,) array_like or None
        Default ``0, 0.1, …, 1`` (the 11-point curve).

    Returns
    -------
    recall : (L,) float64
    precision : (L,) float64
        For each query the largest precision reached at a recall ≥ the level, averaged.
    """
    rel, n_rel = _psb_rows(*ranked_relevance(D, labels), "precision-recall")
    levels = np.linspace(0, 1, 11) if recall_levels is None else np.asarray(recall_levels, float)
    if levels.ndim != 1 or not np.all((levels >= 0) & (levels <= 1)):
        raise InvalidOptionError(f"recall_levels must be a 1-D array in [0, 1], got {levels!r}")
    return levels, _pr_curve(rel, n_rel, levels)


def rank_recall(D, kept, depths=(10, 20, 40)) -> dict:
    """How much of each query's first ranks a subset of pairs keeps (no labels: the ranks of
    ``D`` are the truth, e.g. an exact matrix against the pairs an approximate search refines).

    Parameters
    ----------
    D : (N, N) array_like of float
        The reference dissimilarities; row ``i`` ranks every other item for query ``i``
        (query excluded, ties by index as everywhere here).
    kept : (N, N) array_like of bool
        ``kept[i, j]``: the pair is kept for query ``i``.
    depths : sequence of int
        Each ≥ 1; a depth beyond N − 1 counts all N − 1 others.

    Returns
    -------
    dict
        ``{t: (N,) float64}``: for each depth ``t`` the share of query ``i``'s first ``t``
        ranks ``j`` with ``kept[i, j]``. One sort per row, O(N² log N).

    Examples
    --------
    >>> D = [[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]]
    >>> kept = [[0, 1, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0], [0, 0, 0, 0]]
    >>> rank_recall(D, kept, depths=(2,))[2].tolist()
    [0.5, 0.5, 0.0, 0.0]
    """
    D = _check_matrix(D)
    n = D.shape[0]
    kept = np.asarray(kept)
    if kept.shape != D.shape or not (kept.dtype == bool or np.isin(kept, (0, 1)).all()):
        raise InvalidOptionError(f"kept must be an (N, N) = {D.shape} mask of booleans, got shape "
                                 f"{kept.shape} and dtype {kept.dtype}")
    depths = tuple(depths)
    bad = [t for t in depths if not isinstance(t, (int, np.integer)) or t < 1]
    if not depths or bad:
        raise InvalidOptionError(f"depths must be integers >= 1, got {depths!r}")
    order = _ranked_order(D)[:, :max(depths)]
    first = kept.astype(bool)[np.arange(n)[:, None], order]
    return {t: first[:, :t].mean(axis=1) for t in depths}


def retrieval_metrics(D, labels, max_rank: int = 10, e_depth: int = 32) -> dict:
    """Every retrieval score of this module in one JSON-friendly dict.

    Parameters
    ----------
    D : (N, N) array_like of float
    labels : (N,) array_like
    max_rank : int
        Ranks of the Kimia top-k counts (clipped to N − 1).
    e_depth : int
        Depth of the E-measure.

    Returns
    -------
    dict
        ``n``, ``n_classes``, ``top_k_counts`` (list), ``top_k_total``, ``top_k_max``
        (= N · max_rank, e.g. 990 on Kimia-99), ``bulls_eye`` (percent),
        ``nearest_neighbor``, ``first_tier``, ``second_tier``, ``e_measure``, ``dcg``,
        ``map``, ``pr_recall`` and ``pr_precision`` (lists); plain Python types only.

    Examples
    --------
    >>> D = [[0, 1, 5, 6], [1, 0, 6, 5], [5, 6, 0, 1], [6, 5, 1, 0]]
    >>> m = retrieval_metrics(D, [0, 0, 1, 1])
    >>> m["nearest_neighbor"], m["bulls_eye"], m["map"]
    (1.0, 100.0, 1.0)
    """
    rel_all, n_rel_all = ranked_relevance(D, labels)
    n = rel_all.shape[0]
    k = int(min(max_rank, n - 1))
    counts = rel_all[:, :k].sum(axis=0)
    rel, n_rel = _psb_rows(rel_all, n_rel_all, "retrieval metrics")
    levels = np.linspace(0, 1, 11)
    return {
        "n": int(n),
        "n_classes": int(len(np.unique(np.asarray(labels)))),
        "top_k_counts": [int(c) for c in counts],
        "top_k_total": int(counts.sum()),
        "top_k_max": int(n * k),
        "bulls_eye": bulls_eye(D, labels),
        "nearest_neighbor": float(rel[:, 0].mean()),
        "first_tier": _tier(rel, n_rel, 1),
        "second_tier": _tier(rel, n_rel, 2),
        "e_measure": _e_measure(rel, n_rel, e_depth),
        "dcg": _dcg(rel, n_rel),
        "map": float(_average_precision(rel, n_rel).mean()),
        "pr_recall": [float(x) for x in levels],
        "pr_precision": [float(x) for x in _pr_curve(rel, n_rel, levels)],
    }
