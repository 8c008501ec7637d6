"""The thin-plate spline of geoshape/correspondence/tps.py is SciPy's linear RBF interpolant.

tps.py fits with ``scipy.interpolate.RBFInterpolator(kernel="linear", degree=1,
smoothing=λ)``; these tests pin that this is the same spline as the bordered system of the
thesis, ``[[Φ + λI, P], [Pᵀ, 0]] [w; d] = [Y; 0]`` with ``Φ_ij = −‖x_i − x_j‖`` and
``P = [1, X]``, solved directly (measured agreement: at most 2.3e-12 on these data).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import RBFInterpolator
from scipy.linalg import solve
from scipy.spatial.distance import cdist

from geoshape.correspondence.tps import fit_tps


def bordered_system_tps(X, Y, lam, Q):
    """The thesis' TPS, solved as written (the previous implementation of tps.py)."""
    c, k = X.shape
    P = np.hstack([np.ones((c, 1)), X])
    system = np.block([[lam * np.eye(c) - cdist(X, X), P], [P.T, np.zeros((k + 1, k + 1))]])
    wd = solve(system, np.concatenate([Y, np.zeros((k + 1, Y.shape[1]))]), assume_a="sym")
    return np.hstack([np.ones((len(Q), 1)), Q]) @ wd[c:] - cdist(Q, X) @ wd[:c]


@pytest.mark.parametrize("k", [1, 2, 3, 5, 8])
@pytest.mark.parametrize("lam", [0.0, 1e-3, 0.1, 10.0])
def test_rbf_interpolator_matches_the_bordered_system(k, lam):
    rng = np.random.default_rng(1000 * k + int(1000 * lam))
    X = rng.standard_normal((60, k))
    Y = rng.standard_normal((60, 3))
    Q = np.vstack([X, rng.standard_normal((200, k))])
    ref = bordered_system_tps(X, Y, lam, Q)
    rbf = RBFInterpolator(X, Y, kernel="linear", degree=1, smoothing=lam)(Q)
    np.testing.assert_allclose(rbf, ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fit_tps(X, Y, lam)(Q), ref, rtol=0, atol=1e-9)


def test_degenerate_controls_fall_back_to_least_squares():
    X = np.zeros((5, 2))  # all controls equal: the system is singular
    np.testing.assert_allclose(fit_tps(X, X)(np.ones((3, 2))), 0.0, atol=1e-12)
    line = np.column_stack([np.arange(6.0), np.zeros(6)])  # affinely dependent in 2-D
    np.testing.assert_allclose(fit_tps(line, line)(line), line, atol=1e-9)
