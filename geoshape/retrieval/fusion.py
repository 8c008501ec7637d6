"""Late fusion of several descriptors' dissimilarity matrices (query-adaptive).

Each descriptor ranks shapes in its own units (χ², L2, LFD, ...), so matrices cannot be
added as they are. :func:`fuse_distances` makes each one unit-free per query (divided by the
query's median distance to the database), weighs each component per query by how sharply it
separates the query's closest few items from the rest (its *gap*), and averages.

:data:`FUSED_WEIGHTS` are the weights chosen by cross-validation over three 3D collections
(``tosca_r5k``, the generated articulated set, ``mixed3d``; ``geoshape bench fusion``); they
define the retrieval method ``fused``, the default of ``geoshape retrieval3d DIR`` (no
``--descriptor``) and of the index.

>>> import numpy as np
>>> x = np.r_[0.0, 0.1, 0.2, 5.0, 5.1, 5.2]
>>> A = np.abs(x[:, None] - x[None, :])
>>> D = fuse_distances({"a": A, "b": 1000 * A}, {"a": 0.5, "b": 0.5})
>>> bool(np.allclose(D, D.T)) and bool(D[0, 1:3].max() < D[0, 3:].min())
True
"""

from __future__ import annotations

import math

import numpy as np

from geoshape.errors import InvalidOptionError

__all__ = ["FUSED_WEIGHTS", "FUSED_K", "GAP_FLOOR", "fuse_distances", "check_weights"]

#: Component weights of the ``fused`` retrieval method: the "grid best on all collections" of
#: ``geoshape bench fusion`` (pool evd_heat, shapedna, lfd, shd, wks on the 1/8 grid, adaptive
#: fusion scored by FT + NN/2 averaged over tosca_r5k, the generated articulated set and
#: mixed3d). ``shd`` got weight 0, so it is not computed. Scores (docs/RESULTS.md, section
#: "3D late fusion", row "fusion, adaptive (library)"): tosca_r5k NN 1.000 FT 0.937, mixed3d
#: NN 0.971 FT 0.780, generated 1.000 / 1.000; the best single descriptors there: tosca_r5k
#: evd_heat 1.000 / 0.959, mixed3d lfd 0.942 / 0.774.
FUSED_WEIGHTS: dict[str, float] = {"evd_heat": 0.25, "shapedna": 0.125, "lfd": 0.25, "wks": 0.375}

#: Nearest items per query whose mean distance defines the gap (a query's closest few).
FUSED_K = 3

#: Smallest gap: a component that does not separate a query's neighbours keeps a
#: negligible (not zero) weight, so the per-query weights never all vanish.
GAP_FLOOR = 1e-3


def check_weights(weights, names=None) -> dict[str, float]:
    """Validated fusion weights: finite, non-negative, not all zero, names among ``names``.

    Raises
    ------
    InvalidOptionError
        Naming the offending component (negative / non-finite / unknown) or saying that
        all weights are zero.
    """
    if not isinstance(weights, dict) or not weights:
        raise InvalidOptionError("fusion weights must be a non-empty dict {component: weight}")
    out = {}
    for name, w in weights.items():
        if names is not None and name not in names:
            listed = ", ".join(repr(n) for n in names)
            raise InvalidOptionError(f"fusion weight for unknown component {name!r}; components: {listed}")
        try:
            w = float(w)
        except (TypeError, ValueError):
            raise InvalidOptionError(f"fusion weight of {name!r} must be a number, got {w!r}") from None
        if not math.isfinite(w):
            raise InvalidOptionError(f"fusion weight of {name!r} must be finite, got {w!r}")
        if w < 0:
            raise InvalidOptionError(f"fusion weight of {name!r} must be non-negative, got {w!r}")
        out[name] = w
    if not sum(out.values()) > 0:
        raise InvalidOptionError("fusion weights are all zero; at least one must be positive")
    return out


def _row_scale(D: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """Per-row median of the database entries (diagonal excluded when ``mask`` is given)."""
    if mask is None:
        med = np.median(D, axis=1)
    else:
        med = np.array([np.median(r[m]) for r, m in zip(D, mask, strict=True)])
    bad = ~(med > 0)
    if np.any(bad):  # degenerate row (most distances 0): its smallest positive entry
        for i in np.flatnonzero(bad):
            pos = D[i][(D[i] > 0) & (mask[i] if mask is not None else True)]
            med[i] = pos.min() if pos.size else 1.0
    return med


def fuse_distances(matrices: dict, weights: dict, *, k: int = FUSED_K, adaptive: bool = True,
                   all_pairs: bool | None = None) -> np.ndarray:
    """Fuse component dissimilarity matrices, query-adaptively.

    For each component ``c`` and query ``q`` (a row):

    1. ``N_c[q] = D_c[q] / median(D_c[q])``: row-normalised distances;
    2. ``gap_c(q) = max(1 − mean of the k smallest N_c[q], GAP_FLOOR)``;
    3. ``W_c(q) = w_c gap_c(q) / Σ_c' w_c' gap_c'(q)`` (``adaptive=False``: ``w_c / Σ w``);
    4. ``D[q] = Σ_c W_c(q) N_c[q]``; for all-pairs input, then ``0.5 (D + Dᵀ)`` with a zero
       diagonal.

    Why these constants (none has units):

    - the **median** of a query's distances is a robust per-query scale: it makes every
      component unit-free and insensitive to a few outliers, so a component scaled by any
      positive constant fuses identically;
    - after that the median distance is 1, so ``1 − mean of the k nearest`` is the fraction of
      the typical distance by which the query's neighbours stand out: a component that sees a
      tight group around the query gets more say for *that* query;
    - **k = 3** looks at a query's closest few items — enough to not trust one lucky match,
      fewer than a class (classes here hold 4–12 items), so it measures the query's own group;
    - the floor ``GAP_FLOOR = 1e-3`` keeps weights defined when every component's neighbours
      are as far as the median (gap ≤ 0).

    Parameters
    ----------
    matrices : dict {name: (Q, M) array}
        Dissimilarities of ``Q`` queries to ``M`` database items, one per component, same
        shape, finite, non-negative.
    weights : dict {name: float}
        One non-negative weight per component (same names as ``matrices``), not all zero;
        they need not sum to 1. Zero-weight components are ignored.
    k : int
        Nearest database items per query for the gap (capped at the database size).
    adaptive : bool
        Per-query weights ``w_c gap_c(q)`` (default); ``False``: fixed weights ``w_c``.
    all_pairs : bool or None
        The queries are the database items themselves (``D[i, i]`` is a shape to itself):
        the diagonal is left out of medians and nearest items, and the output is
        symmetrised with a zero diagonal. Default: ``True`` when ``Q == M``.
        In the general ``(Q, M)`` case medians and nearest items run over all ``M``
        database items of the row and the output is not symmetrised.

    Returns
    -------
    D : (Q, M) float64
        Fused, unit-free dissimilarities (about 1 for a typical pair).

    Raises
    ------
    InvalidOptionError
        Bad weights (negative, non-finite, all zero, names without a matrix or matrices
        without a weight), matrices of different or non-2D shapes, non-finite or negative
        entries, ``k < 1``.

    Notes
    -----
    Time O(C Q M) for C components (medians and the k nearest by partial sorts), memory
    O(Q M) besides the inputs.
    """
    if not isinstance(matrices, dict) or not matrices:
        raise InvalidOptionError("fusion needs a non-empty dict {component: matrix}")
    w = check_weights(weights, list(matrices))
    missing = [n for n in matrices if n not in w]
    if missing:
        raise InvalidOptionError(f"no fusion weight for component(s) {', '.join(map(repr, missing))}")
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or k < 1:
        raise InvalidOptionError(f"fusion k must be a positive integer, got {k!r}")
    mats = {}
    shape = None
    for name, D in matrices.items():
        D = np.asarray(D, dtype=np.float64)
        if D.ndim != 2 or D.size == 0:
            raise InvalidOptionError(f"component {name!r}: need a non-empty 2D matrix, got shape {D.shape}")
        if shape is not None and D.shape != shape:
            raise InvalidOptionError(f"component {name!r} has shape {D.shape}, the others {shape}")
        if not np.all(np.isfinite(D)) or np.any(D < 0):
            raise InvalidOptionError(f"component {name!r}: dissimilarities must be finite and non-negative")
        shape = D.shape
        mats[name] = D
    Q, M = shape
    if all_pairs is None:
        all_pairs = Q == M
    if all_pairs and Q != M:
        raise InvalidOptionError(f"all_pairs needs a square matrix, got shape {shape}")
    mask = ~np.eye(Q, dtype=bool) if all_pairs else None
    n_db = M - 1 if all_pairs else M
    if n_db < 1:
        raise InvalidOptionError("fusion needs at least one database item besides the query")
    kk = min(int(k), n_db)
    used = [n for n in mats if w[n] > 0]
    normed, scores = [], []
    for name in used:
        D = mats[name]
        N = D / _row_scale(D, mask)[:, None]
        normed.append(N)
        if adaptive:
            S = np.where(mask, N, np.inf) if all_pairs else N
            near = np.partition(S, kk - 1, axis=1)[:, :kk] if kk < S.shape[1] else S
            gap = np.maximum(1.0 - near.mean(axis=1), GAP_FLOOR)
        else:
            gap = np.ones(Q)
        scores.append(w[name] * gap)
    W = np.array(scores)
    W /= W.sum(axis=0)
    out = np.zeros(shape)
    for Wc, N in zip(W, normed, strict=True):
        out += Wc[:, None] * N
    if all_pairs:
        out = 0.5 * (out + out.T)
        np.fill_diagonal(out, 0.0)
    return out
