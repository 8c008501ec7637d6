"""The ``region`` term of a 2D method: Zernike moment magnitudes of the region a contour
encloses (known values on a disc, invariances, errors), added per pair as a weighted
city-block distance."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import similar, wobbly_contours

from geoshape.contour import methods
from geoshape.contour.descriptors import zernike_magnitudes
from geoshape.errors import InvalidContourError, InvalidOptionError
from geoshape.geometry.contour import mirror_contour, polygon_centroid, resample_contour


@pytest.fixture(scope="module")
def shapes():
    """Four distinct star-like contours (tests.conftest)."""
    return wobbly_contours()


def test_polygon_centroid_is_the_region_s_not_the_vertices():
    # a square sampled densely on one side: the vertex mean moves, the region's centroid does not
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    dense = np.vstack([np.c_[np.linspace(0, 2, 40, endpoint=False), np.zeros(40)], square[1:]])
    assert np.allclose(polygon_centroid(dense), [1.0, 1.0])
    assert not np.allclose(dense.mean(axis=0), [1.0, 1.0])
    assert np.allclose(polygon_centroid(dense[::-1]), [1.0, 1.0])  # either orientation


def test_a_disc_has_the_radial_moments_of_theory_and_no_angular_ones():
    """A disc of radius a in the unit disc: Z_nm = 0 for m ≠ 0 and the mean of R_n0 over the
    disc for m = 0 — for a = 1/2 (radius 2): R_20 = 2ρ² − 1 gives a² − 1 = −0.75, R_40 =
    6ρ⁴ − 6ρ² + 1 gives 2a⁴ − 3a² + 1 = 0.375."""
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    Z = zernike_magnitudes(np.c_[np.cos(t), np.sin(t)], order=4, radius=2.0, grid=256)
    nm = [(2, 0), (2, 2), (3, 1), (3, 3), (4, 0), (4, 2), (4, 4)]
    assert len(Z) == len(nm)
    expected = {(2, 0): 0.75, (4, 0): 0.375}
    for (n, m), z in zip(nm, Z, strict=True):
        assert z == pytest.approx(expected.get((n, m), 0.0), abs=0.01), (n, m)


def test_magnitudes_are_invariant_to_similarity_start_point_sampling_and_mirror(shapes):
    P = shapes[0]
    Z = zernike_magnitudes(P)
    assert Z.shape == (23,) and zernike_magnitudes(P, order=12).shape == (47,)
    for copy in (similar(P), np.roll(P, 17, axis=0), mirror_contour(similar(P, theta=2.0)),
                 resample_contour(P, 300), P[::-1]):
        assert np.abs(zernike_magnitudes(copy) - Z).sum() < 0.02
    others = [np.abs(zernike_magnitudes(Q) - Z).sum() for Q in shapes[1:]]
    assert min(others) > 0.1  # different shapes are far apart


@pytest.mark.parametrize("bad, match", [
    (dict(order=1), "order"), (dict(order=2.5), "order"), (dict(radius=0.0), "radius"),
    (dict(grid=8), "grid"),
])
def test_bad_descriptor_options_are_rejected(shapes, bad, match):
    with pytest.raises(InvalidOptionError, match=match):
        zernike_magnitudes(shapes[0], **bad)


def test_a_degenerate_contour_is_rejected_by_name():
    with pytest.raises(InvalidContourError, match="contour"):
        zernike_magnitudes(np.zeros((10, 2)))


def test_the_term_adds_weight_times_the_city_block_distance(shapes):
    base = methods.method_spec("default_phases")
    spec = methods.method_spec("default_phases", region=methods._region_term(0.5, order=6))
    sig_b = [methods.contour_signature(P, spec=base) for P in shapes]
    sig_r = [methods.contour_signature(P, spec=spec) for P in shapes]
    np.testing.assert_array_equal(sig_b[1].X, sig_r[1].X)
    assert sig_b[0].Z is None and sig_r[0].Z.shape == (14,)
    Z = np.array([zernike_magnitudes(P, order=6) for P in shapes])
    expected = methods.pair_costs(sig_b[0], sig_b[1:], base) + 0.5 * np.abs(Z[1:] - Z[0]).sum(axis=1)
    assert np.allclose(methods.pair_costs(sig_r[0], sig_r[1:], spec), expected, rtol=1e-12)
    stack = methods.stack_signatures(sig_r[1:])
    assert np.allclose(methods.pair_costs(sig_r[0], stack, spec, cols=[2, 0]), expected[[2, 0]], rtol=1e-12)
    assert np.allclose(methods.pair_costs(sig_r[0], stack.tail(1), spec), expected[1:], rtol=1e-12)
    # match_contours reports the same distance (and the main term's map)
    _, cost = methods.match_contours(shapes[0], shapes[2], method="default_phases", region=spec["region"])
    assert np.isclose(cost, expected[1], rtol=1e-9)


def test_coarse_to_fine_refines_with_the_region_term(shapes):
    from geoshape.contour.retrieval import (
        COARSE_STARTS,
        first_pass_matrix,
        nearest_mask,
        shape_distance_matrix,
    )

    contours = shapes + [np.roll(1.3 * P, 4, axis=0) for P in shapes]
    region = methods._region_term(0.5)
    spec = methods.method_spec("default_phases", region=region)
    sigs = [methods.contour_signature(P, spec=spec) for P in contours]
    options = dict(region=region, signatures=sigs, backend="serial")
    exact = shape_distance_matrix(None, "default_phases", search="exact", **options)
    plain = shape_distance_matrix(None, "default_phases", search="exact", signatures=sigs, backend="serial")
    Z = np.array([sig.Z for sig in sigs])
    assert np.allclose(exact, plain + 0.5 * np.abs(Z[:, None] - Z[None]).sum(axis=2), atol=1e-12)
    fine = shape_distance_matrix(None, "default_phases", search="coarse_to_fine", refine_k=2, **options)
    refine = nearest_mask(first_pass_matrix(sigs, 0.3, COARSE_STARTS, spread_power=0.0, backend="serial"), 2)
    assert refine.sum() < refine.size - len(refine)  # some pairs are left to the first pass
    np.fill_diagonal(refine, False)
    assert np.allclose(fine[refine], exact[refine], atol=1e-12)


@pytest.mark.parametrize("bad, match", [
    (dict(weight=-1.0), "weight"), (dict(order=1), "order"), (dict(radius=-2.0), "radius"),
    (dict(order=12.0), "order"), (dict(order=True), "order"), (dict(weight="0.1"), "weight"),
])
def test_bad_region_terms_are_rejected_up_front(bad, match):
    with pytest.raises(InvalidOptionError, match=match):
        methods.method_spec("default_phases", region=dict(methods._region_term(1.0), **bad))
    with pytest.raises(InvalidOptionError, match="keys"):
        methods.method_spec("default_phases", region=dict(weight=1.0))


def test_variant_modifiers_of_the_region_term():
    from geoshape.bench.method_variants import parse_variant

    _, _, over = parse_variant("default_region+rweight=0.1+rorder=12+rradius=1.5")
    assert over["region"] == dict(weight=0.1, order=12, radius=1.5)
    for bad in ("default_region+rcolour=2", "default_phases+rweight=0.1", "default_region+rorder=x"):
        with pytest.raises(InvalidOptionError, match="bad modifier"):
            parse_variant(bad)
