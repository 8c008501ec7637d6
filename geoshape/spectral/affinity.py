"""Gaussian affinities on geodesic, Euclidean or combined distances (thesis §4.3, §4.4).

``A_ij = exp(-d_ij^2 / (2 sigma^2))``. The width ``sigma`` follows one of the rules of
:data:`SIGMA_RULES`: ``"max"`` (the largest distance — the thesis default, which maps all
distances into [exp(-1/2), 1] and makes the embedding scale-invariant), ``"mean"`` (the
mean distance), or a number ``rho`` meaning ``rho * mean``. With a Nyström block the
max/mean are taken over the sampled ``l x n`` rows (an estimate of the full matrix's).
"""

from __future__ import annotations

import numpy as np

from geoshape._options import check_choice
from geoshape.errors import InvalidOptionError

__all__ = [
    "AFFINITY_KINDS",
    "SIGMA_RULES",
    "parse_sigma",
    "resolve_sigma",
    "gaussian_affinity",
    "distance_rows",
]

AFFINITY_KINDS = ("geodesic", "euclidean", "combined")
SIGMA_RULES = ("max", "mean")
#: Smallest width factor ρ (of the mean distance). Unit-free: at ρ = 1e-6 every off-diagonal
#: affinity is already exp(-10¹²·(d/mean)²) = 0, so the kernel is the identity for any
#: smaller ρ too; below it σ² itself can underflow and the kernel is undefined.
MIN_SIGMA_FACTOR = 1e-6


def parse_sigma(sigma) -> str | float:
    """Normalise a sigma rule: ``"max"``, ``"mean"`` or a positive factor ``rho`` (of the mean).

    Strings holding a number (as given on the command line) become floats.

    >>> parse_sigma("0.5"), parse_sigma("max")
    (0.5, 'max')
    """
    if isinstance(sigma, str):
        try:
            sigma = float(sigma)
        except ValueError:
            return check_choice("sigma", sigma, SIGMA_RULES + ("<positive number rho>",))
    rho = float(sigma)
    if not np.isfinite(rho) or rho < MIN_SIGMA_FACTOR:
        raise InvalidOptionError(
            f"sigma must be 'max', 'mean' or a factor of the mean distance ≥ {MIN_SIGMA_FACTOR:g}, "
            f"got {sigma!r}"
        )
    return rho


def resolve_sigma(D: np.ndarray, sigma="max") -> float:
    """The Gaussian width for distances ``D`` (any shape) under rule ``sigma``.

    Raises
    ------
    InvalidOptionError
        Unknown rule, or all distances zero (no width can be defined).
    """
    rule = parse_sigma(sigma)
    finite = D[np.isfinite(D)]
    if rule == "max":
        value = float(finite.max()) if finite.size else 0.0
    else:
        value = float(finite.mean()) if finite.size else 0.0
        if not isinstance(rule, str):
            value *= rule
    if not value > 0:
        raise InvalidOptionError(
            "cannot set the Gaussian width: all distances are zero (coincident vertices?)"
        )
    return value


def gaussian_affinity(D: np.ndarray, sigma="max", *, out: np.ndarray | None = None,
                      ) -> tuple[np.ndarray, float]:
    """Gaussian affinity of a distance array.

    Parameters
    ----------
    D : (..., n) float
        Distances (an n x n matrix or an l x n block). Infinite distances give 0.
    sigma : "max", "mean" or float
        Width rule; a float ``rho`` means ``rho * mean(D)``.
    out : ndarray, optional
        Where to write (may be ``D`` itself, to save an n x n copy).

    Returns
    -------
    A : ndarray, same shape as ``D``
        Entries in [0, 1], 1 on zero distances.
    sigma : float
        The width used.

    Examples
    --------
    >>> import numpy as np
    >>> A, s = gaussian_affinity(np.array([[0.0, 2.0], [2.0, 0.0]]))
    >>> s, A.round(4).tolist()
    (2.0, [[1.0, 0.6065], [0.6065, 1.0]])
    """
    D = np.asarray(D, dtype=np.float64)
    s = resolve_sigma(D, sigma)
    if out is None:
        out = np.empty_like(D)
    np.multiply(D, D, out=out)
    out *= -1.0 / (2.0 * s * s)
    np.exp(out, out=out)
    return out, s


def distance_rows(V: np.ndarray, rows, kind: str, solver=None, geodesic_rows=None,
                  ) -> np.ndarray:
    """Distances from vertices ``rows`` to all vertices, for affinity kind ``kind``.

    Parameters
    ----------
    V : (n, 3) float
    rows : (r,) int or None
        Source vertices; ``None`` means all (an n x n matrix).
    kind : {"geodesic", "euclidean", "combined"}
        ``combined`` is the uniform average of geodesic and Euclidean distances.
    solver : GeodesicSolver, optional
        Needed for geodesic/combined unless ``geodesic_rows`` is given.
    geodesic_rows : (r, n) float, optional
        Geodesic rows already computed (e.g. by farthest-point sampling); reused.

    Returns
    -------
    D : (r, n) float64
    """
    check_choice("affinity", kind, AFFINITY_KINDS)
    from scipy.spatial.distance import cdist

    X = V if rows is None else V[np.asarray(rows)]
    if kind == "euclidean":
        return cdist(X, V)
    if geodesic_rows is None:
        idx = np.arange(len(V)) if rows is None else np.asarray(rows)
        geodesic_rows = solver.distances(idx)
    if kind == "geodesic":
        return geodesic_rows
    return 0.5 * (geodesic_rows + cdist(X, V))
