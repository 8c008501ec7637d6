"""The one χ² of geoshape/distances.py: single pair, block form, conventions."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.distances import chi2_distance, chi2_distances
from geoshape.errors import InvalidOptionError


def test_chi2_by_hand():
    assert chi2_distance([1.0, 0.0], [3.0, 0.0]) == 0.5  # ½ (1 − 3)² / 4, the empty bin adds 0
    assert chi2_distance([2.0, 1.0], [2.0, 1.0]) == 0.0
    assert chi2_distance([-1.0, 0.0], [3.0, 0.0]) == 0.5  # absolute values
    with pytest.raises(InvalidOptionError, match="shape"):
        chi2_distance([1.0, 2.0], [1.0])


def test_block_form_matches_single_pairs():
    rng = np.random.default_rng(0)
    X = rng.random((7, 20))
    Y = rng.random((5, 20))
    X[0, :4] = 0.0
    Y[1, :4] = 0.0  # bins empty in both
    D = chi2_distances(X, Y)
    assert D.shape == (7, 5) and D.dtype == np.float64
    ref = np.array([[chi2_distance(x, y) for y in Y] for x in X])
    np.testing.assert_allclose(D, ref, rtol=1e-14)
    np.testing.assert_allclose(chi2_distances(-X, Y), D, rtol=0)  # absolute values by default
    assert np.all(chi2_distances(X, X).diagonal() == 0.0)
    # single precision for histograms: the same up to ~1e-7
    D32 = chi2_distances(X, Y, absolute=False, dtype=np.float32)
    assert D32.dtype == np.float64
    np.testing.assert_allclose(D32, D, rtol=1e-5)
    assert chi2_distances(np.zeros((0, 20)), Y).shape == (0, 5)
    assert chi2_distances(X, np.zeros((0, 20))).shape == (7, 0)


def test_chunking_does_not_change_the_numbers(monkeypatch):
    import geoshape.distances as dist

    rng = np.random.default_rng(1)
    X, Y = rng.random((9, 13)), rng.random((11, 13))
    whole = chi2_distances(X, Y)
    monkeypatch.setattr(dist, "_CHI2_BLOCK", 1)  # one row per chunk
    np.testing.assert_array_equal(dist.chi2_distances(X, Y), whole)
