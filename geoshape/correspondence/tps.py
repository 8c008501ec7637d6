"""Thin-plate splines in any dimension (thesis Appendix A; Bookstein 1989).

``f(x) = [1, x] d + Σ_j w_j φ(‖x − c_j‖)`` with the kernel ``φ(r) = −r`` (the biharmonic
radial function of 3-D, used by the thesis in every dimension). Given control points
``X`` and targets ``Y`` the coefficients solve

    [[Φ + λ I, P], [Pᵀ, 0]] [w; d] = [Y; 0],   Φ_ij = −‖x_i − x_j‖,  P = [1, X]

``λ = 0`` interpolates the controls; ``λ → ∞`` tends to the least-squares affine map; an
affine ``Y`` is reproduced exactly for every λ. (The kernel ``−r`` is conditionally
positive definite, so the smoothing term enters with a + sign; the thesis writes the
diagonal shift as ``Φ − λI`` with its own sign convention for Φ.)

This is SciPy's ``RBFInterpolator(kernel="linear", degree=1, smoothing=λ)``, which solves
the same system (with the polynomial columns shifted and scaled for conditioning; the two
agree to about 1e-12, see tests/test_tps.py). Only when that system is exactly singular
(degenerate controls) is it solved here, in the least-squares sense.

Cost: fitting O(c^3) for c controls, applying O(n c k).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from geoshape.errors import InvalidOptionError


@dataclass(frozen=True)
class ThinPlateSpline:
    """A fitted spline: ``tps(P)`` maps points ``P (n, k)`` to ``(n, k_out)``."""

    controls: np.ndarray  # (c, k)
    interpolant: Callable[[np.ndarray], np.ndarray]

    def __call__(self, P) -> np.ndarray:
        """Map points ``P (n, k)`` → ``(n, k_out)``."""
        return self.interpolant(np.asarray(P, dtype=np.float64))


def fit_tps(X, Y, lam: float = 0.0) -> ThinPlateSpline:
    """Fit the thin-plate spline taking controls ``X (c, k)`` to ``Y (c, k_out)``.

    Raises InvalidOptionError on mismatched shapes, negative λ or too few controls
    (``c < k + 1``, where the affine part is undetermined).
    """
    from scipy.interpolate import RBFInterpolator
    from scipy.linalg import LinAlgError

    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    if X.ndim != 2 or Y.ndim != 2 or len(X) != len(Y):
        raise InvalidOptionError(
            f"TPS needs X (c, k) and Y (c, k_out) with equal c, got {X.shape}, {Y.shape}"
        )
    if lam < 0:
        raise InvalidOptionError(f"TPS regularisation must be >= 0, got {lam}")
    c, k = X.shape
    if c < k + 1:
        raise InvalidOptionError(f"TPS in {k}-D needs at least {k + 1} control points, got {c}")
    try:
        f = RBFInterpolator(X, Y, kernel="linear", degree=1, smoothing=lam)
    except LinAlgError:  # degenerate controls (e.g. affinely dependent) make it singular
        f = _least_squares_tps(X, Y, lam)
    return ThinPlateSpline(X, f)


def _least_squares_tps(X: np.ndarray, Y: np.ndarray, lam: float):
    """The minimum-norm least-squares solution of the (singular) TPS system, as a map."""
    from scipy.linalg import lstsq

    c, k = X.shape
    P = np.column_stack([np.ones(c), X])
    L = np.zeros((c + k + 1, c + k + 1))
    L[:c, :c] = -cdist(X, X) + lam * np.eye(c)
    L[:c, c:] = P
    L[c:, :c] = P.T
    sol = lstsq(L, np.vstack([Y, np.zeros((k + 1, Y.shape[1]))]))[0]
    return functools.partial(_apply_tps, X, sol[:c], sol[c:])


def _apply_tps(controls: np.ndarray, w: np.ndarray, d: np.ndarray, P: np.ndarray) -> np.ndarray:
    # the kernel is -r: f(P) = [1, P] d - cdist(P, controls) w
    return np.column_stack([np.ones(len(P)), P]) @ d - cdist(P, controls) @ w
