"""The main term's spread normalisation (``spread_power``): each shape's descriptor spread (known
values, invariances) and the pair's main matching cost divided by their mean spread to a power,
in every path that computes a 2D distance (pairs, coarse-to-fine search, ``match_contours``)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import similar, wobbly_contours

from geoshape.contour import methods
from geoshape.errors import InvalidOptionError


@pytest.fixture(scope="module")
def shapes():
    """Four distinct star-like contours and a similar copy of each (tests.conftest)."""
    stars = wobbly_contours()
    return stars + [np.roll(similar(P, theta=0.4 * k), 7 * k, axis=0) for k, P in enumerate(stars)]


def test_descriptor_spread_is_the_mean_squared_distance_of_all_row_pairs():
    rng = np.random.default_rng(0)
    X = rng.random((30, 5))
    brute = np.mean(((X[:, None] - X[None]) ** 2).sum(axis=2))
    assert methods.descriptor_spread(X) == pytest.approx(brute, rel=1e-12)
    assert methods.descriptor_spread(X[::-1] + 3.0) == pytest.approx(brute, rel=1e-12)  # order, shift
    assert methods.descriptor_spread(np.tile(X[:1], (8, 1))) == pytest.approx(0.0, abs=1e-12)  # alike


def test_a_shape_s_spread_does_not_depend_on_pose_or_start_point(shapes):
    spec = methods.method_spec("default")
    spreads = [methods.contour_signature(P, spec=spec).spread for P in shapes]
    assert np.allclose(spreads[:4], spreads[4:], rtol=1e-3)
    assert all(0 < s < 2 for s in spreads)  # Hellinger-embedded histograms: rows of norm ≤ 1


@pytest.mark.parametrize("power", [0.25, 1.0])
def test_the_main_term_is_divided_by_the_pairs_mean_spread(shapes, power):
    """Without extra terms the distance is the plain one over ((s_i + s_j) / 2) ** power; with
    them only the main term is divided (the terms are added as before)."""
    sigs = [methods.contour_signature(P, spec=methods.method_spec("default_144pt")) for P in shapes]
    s = np.array([sig.spread for sig in sigs])
    plain = methods.pair_costs(sigs[0], sigs[1:], methods.method_spec("default_144pt"))
    spec = methods.method_spec("default_144pt", spread_power=power)
    expected = plain / ((s[0] + s[1:]) / 2) ** power
    assert np.allclose(methods.pair_costs(sigs[0], sigs[1:], spec), expected, rtol=1e-12)
    stack = methods.stack_signatures(sigs[1:])
    assert np.allclose(methods.pair_costs(sigs[0], stack, spec, cols=[3, 1]), expected[[3, 1]], rtol=1e-12)
    assert np.allclose(methods.pair_costs(sigs[0], stack.tail(2), spec), expected[2:], rtol=1e-12)

    full = methods.method_spec("default", spread_power=0.0)
    sigs_full = [methods.contour_signature(P, spec=full) for P in shapes]
    main = methods.pair_costs(sigs_full[0], sigs_full[1:], methods.method_spec("default_144pt"))
    scaled = methods.pair_costs(sigs_full[0], sigs_full[1:], dict(full, spread_power=power))
    terms = methods.pair_costs(sigs_full[0], sigs_full[1:], full) - main
    assert np.allclose(scaled, main / ((s[0] + s[1:]) / 2) ** power + terms, rtol=1e-12)


def test_zero_power_is_the_method_without_normalisation(shapes):
    """``default`` with ``spread_power=0`` computes what ``default_zernike`` (the default
    without it) computes, to the bit; with its own power it does not."""
    spec = methods.method_spec("default")
    assert spec["spread_power"] > 0
    sigs = [methods.contour_signature(P, spec=spec) for P in shapes]
    before = methods.pair_costs(sigs[0], sigs[1:], methods.method_spec("default_zernike"))
    np.testing.assert_array_equal(methods.pair_costs(sigs[0], sigs[1:], dict(spec, spread_power=0)), before)
    assert not np.allclose(methods.pair_costs(sigs[0], sigs[1:], spec), before)


def test_a_signature_without_its_spread_is_refused_and_a_zero_spread_is_floored(shapes):
    import dataclasses

    spec = methods.method_spec("default_144pt", spread_power=0.5)
    sigs = [methods.contour_signature(P, spec=spec) for P in shapes[:3]]
    bare = dataclasses.replace(sigs[0], spread=None)
    with pytest.raises(InvalidOptionError, match="needs each signature's descriptor spread"):
        methods.pair_costs(bare, sigs[1:], spec)
    flat = dataclasses.replace(sigs[1], spread=0.0)  # all of its points alike
    costs = methods.pair_costs(flat, [flat, sigs[2]], spec)
    assert np.isfinite(costs).all() and costs[0] == pytest.approx(0.0, abs=1e-9)
    assert methods.spread_scale(0.0, 0.0, 0.5) == pytest.approx(methods.MIN_SPREAD ** 0.5)


def test_match_contours_reports_the_matrix_entry(shapes):
    from geoshape.contour.retrieval import shape_distance_matrix

    D = shape_distance_matrix(shapes[:3], "default", spread_power=0.5, backend="serial")
    _, cost = methods.match_contours(shapes[0], shapes[2], method="default", spread_power=0.5)
    assert cost == pytest.approx(D[0, 2], rel=1e-9)
    assert D[0, 2] != pytest.approx(shape_distance_matrix(shapes[:3], "default", backend="serial")[0, 2])


def test_coarse_to_fine_ranks_and_refines_with_the_spread(shapes):
    """The first pass is divided by the same scale as the exact main term it estimates, so the
    refined set is chosen on comparable values, and refined entries are the exact distances."""
    from geoshape.contour.retrieval import (
        COARSE_STARTS,
        first_pass_matrix,
        nearest_mask,
        refined_matrix,
        shape_distance_matrix,
    )

    spec = methods.method_spec("default", spread_power=0.25)
    sigs = [methods.contour_signature(P, spec=spec) for P in shapes]
    s = np.array([sig.spread for sig in sigs])
    plain = first_pass_matrix(sigs, 0.3, COARSE_STARTS, spread_power=0.0, backend="serial")
    A = first_pass_matrix(sigs, 0.3, COARSE_STARTS, spread_power=0.25, backend="serial")
    assert np.allclose(A, plain / ((s[:, None] + s[None]) / 2) ** 0.25, rtol=1e-12)
    options = dict(signatures=sigs, backend="serial", spread_power=0.25)
    exact = shape_distance_matrix(None, "default", search="exact", **options)
    fine = shape_distance_matrix(None, "default", search="coarse_to_fine", refine_k=2, **options)
    refine = nearest_mask(A, 2)
    assert refine.sum() < refine.size - len(refine)  # some pairs are left to the first pass
    np.testing.assert_allclose(fine, refined_matrix(exact, A, refine), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan"), "0.25", True])
def test_bad_spread_powers_are_rejected_up_front(bad):
    with pytest.raises(InvalidOptionError, match="spread_power must be a number in"):
        methods.method_spec("default", spread_power=bad)


def test_spread_needs_the_squared_euclidean_cost():
    with pytest.raises(InvalidOptionError, match="spread_power needs the 'sqeuclidean' metric"):
        methods.method_spec("idsc", metric="chi2", spread_power=0.5)


def test_variant_modifier_of_the_spread():
    from geoshape.bench.method_variants import parse_variant

    assert parse_variant("default+spread0.25")[2] == {"spread_power": 0.25}
    for bad in ("default+spread1.5", "default+spread-1", "default+spreadx"):
        with pytest.raises(InvalidOptionError, match=r"bad modifier .*\+spreadX with 0 <= X <= 1"):
            parse_variant(bad)
