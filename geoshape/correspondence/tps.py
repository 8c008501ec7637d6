"""Thin-plate splines in any dimension (thesis Appendix A; Bookstein 1989).

``f(x) = [1, x] d + Σ_j w_j φ(‖x − c_j‖)`` with the kernel ``φ(r) = −r`` (the biharmonic
radial function of 3-D, used by the thesis in every dimension). Given control points
``X`` and targets ``Y`` the coefficients solve

    [[Φ + λ I, P], [Pᵀ, 0]] [w; d] = [Y; 0],   Φ_ij = −‖x_i − x_j‖,  P = [1, X]

``λ = 0`` interpolates the controls; ``λ → ∞`` tends to the least-squares affine map; an
affine ``Y`` is reproduced exactly for every λ. (The kernel ``−r`` is conditionally
positive definite, so the smoothing term enters with a + sign; the thesis writes the
diagonal shift as ``Φ − λI`` with its own sign convention for Φ.)

Cost: fitting O(c^3) for c controls, applying O(n c k).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from geoshape.errors import InvalidOptionError


@dataclass(frozen=True)
class ThinPlateSpline:
    controls: np.ndarray  # (c, k)
    w: np.ndarray  # (c, k_out)
    d: np.ndarray  # (k + 1, k_out)

    def __call__(self, P) -> np.ndarray:
        """Map points ``P (n, k)`` → ``(n, k_out)``."""
        P = np.asarray(P, dtype=np.float64)
        return np.column_stack([np.ones(len(P)), P]) @ self.d - cdist(P, self.controls) @ self.w


def fit_tps(X, Y, lam: float = 0.0) -> ThinPlateSpline:
    """Fit the thin-plate spline taking controls ``X (c, k)`` to ``Y (c, k_out)``.

    Raises InvalidOptionError on mismatched shapes, negative λ or too few controls
    (``c < k + 1``, where the affine part is undetermined).
    """
    from scipy.linalg import LinAlgError, lstsq, solve

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
    P = np.column_stack([np.ones(c), X])
    L = np.zeros((c + k + 1, c + k + 1))
    L[:c, :c] = -cdist(X, X) + lam * np.eye(c)
    L[:c, c:] = P
    L[c:, :c] = P.T
    rhs = np.vstack([Y, np.zeros((k + 1, Y.shape[1]))])
    try:
        sol = solve(L, rhs, assume_a="sym")
    except (LinAlgError, ValueError):  # duplicated controls make L singular
        sol = lstsq(L, rhs)[0]
    # the kernel is -r, so store w for `- cdist @ w`
    return ThinPlateSpline(X, sol[:c], sol[c:])
