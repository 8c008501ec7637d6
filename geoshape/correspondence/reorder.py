"""Eigenvector reordering and sign correction between two spectral embeddings.

Mesh 1's embedding ``A (n1, k)`` stays fixed; we search the signed permutation ``P`` of
mesh 2's columns (``B' = B[:, perm] * signs``) minimising the best-match cost
``cost = Σ_i min_j ‖A_i − B'_j‖`` (thesis §4.2.5–4.2.6). Three searches:

- ``exhaustive``: all ``k! 2^k`` signed permutations (3840 for k = 5, 46080 for k = 6),
  per permutation one compiled pass over the point pairs for all ``2^k`` sign vectors
  (their signed sums grown as a tree of prefix sums);
- ``greedy``: exhaustive on the first two columns, then each further column of ``A`` takes
  the best remaining column of ``B`` and sign — O(k^2) cost evaluations;
- ``pairwise``: swap consecutive columns on absolute values while the cost drops, then
  fix signs greedily one column at a time (Shapiro–Brady style) — O(f k) evaluations.

Costs are evaluated on at most ``max_points`` farthest-in-embedding samples of each
embedding (a subset preserves the ranking of configurations at a fraction of the cost):
each evaluation is O(s1 s2 k).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError
from geoshape.geometry.sampling import euclidean_farthest_point_sampling

REORDER_METHODS = ("exhaustive", "greedy", "pairwise", "signs", "none")


@dataclass(frozen=True)
class Alignment:
    """A signed permutation of mesh 2's embedding columns and its best-match cost."""

    perm: tuple[int, ...]
    signs: tuple[int, ...]
    cost: float

    def apply(self, B: np.ndarray) -> np.ndarray:
        """``B[:, perm] * signs`` — mesh 2's embedding aligned to mesh 1's columns."""
        return B[:, list(self.perm)] * np.asarray(self.signs, dtype=float)


def best_match_cost(A: np.ndarray, B: np.ndarray) -> float:
    """``Σ_i min_j ‖A_i − B_j‖`` (brute force, O(n1 n2 k))."""
    d2 = (A * A).sum(1)[:, None] + (B * B).sum(1)[None, :] - 2.0 * A @ B.T
    return float(np.sqrt(np.maximum(d2.min(axis=1), 0.0)).sum())


def _exhaustive(A, B, n_keep, beside=False):
    from geoshape.geometry._kernels import signed_match_costs
    from geoshape.parallel import map_beside

    k = A.shape[1]
    sign_table = np.array(list(itertools.product((1.0, -1.0), repeat=k)))
    A = np.ascontiguousarray(A)
    perms = list(itertools.permutations(range(k)))

    def cheapest(perm):  # the n_keep cheapest sign vectors of one column order
        costs = signed_match_costs(A, np.ascontiguousarray(B[:, list(perm)]))
        return [Alignment(tuple(perm), tuple(int(x) for x in sign_table[s]), float(costs[s]))
                for s in np.argsort(costs)[:n_keep]]

    # the first order here: the kernel is compiled (or loaded) before any child needs it
    per_perm = [cheapest(perms[0])]
    per_perm += map_beside(cheapest, perms[1:]) if beside else [cheapest(perm) for perm in perms[1:]]
    results = [a for alignments in per_perm for a in alignments]
    results.sort(key=lambda a: a.cost)
    return results[:n_keep]


def _greedy(A, B, n_keep):
    k = A.shape[1]
    first = []
    for c0, c1 in itertools.permutations(range(k), 2):
        for s0, s1 in itertools.product((1, -1), repeat=2):
            cost = best_match_cost(A[:, :2], B[:, [c0, c1]] * [s0, s1])
            first.append((cost, [c0, c1], [s0, s1]))
    first.sort(key=lambda t: t[0])
    beams = first[: max(n_keep, 2)]
    for col in range(2, k):
        grown = []
        for _, perm, signs in beams:
            for c in (c for c in range(k) if c not in perm):
                for s in (1, -1):
                    p2, s2 = perm + [c], signs + [s]
                    grown.append((best_match_cost(A[:, : col + 1], B[:, p2] * s2), p2, s2))
        grown.sort(key=lambda t: t[0])
        beams = grown[: max(n_keep, 2)]
    return [Alignment(tuple(p), tuple(s), float(c)) for c, p, s in beams[:n_keep]]


def _pairwise(A, B, n_keep, swaps: bool = True):
    k = A.shape[1]
    perm = list(range(k))
    absA = np.abs(A)
    cost = best_match_cost(absA, np.abs(B[:, perm]))
    while swaps:
        best = None
        for c in range(k - 1):
            trial = perm.copy()
            trial[c], trial[c + 1] = trial[c + 1], trial[c]
            t = best_match_cost(absA, np.abs(B[:, trial]))
            if t < cost - 1e-12 and (best is None or t < best[0]):
                best = (t, trial)
        if best is None:
            break
        cost, perm = best
    signs = [1] * k
    for c in range(k):
        costs = []
        for s in (1, -1):
            trial = signs.copy()
            trial[c] = s
            costs.append(best_match_cost(A[:, : c + 1], B[:, perm[: c + 1]] * trial[: c + 1]))
        signs[c] = 1 if costs[0] <= costs[1] else -1
    final = best_match_cost(A, B[:, perm] * signs)
    out = [Alignment(tuple(perm), tuple(signs), final)]
    if n_keep > 1:  # runner-up: the best single sign change of the result
        alts = []
        for c in range(k):
            s2 = signs.copy()
            s2[c] = -s2[c]
            alts.append(Alignment(tuple(perm), tuple(s2), best_match_cost(A, B[:, perm] * s2)))
        out += sorted(alts, key=lambda a: a.cost)[: n_keep - 1]
    return out


def align_embeddings(A, B, method: str = "exhaustive", *, n_keep: int = 2,
                     max_points: int = 200, seed: int = 0, beside: bool = False) -> list[Alignment]:
    """Find the signed column permutations of ``B`` that best match ``A``.

    Parameters
    ----------
    A : (n1, k) float — mesh 1's embedding (fixed)
    B : (n2, k) float — mesh 2's embedding
    method : {"exhaustive", "greedy", "pairwise", "signs", "none"}
        ``signs``: greedy sign correction only, no reordering (Shapiro–Brady);
        ``none`` keeps B's columns and signs as they are.
    n_keep : int
        How many of the best configurations to return (the best and runner-up are
        typically the two mirror-symmetric solutions of a symmetric shape).
    max_points : int
        Cost evaluated on this many farthest-point samples of each embedding.
    beside : bool
        ``exhaustive``: share the column orders with a second core
        (:func:`geoshape.parallel.map_beside`; the same result), worth it for one large
        search, not inside a loop over many small ones.

    Returns
    -------
    list of :class:`Alignment`, best first; costs are on the sampled points.

    Notes
    -----
    Exhaustive time O(k! 2^k s1 s2) with s = min(n, max_points): about a second for
    k = 5 and 300 samples; use ``greedy`` for k >= 7.
    """
    check_choice("reordering method", method, REORDER_METHODS)
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    if A.ndim != 2 or B.ndim != 2 or A.shape[1] != B.shape[1]:
        raise InvalidOptionError(f"embeddings must be (n1, k) and (n2, k), got {A.shape} and {B.shape}")
    k = A.shape[1]
    if k < 1:
        raise InvalidOptionError(f"embeddings must have at least one column, got {A.shape} and {B.shape}")
    if method == "exhaustive" and k > 7:
        raise InvalidOptionError(f"exhaustive reordering of k = {k} columns is intractable; use 'greedy'")
    A_s = A[euclidean_farthest_point_sampling(A, max_points, seed)]
    B_s = B[euclidean_farthest_point_sampling(B, max_points, seed)]
    if method == "none":
        return [Alignment(tuple(range(k)), (1,) * k, best_match_cost(A_s, B_s))]
    if method == "exhaustive":
        return _exhaustive(A_s, B_s, n_keep, beside)
    if method == "greedy":
        return _greedy(A_s, B_s, n_keep)
    return _pairwise(A_s, B_s, n_keep, swaps=method == "pairwise")
