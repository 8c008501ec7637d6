"""The ``heights`` term of a 2D method: height functions in the paper's form (runs scaled to
[−1, 1], weights 1/r), matched on their own by a cyclic DP with city-block costs, divided by
the two shapes' complexities, and added to the method's distance."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import similar, wobbly_contours
from scipy.spatial.distance import cdist

from geoshape.contour.descriptors import height_functions
from geoshape.contour.matching import batch_match_costs, cyclic_dp_l1_costs
from geoshape.contour.methods import (
    _heights_term,
    contour_signature,
    height_costs,
    match_contours,
    method_spec,
    pair_costs,
    stack_signatures,
)
from geoshape.errors import InvalidOptionError
from geoshape.geometry.contour import mirror_contour


@pytest.fixture(scope="module")
def shapes():
    return wobbly_contours()


def _spec(weight=1.0, **options):
    return method_spec("default_144pt", heights=_heights_term(weight, **options))


def test_max_scale_puts_the_run_means_in_unit_range_and_inverse_weights_are_one_over_r(shapes):
    P = shapes[0]
    plain = height_functions(P, n_groups=9, decay=None, scale="max") * np.sqrt(9)
    assert np.isclose(np.abs(plain).max(), 1.0)
    assert np.allclose(height_functions(similar(P), n_groups=9, decay=None, scale="max"),
                       plain / np.sqrt(9), atol=1e-12)
    weighted = height_functions(P, n_groups=9, decay="inverse", scale="max") * np.sqrt(9)
    r = np.array([1, 2, 3, 4, 5, 4, 3, 2, 1])  # the run's rank from the point, either way
    assert np.allclose(weighted, plain / r, atol=1e-12)
    with pytest.raises(InvalidOptionError, match="decay"):
        height_functions(P, decay="harmonic")


def test_l1_dp_costs_are_the_dp_of_city_block_cost_matrices():
    rng = np.random.default_rng(0)
    H1, H2 = rng.random((30, 7)), rng.random((5, 2, 26, 7))
    C = np.stack([np.stack([cdist(H1, H2[b, v], "cityblock") for v in range(2)]) for b in range(5)])
    for starts in (3, 52):  # 52: every start of both variants (the exact cyclic DP)
        expected = batch_match_costs(C, "dp", skip_cost=0.8, n_starts=starts)
        H2T = H2.transpose(0, 1, 3, 2)  # points last
        assert np.allclose(cyclic_dp_l1_costs(H1, H2T, skip_cost=0.8, n_starts=starts), expected,
                           rtol=1e-12, atol=0)


def test_heights_term_is_invariant_to_similarity_start_point_and_mirror(shapes):
    spec = _spec(n_groups=12, step=2)
    P = shapes[0]
    sig = contour_signature(P, spec=spec)
    # shifts by multiples of the step keep the same subsampled points
    copies = [similar(P), np.roll(P, 10, axis=0), np.roll(mirror_contour(similar(P)), 8, axis=0)]
    others = shapes[1:]
    stack = stack_signatures([contour_signature(Q, spec=spec) for Q in copies + others])
    h = height_costs(sig, stack, spec)
    assert np.allclose(h[:3], 0.0, atol=1e-9)
    assert (h[3:] > 1e-3).all()


def test_all_phases_make_the_term_independent_of_the_start_point(shapes):
    """Sampled from one phase, a copy shifted by an odd number of points reads the other half of
    the samples and keeps a residue; matched against every phase of the other shape, it is 0."""
    P = shapes[1]
    copies = [np.roll(P, 1, axis=0), np.roll(similar(P), 7, axis=0),
              np.roll(mirror_contour(P), 5, axis=0)]
    for all_phases, step in ((False, 2), (True, 2), (True, 3)):
        spec = _spec(n_groups=12, step=step, all_phases=all_phases)
        sig = contour_signature(P, spec=spec)
        assert sig.H.shape[0] == (step if all_phases else 1)
        stack = stack_signatures([contour_signature(Q, spec=spec) for Q in copies + shapes[2:]])
        h = height_costs(sig, stack, spec)
        if all_phases:
            assert np.allclose(h[:3], 0.0, atol=1e-9) and (h[3:] > 1e-3).all()
        else:
            assert (h[:3] > 1e-4).all()  # the residue the phases remove


def test_the_term_adds_weight_times_height_costs_to_the_distance(shapes):
    base, spec = method_spec("default_144pt"), _spec(weight=0.5, n_groups=12)
    sig_b = [contour_signature(P, spec=base) for P in shapes]
    sig_h = [contour_signature(P, spec=spec) for P in shapes]
    np.testing.assert_array_equal(sig_b[1].X, sig_h[1].X)
    plain = pair_costs(sig_b[0], sig_b[1:], base)
    stack = stack_signatures(sig_h[1:])
    expected = plain + 0.5 * height_costs(sig_h[0], stack, spec)
    assert np.allclose(pair_costs(sig_h[0], sig_h[1:], spec), expected, rtol=1e-12)
    # only some columns: the same values
    assert np.allclose(pair_costs(sig_h[0], stack, spec, cols=[2, 0]), expected[[2, 0]], rtol=1e-12)
    # match_contours reports the same distance (and the main term's map)
    _, cost = match_contours(shapes[0], shapes[2], method="default_144pt", heights=spec["heights"])
    assert np.isclose(cost, expected[1], rtol=1e-9)


def test_complexity_is_zero_for_a_circle_and_grows_with_detail(shapes):
    t = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    spec = _spec(n_groups=12)
    circle = contour_signature(np.c_[np.cos(t), np.sin(t)], spec=spec)
    assert circle.complexity < 1e-9 < contour_signature(shapes[0], spec=spec).complexity


@pytest.mark.parametrize("bad, match", [
    (dict(weight=-1.0), "weight"), (dict(skip_cost=0.0), "skip_cost"), (dict(n_starts=0), "n_starts"),
    (dict(step=1.5), "step"), (dict(all_phases="yes"), "all_phases"),
])
def test_bad_heights_terms_are_rejected_up_front(bad, match):
    term = dict(_heights_term(1.0), **bad)
    with pytest.raises(InvalidOptionError, match=match):
        method_spec("default", heights=term)
    with pytest.raises(InvalidOptionError, match="keys"):
        method_spec("default", heights=dict(weight=1.0))


def test_variant_modifiers_of_the_heights_term():
    from geoshape.bench.method_variants import parse_variant

    base = dict(_heights_term(0.5))
    _, _, over = parse_variant("default_heights+hweight=0.25+hgroups=11+hskip=0.3")
    term = over["heights"]
    assert term["weight"] == 0.25 and term["skip_cost"] == 0.3
    assert term["descriptor"] == dict(base["descriptor"], n_groups=11)
    assert "all_phases" not in term
    assert parse_variant("default_heights+hphases=1")[2]["heights"]["all_phases"] is True
    for bad in ("default_heights+hcolour=2", "default_heights+hphases=2"):
        with pytest.raises(InvalidOptionError, match="bad modifier"):
            parse_variant(bad)


def test_coarse_to_fine_refines_with_the_whole_distance(shapes):
    """Refined entries of the coarse-to-fine search are the exact distances, heights term
    included (the first pass ranks by the main term alone)."""
    from geoshape.contour.retrieval import shape_distance_matrix

    contours = shapes + [np.roll(1.3 * P, 4, axis=0) for P in shapes]
    spec = _spec(weight=0.5, n_groups=12)
    sigs = [contour_signature(P, spec=spec) for P in contours]
    options = dict(heights=spec["heights"], signatures=sigs, backend="serial")
    exact = shape_distance_matrix(None, "default_144pt", search="exact", **options)
    fine = shape_distance_matrix(None, "default_144pt", search="coarse_to_fine", refine_k=1, **options)
    np.fill_diagonal(fine, np.inf)
    nearest = fine.argmin(axis=1)
    rows = np.arange(len(contours))
    np.testing.assert_array_equal(fine[rows, nearest], exact[rows, nearest])
    np.testing.assert_array_equal(nearest, (rows + len(shapes)) % len(contours))  # its copy
