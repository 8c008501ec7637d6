"""The registry of 2D matching methods and :func:`match_contours`.

A *method* names a point descriptor (or a weighted combination of several), the point cost,
and a matcher. The registry ``CONTOUR_METHODS`` is what the command line and the docs list:

============== ======================================== ============ ===========================
name           descriptor                               point cost   matcher
============== ======================================== ============ ===========================
``gsc``        geodesic shape context, hysteresis       squared L2   proximity heuristic
               thresholding (thesis, faithful)                       (2 anchors), best match
``shape_context`` shape context 5×12, tangent-relative  χ²           Hungarian
``idsc``       inner-distance shape context 8×12        Hellinger    cyclic DP
``curvature_map`` sampled curvature map                 squared L2   best match
``default``    inner-distance shape context 5×12 +     Hellinger +  cyclic DP (16 starts
               ¼ shape context (distances in median     squared L2   per orientation), both
               units) + 0.005 geodesic shape context,                orientations (mirror images)
               on 144 contour points smoothed by a
               Gaussian of 0.25 % of the perimeter,
               parts of ≥ 1 % of the largest joined;
               plus ¼ × the height-functions            city-block   cyclic DP (2 starts per
               dissimilarity of Wang et al. (2012),                  orientation and sampling
               matched on its own (:func:`height_costs`)             phase), both orientations,
                                                                     both phases
               plus 0.0125 × the regions' Zernike       city-block   none (one vector per
               moment magnitudes, orders 2 to 12                     shape, reflection-
               (``zernike_magnitudes``)                              invariant)
               the main term divided by the pair's mean
               descriptor spread to the power 0.25
               (``spread_scale``)
``default_nomirror`` the same, direct orientation only (the region term is reflection-invariant)
``default_zernike`` the default of 2026-12-06 (night) to 12-07: the same without the spread
               normalisation (pinned)
``default_phases`` the default of 2026-12-06 (evening): ``default_zernike`` without the region term (pinned)
``default_region`` ``default_phases`` + 0.025 × the region term on orders 2 to 8 (pinned candidate)
``default_144pt`` the default of 2026-12-05 (night) to 12-06: the same without the height functions (pinned)
``default_100pt`` ``default_144pt`` on 100 unsmoothed points, parts of ≥ 0.5 % joined (pinned,
               the default before)
``default_128pt`` ``default_144pt`` on 128 points, parts of ≥ 0.5 % joined (pinned: the default of
               2026-12-05, evening)
``default_mean`` the same with distances in mean units (the papers')
``default_median`` the default of 2026-12-05 (½ shape context), pinned (a cross-validation candidate)
``default_2026_11`` the default of 2026-12-01 to 12-05: 4 starts per orientation (kept under this name)
``default_hf`` ``default_2026_11`` + 3 × height functions (Wang et al. 2012), a cross-validation candidate
``default_heights`` ``default_144pt`` + ¼ × the height-functions dissimilarity on one sampling
               phase, 4 starts per orientation (pinned: the default of 2026-12-06, afternoon)
``height_functions`` height functions alone  squared L2   cyclic DP, both orientations
============== ======================================== ============ ===========================

A silhouette and its reflection are the same shape for retrieval: ``default`` matches each
shape against the other one and against its mirror image and keeps the better (option
``mirror``; ``mirror=False`` in the API, ``--method default_nomirror`` on the command line
turn it off). Chosen by ``geoshape bench mirror2d`` (docs/RESULTS.md, "2D mirror-aware
matching"); kept against ``default_hf`` (+ height functions) and the same on 128 contour
points, its cyclic DP given 16 starts per orientation instead of 4 (of 4, 6, 8, 16 and 128
points), its histograms' distances measured in median instead of mean units and the shape
context weighted ¼ instead of ½ (of ⅛, ¼, ½ and 1), and its contours traced on 144 points
smoothed by 0.25 % of the perimeter (of 64, 100, 128, 144 and 160 points, smoothing 0, 0.125 %,
0.25 % and 0.5 %) with every part of at least 1 % of the largest joined (of 0, 0.25, 0.5, 1
and 2 %), by ``geoshape bench mirror2d --methods …`` (docs/RESULTS.md, "2D default method:
cross-validated choice": best worst-case bull's-eye over nine dev collections). How a method's
contours are traced is part of it: :func:`contour_tracing`.

Per shape, everything is computed once into a *signature* (:func:`contour_signature`):
an embedding ``X (N, K)`` in which the point cost is a squared Euclidean distance (histograms
enter as ``sqrt(h / 2)``, so the squared distance is the squared Hellinger distance, in
[0, 1]) — a cost matrix is then one matrix product — or, for ``χ²``, the histograms
themselves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoshape._options import check_choice, is_real_number
from geoshape.contour.matching import (
    MATCHERS,
    batch_match_costs,
    best_match,
    cyclic_dp_gram_costs,
    cyclic_dp_l1_costs,
    cyclic_dp_match,
    hungarian_match,
    proximity_match,
)
from geoshape.distances import chi2_distances
from geoshape.errors import InvalidOptionError
from geoshape.io.validate import check_contour

__all__ = [
    "POINT_DESCRIPTORS",
    "CONTOUR_METHODS",
    "DEFAULT_METHOD",
    "ContourSignature",
    "SignatureStack",
    "stack_signatures",
    "method_spec",
    "contour_signature",
    "signature_cost_matrices",
    "pair_costs",
    "match_contours",
    "descriptor_spread",
    "spread_scale",
]


def _gsc(P, **kw):
    from geoshape.contour.descriptors import geodesic_shape_context

    return geodesic_shape_context(P, **kw)


def _sc(P, **kw):
    from geoshape.contour.shape_context import shape_context

    return shape_context(P, **kw)


def _idsc(P, **kw):
    from geoshape.contour.inner_distance import inner_distance_shape_context

    return inner_distance_shape_context(P, **kw)


def _hf(P, **kw):
    from geoshape.contour.descriptors import height_functions

    return height_functions(P, **kw)


def _cmap(P, **kw):
    from geoshape.contour.descriptors import curvature_map

    return curvature_map(P, **kw)


#: Point descriptors by name: function ``(P, **options) -> (N, K)``.
POINT_DESCRIPTORS = {
    "gsc": _gsc,
    "shape_context": _sc,
    "idsc": _idsc,
    "curvature_map": _cmap,
    "height_functions": _hf,
}

#: How a descriptor enters the embedding: ``raw`` as is, ``hist`` as sqrt(h/2) (Hellinger).
_TRANSFORMS = ("raw", "hist")

#: The parts of the defaults of 2026-12-01 to 12-05: distances in mean units (as the papers),
#: shape context at weight 0.5. Pinned for the cross-validation candidates built on them.
_PAPER_PARTS = (("idsc", 1.0, "hist", dict(n_r=5)), ("shape_context", 0.5, "hist", {}),
                ("gsc", 0.005, "raw", {}))


def _in_units(parts: tuple, unit: str) -> tuple:
    """``parts`` with every histogram's distances in ``unit`` (``"mean"`` as the papers, or
    ``"median"``: robust to parts added or lost)."""
    return tuple((name, w, tr, {**opts, "normalize_by": unit} if tr == "hist" else opts)
                 for name, w, tr, opts in parts)


def _reweighted(parts: tuple, **weights: float) -> tuple:
    """``parts`` with the weights of the named descriptors replaced."""
    return tuple((name, weights.get(name, w), tr, opts) for name, w, tr, opts in parts)


#: The default of 2026-12-05 (``default_median``): the paper parts in median units.
_MEDIAN_PARTS = _in_units(_PAPER_PARTS, "median")
#: The default's parts: median units, shape context at weight 0.25.
#: the descriptor parts of the default since 2026-12-05 (pinned variants name them, so they
#: stay put when the default's parts move)
_PARTS_2026_12_05 = _reweighted(_MEDIAN_PARTS, shape_context=0.25)
_DEFAULT_PARTS = _PARTS_2026_12_05

#: The default of 2026-12-05 (night) to 12-06 (``default_144pt``; the default below adds the
#: height-functions term to it): histogram distances in median units, shape context at a
#: quarter of the inner-distance shape context's weight, 16 cyclic-DP starts per orientation
#: (32 in all with the mirror image), each the best worst-case bull's-eye over the nine dev collections within
#: twice the matrix time of default_2026_11 (docs/RESULTS.md, "2D default method:
#: cross-validated choice": 8 starts tie 16 within 0.05 points at a lower mean mAP; shape
#: context 0.125 ties 0.25 at a lower mean mAP; skip cost 0.3 and gsc weight 0.005 lose when
#: halved or doubled; all of these and the smoothing re-checked so on 144 points, docs/2d.md).
#: n_starts = N is the exact cyclic DP. Its contours: 144 points smoothed
#: by 0.0025 x the perimeter, parts of at least 1 % of the largest component joined (the
#: tracer's PART_FRACTION), each chosen by the same rule (144 points at 1.99x the reference's
#: matrix time; 160 points is better on the worst case but costs 2.4x, beyond the budget).
_DEFAULT_2026_12_06 = dict(
    parts=_DEFAULT_PARTS,
    metric="sqeuclidean", matcher="dp", matcher_options=dict(skip_cost=0.3, n_starts=16),
    mirror=True, tracing=dict(n_points=144, smoothing=0.0025),
    summary="inner-distance SC 5x12 + 0.25 shape context (distances in median units) + 0.005 "
    "geodesic SC, cyclic DP (16 starts per orientation), mirror images too, on 144 contour "
    "points smoothed by a Gaussian of 0.0025 x the perimeter, parts of >= 1 % of the largest "
    "joined",
)

#: Contour tracing of the pinned defaults of 2026-12-01 to 12-05: 100 points, unsmoothed, the
#: largest component alone.
_TRACING_2026_11 = dict(n_points=100, smoothing=0.0, part_fraction=2.0)


def _pinned_2026_12_05(summary: str, **tracing) -> dict:
    """The default of 2026-12-05 — descriptors, matcher and mirror images written out, parts of
    at least 0.5 % of the largest joined — with its contour tracing's other settings: rows
    measured under it stay reproducible when the default moves."""
    return dict(parts=_PARTS_2026_12_05, metric="sqeuclidean", matcher="dp",
                matcher_options=dict(skip_cost=0.3, n_starts=16), mirror=True,
                tracing=dict(tracing, part_fraction=0.005), summary=summary)


def _heights_term(weight: float, *, n_groups: int = 23, skip_cost: float = 0.15, n_starts: int = 4,
                  step: int = 2, all_phases: bool = False) -> dict:
    """A ``heights`` term: ``weight`` × the height-functions dissimilarity (:func:`height_costs`)
    of every ``step``-th contour point, ``n_groups`` runs per point weighted ``1 / r`` and
    scaled to [−1, 1] (:func:`geoshape.contour.descriptors.height_functions` with
    ``decay="inverse"``, ``scale="max"``), cyclic DP with ``skip_cost`` and ``n_starts`` starts
    per orientation. With ``all_phases`` the other shape is sampled from each of its ``step``
    starting points and the best is kept, so the term no longer depends on where each tracing
    starts (the key is left out when false: specs without it keep their cache digests)."""
    term = dict(weight=weight, descriptor=dict(n_groups=n_groups, decay="inverse", scale="max"),
                skip_cost=skip_cost, n_starts=n_starts, step=step)
    return dict(term, all_phases=True) if all_phases else term


#: The default of 2026-12-06 (evening) (``default_phases``; the default below adds the region
#: term to it): ``default_144pt`` plus a quarter of the height-functions dissimilarity (23
#: runs, skip cost 0.15, every 2nd point; weight, skip and runs the rule's choice over the
#: nine dev collections, "default2d-heights"), the other shape sampled from both phases
#: (start-point invariant) with 2 DP starts per orientation and phase — the rule's choice in
#: "2D default method: cross-validated choice (default2d-phases)": the only eligible variant
#: of the term in that run (1.98x the reference's matrix time; one phase with 4 starts 2.02x,
#: both phases with 4 starts 2.13x), worst case 95.33 %.
_DEFAULT_PHASES = dict(
    _DEFAULT_2026_12_06, heights=_heights_term(0.25, n_starts=2, all_phases=True),
    summary="inner-distance SC 5x12 + 0.25 shape context (distances in median units) + 0.005 "
    "geodesic SC, cyclic DP (16 starts per orientation), mirror images too, plus 0.25 x the "
    "height-functions dissimilarity (23 runs weighted 1/r on every 2nd point, both sampling "
    "phases, city-block cyclic DP, divided by the shapes' complexities), on 144 contour points "
    "smoothed by a Gaussian of 0.0025 x the perimeter, parts of >= 1 % of the largest joined",
)


def _region_term(weight: float, *, order: int = 8, radius: float = 2.0) -> dict:
    """A ``region`` term: ``weight`` × the city-block distance between the two shapes' Zernike
    moment magnitudes up to ``order`` (:func:`geoshape.contour.descriptors.zernike_magnitudes`,
    the unit disc ``radius`` equal-area radii wide). The magnitudes do not change under a
    reflection, so one vector serves both orientations. O(K) per pair."""
    return dict(weight=weight, order=order, radius=radius)


#: The default of 2026-12-06 (night) to 12-07 (``default_zernike``): ``default_phases`` plus
#: 0.0125 x the city-block distance of the Zernike moment magnitudes up to order 12 of the
#: enclosed regions (a disc of twice the equal-area radius) — the rule's choice over the nine dev
#: collections in "2D default method: cross-validated choice (default2d-region)" (time reference:
#: the default before it), among weights 0.00625 to 0.05, orders 8 / 12 / 16 and discs of 1.5 / 2
#: equal-area radii.
_DEFAULT_ZERNIKE = dict(
    _DEFAULT_PHASES, region=_region_term(0.0125, order=12),
    summary="inner-distance SC 5x12 + 0.25 shape context (distances in median units) + 0.005 "
    "geodesic SC, cyclic DP (16 starts per orientation), mirror images too, plus 0.25 x the "
    "height-functions dissimilarity (23 runs weighted 1/r on every 2nd point, both sampling "
    "phases, city-block cyclic DP, divided by the shapes' complexities) and 0.0125 x the "
    "city-block distance of the regions' Zernike moment magnitudes (orders 2 to 12, a disc of "
    "twice the equal-area radius), on 144 contour points smoothed by a Gaussian of 0.0025 x the "
    "perimeter, parts of >= 1 % of the largest joined",
)

#: The default since 2026-12-07: ``default_zernike`` with its main term (the descriptors'
#: matching cost) divided by the pair's mean descriptor spread to the power 0.25
#: (:func:`spread_scale`) — the rule's choice over the nine dev collections in "2D default
#: method: cross-validated choice (default2d-spread)" (time reference: the default before it),
#: among powers 0.125, 0.25, 0.5 and 1.
_DEFAULT = dict(
    _DEFAULT_ZERNIKE, spread_power=0.25,
    summary="inner-distance SC 5x12 + 0.25 shape context (distances in median units) + 0.005 "
    "geodesic SC, cyclic DP (16 starts per orientation), mirror images too, divided by the pair's "
    "mean descriptor spread to the power 0.25, plus 0.25 x the "
    "height-functions dissimilarity (23 runs weighted 1/r on every 2nd point, both sampling "
    "phases, city-block cyclic DP, divided by the shapes' complexities) and 0.0125 x the "
    "city-block distance of the regions' Zernike moment magnitudes (orders 2 to 12, a disc of "
    "twice the equal-area radius), on 144 contour points smoothed by a Gaussian of 0.0025 x the "
    "perimeter, parts of >= 1 % of the largest joined",
)


def _variant(summary: str, base: dict = _DEFAULT, **changes) -> dict:
    """``base`` (the default unless given) with ``changes`` (and its own ``matcher_options``)."""
    out = dict(base, summary=summary, **changes)
    out["matcher_options"] = dict(out["matcher_options"])
    return out


def _pinned(summary: str, **changes) -> dict:
    """The default of 2026-12-05 (night) to 12-06, without the height-functions term, with
    ``changes``: candidates measured against it keep their rows when the default moves."""
    return _variant(summary, base=_DEFAULT_2026_12_06, **changes)


#: Methods by name. ``parts``: (descriptor, weight, transform, options); ``metric``: the
#: point cost; ``matcher`` and its options; ``mirror``: also match the mirror image (the
#: cyclic DP then tries ``n_starts`` starts per orientation: the best ``2·n_starts`` over both).
#: Cross-validation candidates name what they are, so their rows stay reproducible when the
#: default moves.
CONTOUR_METHODS: dict[str, dict] = {
    "default": _DEFAULT,
    "default_nomirror": _variant("the default, direct orientation only (no mirror images)", mirror=False),
    "default_mean": _variant("the default with the histograms' distances in mean units (as the papers)",
                             parts=_in_units(_DEFAULT_PARTS, "mean")),
    "default_2026_11": _pinned("the default of 2026-12-01 to 12-05 (4 cyclic-DP starts per orientation)",
                                parts=_PAPER_PARTS, matcher_options=dict(skip_cost=0.3, n_starts=4),
                                tracing=_TRACING_2026_11),
    "default_median": _pinned("median-unit histograms, 16 starts per orientation (the default of "
                               "2026-12-05)", parts=_MEDIAN_PARTS,
                               matcher_options=dict(skip_cost=0.3, n_starts=16), tracing=_TRACING_2026_11),
    "default_100pt": _pinned_2026_12_05("the default's descriptors and matcher on 100 unsmoothed contour "
                                        "points (the default of 2026-12-05 before the tracing change), "
                                        "parts of >= 0.5 % of the largest joined",
                                        n_points=100, smoothing=0.0),
    "default_128pt": _pinned_2026_12_05("the default of 2026-12-05 (evening): 128 points smoothed by "
                                        "0.0025 x the perimeter, parts of >= 0.5 % of the largest joined",
                                        n_points=128, smoothing=0.0025),
    "default_hf": _pinned("default_2026_11 + 3 x height functions (25 runs), cyclic DP, mirror images too",
                           parts=_PAPER_PARTS + (("height_functions", 3.0, "raw", {}),),
                           matcher_options=dict(skip_cost=0.3, n_starts=4), tracing=_TRACING_2026_11),
    "default_144pt": _pinned("the default of 2026-12-05 (night) to 12-06: the default without the "
                             "height-functions term"),
    "default_heights": _pinned("default_144pt + 0.25 x height-functions dissimilarity (Wang et al. "
                               "2012: 23 runs weighted 1/r, city-block DP on every 2nd point of one "
                               "sampling phase, 4 starts per orientation, divided by the shapes' "
                               "complexities); the default of 2026-12-06 (afternoon)",
                               heights=_heights_term(0.25)),
    "default_phases": _variant("the default of 2026-12-06 (evening): the default without the region "
                               "term (pinned; the time reference of default2d-region)",
                               base=_DEFAULT_PHASES),
    "default_zernike": _variant("the default of 2026-12-06 (night) to 12-07: the default without "
                                "the spread normalisation (pinned; the time reference of "
                                "default2d-spread)", base=_DEFAULT_ZERNIKE),
    "default_region": _variant("default_phases + 0.025 x the city-block distance of the Zernike "
                               "moment magnitudes (orders 2 to 8) of the enclosed regions, scaled to "
                               "twice the equal-area radius (a cross-validation candidate; pinned)",
                               base=_DEFAULT_PHASES, region=_region_term(0.025)),
    "height_functions": dict(
        parts=(("height_functions", 1.0, "raw", {}),),
        metric="sqeuclidean", matcher="dp", matcher_options=dict(skip_cost=0.06, n_starts=4),
        mirror=True,
        summary="height functions (Wang et al. 2012), 25 runs, cyclic DP, mirror images too",
    ),
    "gsc": dict(
        parts=(("gsc", 1.0, "raw", dict(threshold="hysteresis", bins="thesis", window=4)),),
        metric="sqeuclidean", matcher="proximity", matcher_options=dict(c1=10.0, c2=10.0),
        mirror=False,
        summary="geodesic shape context + proximity heuristic, best match (thesis, faithful)",
    ),
    "shape_context": dict(
        parts=(("shape_context", 1.0, "hist", {}),),
        metric="chi2", matcher="hungarian", matcher_options={}, mirror=False,
        summary="shape context (Belongie 2002), chi-squared cost, Hungarian",
    ),
    "idsc": dict(
        parts=(("idsc", 1.0, "hist", {}),),
        metric="sqeuclidean", matcher="dp", matcher_options=dict(skip_cost=0.3, n_starts=4),
        mirror=False,
        summary="inner-distance shape context (Ling & Jacobs 2007), cyclic DP",
    ),
    "curvature_map": dict(
        parts=(("curvature_map", 1.0, "raw", {}),),
        metric="sqeuclidean", matcher="best", matcher_options={}, mirror=False,
        summary="sampled 2D curvature map, best match",
    ),
}

#: The method used when none is named (chosen by ``geoshape bench kimia99/tari1000``).
DEFAULT_METHOD = "default"


def contour_tracing(method: str, n_points: int | None = None) -> dict:
    """How ``method``'s contours are traced: keyword arguments ``n_points``, ``part_fraction``
    and ``smoothing`` of :func:`geoshape.geometry.contour.extract_contour` (and
    ``contour_from_image``) — the registry entry's ``tracing``, else the tracer's defaults
    (:data:`geoshape.geometry.contour.N_POINTS` points, …); ``n_points`` (when given) overrides
    the point count only.

    >>> contour_tracing("gsc")["n_points"], contour_tracing("default")["n_points"]
    (100, 144)
    >>> contour_tracing("default", n_points=64)["smoothing"] == contour_tracing("default")["smoothing"]
    True
    """
    from geoshape.geometry.contour import N_POINTS, PART_FRACTION, SMOOTHING

    check_choice("method", method, CONTOUR_METHODS)
    tracing = dict(dict(n_points=N_POINTS, part_fraction=PART_FRACTION, smoothing=SMOOTHING),
                   **CONTOUR_METHODS[method].get("tracing", {}))
    if n_points is not None:
        tracing["n_points"] = n_points
    return tracing


def method_spec(method: str, **overrides) -> dict:
    """The registry entry of ``method`` with keyword overrides (``matcher=``, ``mirror=``, …).

    Unknown override keys raise :class:`InvalidOptionError` listing the allowed ones.
    """
    check_choice("method", method, CONTOUR_METHODS)
    spec = dict(CONTOUR_METHODS[method])
    spec["matcher_options"] = dict(spec["matcher_options"])
    for key, value in overrides.items():
        if value is None:
            continue
        if key in ("matcher", "metric", "mirror", "parts", "heights", "region", "spread_power"):
            spec[key] = value
        elif key in ("skip_cost", "n_starts", "c1", "c2"):
            spec["matcher_options"][key] = value
        else:
            raise InvalidOptionError(
                f"unknown option {key!r} for method {method!r}; allowed: matcher, metric, "
                "mirror, parts, heights, region, spread_power, skip_cost, n_starts, c1, c2"
            )
    check_choice("matcher", spec["matcher"], MATCHERS)
    check_choice("metric", spec["metric"], ("sqeuclidean", "chi2"))
    for name, _, transform, _ in spec["parts"]:
        check_choice("descriptor", name, POINT_DESCRIPTORS)
        check_choice("transform", transform, _TRANSFORMS)
    if spec["metric"] == "chi2" and (len(spec["parts"]) != 1 or spec["parts"][0][2] != "hist"):
        raise InvalidOptionError("metric 'chi2' needs exactly one histogram descriptor")
    if spec.get("heights"):
        _check_heights(spec["heights"])
    if spec.get("region"):
        _check_region(spec["region"])
    power = spec.get("spread_power", 0.0)
    if not (is_real_number(power) and 0 <= power <= 1):
        raise InvalidOptionError(f"spread_power must be a number in [0, 1], got {power!r}")
    if power and spec["metric"] != "sqeuclidean":
        raise InvalidOptionError("spread_power needs the 'sqeuclidean' metric (the spread is a squared "
                                 f"Euclidean distance), got metric {spec['metric']!r}")
    return spec


def _check_heights(term: dict) -> None:
    """Reject a malformed ``heights`` term, naming the bad entry."""
    keys, optional = {"weight", "descriptor", "skip_cost", "n_starts", "step"}, {"all_phases"}
    if not isinstance(term, dict) or not keys <= set(term) <= keys | optional:
        raise InvalidOptionError(f"heights must be a dict with keys {sorted(keys)} (and optionally "
                                 f"{sorted(optional)}), got {term!r}")
    if not isinstance(term.get("all_phases", False), bool):
        raise InvalidOptionError(f"heights all_phases must be True or False, got {term['all_phases']!r}")
    if not isinstance(term["descriptor"], dict) or "n_groups" not in term["descriptor"]:
        raise InvalidOptionError(f"heights descriptor must name n_groups, got {term['descriptor']!r}")
    checks = (("weight", term["weight"] >= 0, "≥ 0"), ("skip_cost", term["skip_cost"] > 0, "> 0"),
              ("n_starts", int(term["n_starts"]) == term["n_starts"] >= 1, "an integer ≥ 1"),
              ("step", int(term["step"]) == term["step"] >= 1, "an integer ≥ 1"))
    _reject_failed("heights", term, checks)


def _reject_failed(term_name: str, term: dict, checks) -> None:
    """Raise :class:`InvalidOptionError` for the first ``(key, ok, what)`` of ``checks`` that
    failed, naming the term, the key, what it must be and what it was."""
    for key, ok, what in checks:
        if not ok:
            raise InvalidOptionError(f"{term_name} {key} must be {what}, got {term[key]!r}")


def _check_region(term: dict) -> None:
    """Reject a malformed ``region`` term, naming the bad entry."""
    keys = {"weight", "order", "radius"}
    if not isinstance(term, dict) or set(term) != keys:
        raise InvalidOptionError(f"region must be a dict with keys {sorted(keys)}, got {term!r}")
    order = term["order"]
    checks = (("weight", is_real_number(term["weight"]) and term["weight"] >= 0, "a number ≥ 0"),
              ("radius", is_real_number(term["radius"]) and term["radius"] > 0, "a number > 0"),
              ("order", isinstance(order, (int, np.integer)) and not isinstance(order, bool)
               and order >= 2, "an integer ≥ 2"))
    _reject_failed("region", term, checks)


@dataclass(frozen=True)
class ContourSignature:
    """Everything a method needs about one contour, computed once.

    ``X (N, K)``: embedded descriptors; ``s (N,)``: arc-length positions / perimeter;
    ``X_mirror``: the same for the mirror image (``None`` unless the method uses it).
    For a method with a ``heights`` term: ``H (R, N', G)`` the height functions of every
    ``step``-th point, from each of ``R`` starting phases (``R = step`` with the term's
    ``all_phases``, else 1: phase 0), ``H_mirror`` those of the mirror image (or ``None``) and
    ``complexity`` the mean city-block distance between the rows of each phase's ``H``, averaged
    over the phases (0 without the term). For a method with a ``region`` term: ``Z (K,)`` the
    Zernike moment magnitudes of the enclosed region (the same for the mirror image).
    ``spread``: :func:`descriptor_spread` of ``X`` — how varied its points look to the
    descriptor, the unit of the main term's normalisation (``spread_power``,
    :func:`pair_costs`); ``None`` only in a signature built by hand. O(N·K).
    """

    X: np.ndarray
    s: np.ndarray
    X_mirror: np.ndarray | None = None
    H: np.ndarray | None = None
    H_mirror: np.ndarray | None = None
    complexity: float = 0.0
    Z: np.ndarray | None = None
    spread: float | None = None


def descriptor_spread(X: np.ndarray) -> float:
    """Mean of ``‖X[a] − X[b]‖²`` over all ordered pairs of rows of ``X (N, K)`` (``a = b``
    included): ``2 · (mean ‖x‖² − ‖mean x‖²)``, twice the rows' total variance. O(N·K).

    >>> descriptor_spread(np.array([[0.0, 0.0], [3.0, 4.0]]))  # pairs: 0, 25, 25, 0
    12.5
    """
    X = np.asarray(X, dtype=np.float64)
    mean = X.mean(axis=0)
    return float(max(2.0 * ((X**2).sum(axis=1).mean() - mean @ mean), 0.0))


def _embed(P: np.ndarray, spec: dict, inner: tuple | None = None) -> np.ndarray:
    """The embedding ``X (N, K)`` of ``P``; ``inner``: its inner distances, if known (``idsc``)."""
    blocks = []
    for name, weight, transform, options in spec["parts"]:
        known = {"inner": inner} if name == "idsc" and inner is not None else {}
        H = np.asarray(POINT_DESCRIPTORS[name](P, **options, **known), dtype=np.float64)
        if spec["metric"] == "chi2":
            blocks.append(H)
            continue
        H = np.sqrt(np.maximum(H, 0.0) / 2.0) if transform == "hist" else H
        blocks.append(np.sqrt(weight) * H)
    return np.ascontiguousarray(np.hstack(blocks))


def contour_signature(P, method: str = DEFAULT_METHOD, *, spec: dict | None = None,
                      name: str = "contour") -> ContourSignature:
    """Compute the per-shape signature of ``P`` for ``method``.

    Cost: the descriptors' (O(N³) for ``idsc``'s visibility graph, O(N²) for shape context,
    O(N·B) for ``gsc``), twice with ``mirror`` — except the inner distances, which a
    reflection keeps: the mirror image's are the shape's, re-indexed.
    """
    from geoshape.contour.inner_distance import inner_distances, mirrored_inner_distances
    from geoshape.geometry.contour import arc_length, mirror_contour, perimeter

    spec = spec if spec is not None else method_spec(method)
    P = check_contour(P, name=name)
    s = arc_length(P) / perimeter(P)
    uses_inner = spec["mirror"] and any(part[0] == "idsc" for part in spec["parts"])
    inner = inner_distances(P) if uses_inner else None
    X = _embed(P, spec, inner)
    Xm = None
    if spec["mirror"]:
        inner_mirror = None if inner is None else mirrored_inner_distances(*inner)
        Xm = _embed(mirror_contour(P), spec, inner_mirror)
    Z = None
    if spec.get("region"):
        from geoshape.contour.descriptors import zernike_magnitudes

        Z = zernike_magnitudes(P, order=spec["region"]["order"], radius=spec["region"]["radius"])
    spread = descriptor_spread(X)
    if not spec.get("heights"):
        return ContourSignature(X, s, Xm, Z=Z, spread=spread)
    H, Hm, complexity = _height_signature(P, spec)
    return ContourSignature(X, s, Xm, H, Hm, complexity, Z, spread)


def _height_signature(P: np.ndarray, spec: dict):
    """``(H, H_mirror, complexity)`` of the ``heights`` term (:class:`ContourSignature`): height
    functions of every ``step``-th point from each phase (and of the mirror image of those
    points), and the shape's complexity. O(R·N'²·G). A contour of ``N'`` points has ``N' − 1``
    heights per point, so on short contours the runs are capped at that many (each height its
    own run). With ``all_phases`` every phase takes ``N // step`` points (equal lengths)."""
    from scipy.spatial.distance import pdist

    from geoshape.contour.descriptors import height_functions
    from geoshape.geometry.contour import mirror_contour

    term = spec["heights"]
    step = term["step"]
    if term.get("all_phases"):
        samples = [P[r + step * np.arange(len(P) // step)] for r in range(step)]
    else:
        samples = [P[::step]]
    options = dict(term["descriptor"])
    options["n_groups"] = min(options["n_groups"], len(samples[0]) - 1)
    H = np.stack([height_functions(np.ascontiguousarray(Ps), **options) for Ps in samples])
    Hm = None
    if spec["mirror"]:
        Hm = np.stack([height_functions(mirror_contour(Ps), **options) for Ps in samples])
    n = H.shape[1]
    # mean city-block distance over all n² ordered pairs of rows, averaged over the phases
    complexity = float(np.mean([2.0 * float(pdist(Hr, "cityblock").sum()) / (n * n) for Hr in H]))
    return H, Hm, complexity


def _gram_parts(X1: np.ndarray, X2s: np.ndarray, n2: np.ndarray | None = None):
    """``n1 (N,)``, ``n2 (B, M)``, ``G (B, M, N)`` with ``‖X1[i] − X2s[b, j]‖²`` equal to
    ``n1[i] + n2[b, j] − 2 G[b, j, i]`` (``n2`` is computed unless given).

    O(B·N·M·K): one matrix product per pair (the same product, so the same bits, whatever ``B``).
    """
    n1 = (X1**2).sum(axis=1)
    n2 = (X2s**2).sum(axis=2) if n2 is None else n2
    G = np.matmul(X2s, np.ascontiguousarray(X1.T))
    return n1, n2, G


def signature_cost_matrices(X1: np.ndarray, X2s: np.ndarray, metric: str) -> np.ndarray:
    """Point cost matrices of one embedding ``X1 (N, K)`` against a stack ``X2s (B, M, K)``.

    Returns ``(B, N, M)``. O(B·N·M·K) — a single matrix product for ``sqeuclidean``.
    """
    if metric == "chi2":  # histograms: no absolute values; single precision
        out = np.empty((len(X2s), len(X1), X2s.shape[1]))
        for t, X2 in enumerate(X2s):
            out[t] = chi2_distances(X1, X2, absolute=False, dtype=np.float32)
        return out
    n1, n2, G = _gram_parts(X1, X2s)
    C = n1[None, :, None] + n2[:, None, :] - 2.0 * G.transpose(0, 2, 1)
    return np.maximum(C, 0.0, out=C)


@dataclass(frozen=True)
class SignatureStack:
    """Signatures of equal point counts stacked for batched matching (see :func:`stack_signatures`).

    ``XV (B, V, M, K)``: the embeddings of each shape (``V = 1``) and of its mirror image
    (``V = 2``), stacked once so that one matrix product per query gives the Gram matrices of
    both orientations; ``X (B, M, K)`` and ``X_mirror (B, M, K)`` (or ``None``) are views of it;
    ``s (B, M)``; ``sq_norms (B, V, M)``: squared row norms of ``XV``; with a ``heights``
    term, ``HV (B, V·R, G, M')`` the height functions of each orientation's ``R`` phases,
    points last (the layout of :func:`~geoshape.contour.matching.cyclic_dp_l1_costs`), and
    ``complexity (B,)``
    (else ``None``); with a ``region`` term, ``Z (B, K)`` (else ``None``); ``spread (B,)``
    the signatures' descriptor spreads (``None`` if one has none).
    """

    X: np.ndarray
    s: np.ndarray
    X_mirror: np.ndarray | None
    sq_norms: np.ndarray
    XV: np.ndarray
    HV: np.ndarray | None = None
    complexity: np.ndarray | None = None
    Z: np.ndarray | None = None
    spread: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.X)

    def tail(self, first: int) -> SignatureStack:
        """The signatures from ``first`` on (views)."""
        mirror = None if self.X_mirror is None else self.X_mirror[first:]
        heights = (None, None) if self.HV is None else (self.HV[first:], self.complexity[first:])
        region = None if self.Z is None else self.Z[first:]
        return SignatureStack(self.X[first:], self.s[first:], mirror, self.sq_norms[first:],
                              self.XV[first:], *heights, region,
                              None if self.spread is None else self.spread[first:])


def stack_signatures(sigs: list[ContourSignature]) -> SignatureStack:
    """Stack signatures once, to match many queries against them. O(B·M·K)."""
    mirror = sigs[0].X_mirror is not None
    V = 2 if mirror else 1
    XV = np.empty((len(sigs), V, *sigs[0].X.shape))
    for b, sig in enumerate(sigs):
        XV[b, 0] = sig.X
        if mirror:
            XV[b, 1] = sig.X_mirror
    norms = (XV**2).sum(axis=3)
    HV = complexity = None
    if sigs[0].H is not None:
        HV = np.stack([np.concatenate([sig.H, sig.H_mirror]) if mirror else sig.H for sig in sigs])
        HV = np.ascontiguousarray(HV.transpose(0, 1, 3, 2))
        complexity = np.array([sig.complexity for sig in sigs])
    Z = None if sigs[0].Z is None else np.stack([sig.Z for sig in sigs])
    known = all(sig.spread is not None for sig in sigs)
    spread = np.array([sig.spread for sig in sigs], dtype=np.float64) if known else None
    return SignatureStack(XV[:, 0], np.stack([s.s for s in sigs]), XV[:, 1] if mirror else None,
                          norms, XV, HV, complexity, Z, spread)


def pair_costs(sig1: ContourSignature, sigs2, spec: dict, cols=None) -> np.ndarray:
    """Retrieval distances from one signature to several: ``(len(sigs2),)``, or to those at
    ``cols`` only (``(len(cols),)``; the ``dp`` matcher with the squared-Euclidean cost).

    ``sigs2``: a list of signatures or a :class:`SignatureStack` of them. With ``mirror``
    the distance is the smaller of the costs against each shape and against its mirror
    image; for the ``dp`` matcher ``n_starts`` is then per orientation (the best
    ``2·n_starts`` starts ranked over both orientations together). Shapes in ``sigs2`` must
    have equal point counts (they are stacked). A method with a ``heights`` term adds
    ``weight ×`` :func:`height_costs` (matched on their own); one with a ``region`` term adds
    ``weight ×`` the city-block distance of the Zernike magnitudes (no matching: O(K) a pair).
    With ``spread_power = q > 0`` the main term (the descriptors' matching cost) is first
    divided by :func:`spread_scale`, the two shapes' mean descriptor spread to the power ``q``.

    For the ``dp`` matcher with the squared-Euclidean cost the cost matrices are never
    stored: the compiled matcher builds each from the matrix product
    (:func:`geoshape.contour.matching.cyclic_dp_gram_costs`, same values).
    """
    if len(sigs2) == 0:
        return np.zeros(0)
    stack = sigs2 if isinstance(sigs2, SignatureStack) else stack_signatures(list(sigs2))
    return _total_costs(_main_pair_costs(sig1, stack, spec, cols), sig1, stack, spec, cols)


#: Smallest mean spread a pair is divided by (two shapes whose point descriptors are all alike
#: would otherwise give 0 / 0).
MIN_SPREAD = 1e-9


def spread_scale(spread_1, spread_2, power: float) -> np.ndarray:
    """What a pair's main term is divided by with ``spread_power``.

    Shapes whose points all look alike (compact blobs) have small matching costs to
    everything, varied ones large; measured in the pair's own spread, a cost says how unlike
    the shapes are relative to how varied they are. ``power`` tempers the correction (0:
    none; 1: unit-free; chosen by cross-validation, docs/2d.md).

    Parameters
    ----------
    spread_1, spread_2 : float or array_like
        :func:`descriptor_spread` of each shape (broadcast together).
    power : float
        In [0, 1].

    Returns
    -------
    ndarray
        ``max((spread_1 + spread_2) / 2, MIN_SPREAD) ** power``, the broadcast shape. O(1) a pair.

    >>> float(spread_scale(0.5, 1.5, 0.5))
    1.0
    """
    mean = 0.5 * (np.asarray(spread_1, dtype=np.float64) + np.asarray(spread_2, dtype=np.float64))
    return np.maximum(mean, MIN_SPREAD) ** power


def _total_costs(out: np.ndarray, sig1: ContourSignature, stack: SignatureStack, spec: dict,
                 cols=None) -> np.ndarray:
    """``out`` (the main term's distances to ``stack``, or to its ``cols``), in place: divided by
    :func:`spread_scale` with ``spread_power``, plus the ``heights`` and ``region`` terms of
    ``spec``, in that order."""
    picked = slice(None) if cols is None else np.asarray(cols, dtype=np.int64)
    if spec.get("spread_power"):
        if sig1.spread is None or stack.spread is None:
            raise InvalidOptionError("spread_power needs each signature's descriptor spread "
                                     "(contour_signature computes it); a signature has none")
        out /= spread_scale(sig1.spread, stack.spread[picked], spec["spread_power"])
    if spec.get("heights"):
        out += spec["heights"]["weight"] * height_costs(sig1, stack, spec, cols)
    if spec.get("region"):
        out += spec["region"]["weight"] * np.abs(stack.Z[picked] - sig1.Z).sum(axis=1)
    return out


def height_costs(sig1: ContourSignature, stack: SignatureStack, spec: dict,
                 cols=None) -> np.ndarray:
    """The ``heights`` term of ``spec`` from one signature to stacked ones (or those at
    ``cols``): cyclic DP of the height functions with city-block point costs (both
    orientations with ``mirror``; the query's phase 0 against every phase of the others),
    divided by the sum of the two shapes' complexities — the dissimilarity of Wang et al.
    (2012), unit-free. O(B·V·N'²·G + B·n_starts·N'²), ``V`` orientations × phases."""
    term = spec["heights"]
    picked = slice(None) if cols is None else np.asarray(cols, dtype=np.int64)
    HV = stack.HV[picked]
    costs = cyclic_dp_l1_costs(sig1.H[0], HV, skip_cost=term["skip_cost"],
                               n_starts=HV.shape[1] * term["n_starts"])
    return costs / np.maximum(sig1.complexity + stack.complexity[picked], 1e-300)


def _main_pair_costs(sig1: ContourSignature, stack: SignatureStack, spec: dict, cols):
    """:func:`pair_costs` without the ``heights`` and ``region`` terms."""
    X2, s2 = stack.X, stack.s
    opts = _variant_options(spec)
    if spec["matcher"] == "dp" and spec["metric"] == "sqeuclidean":
        return _dp_pair_costs(sig1.X, stack, opts, cols)
    if cols is not None:
        raise InvalidOptionError("pair_costs(cols=…) needs the 'dp' matcher with the 'sqeuclidean' cost")
    s1 = np.broadcast_to(sig1.s, (len(stack), len(sig1.s)))
    C = signature_cost_matrices(sig1.X, X2, spec["metric"])
    if spec["mirror"]:
        Cm = signature_cost_matrices(sig1.X, stack.X_mirror, spec["metric"])
        C = np.stack([C, Cm], axis=1)  # (B, 2, N, M)
        # Mirror point i is the reflection of point -i, so its arc-length position is 1 - s.
        s2m = np.mod(1.0 - np.roll(s2[:, ::-1], 1, axis=1), 1.0)
        s2 = np.stack([s2, s2m], axis=1)
    return batch_match_costs(C, spec["matcher"], s1=s1, s2=s2, **opts)


#: Pairs whose Gram matrices are made and matched at a time (they stay in the cache).
_GRAM_CHUNK = 16


def _dp_pair_costs(X1: np.ndarray, stack: SignatureStack, opts: dict,
                   cols: np.ndarray | None = None) -> np.ndarray:
    """:func:`pair_costs` for the ``dp`` matcher with the squared-Euclidean cost, against
    every stacked shape or only those at ``cols`` (without copying the stack).

    The Gram matrices of all orientations come from one product per chunk of
    ``_GRAM_CHUNK`` pairs into a reused buffer (each pair's is the same product as
    :func:`_gram_parts`, so the same bits), and are matched while still in the cache.
    """
    XV, n2 = stack.XV, stack.sq_norms
    picked = np.arange(len(XV)) if cols is None else np.asarray(cols, dtype=np.int64)
    _, V, M, _ = XV.shape
    n1 = (X1**2).sum(axis=1)
    X1T = np.ascontiguousarray(X1.T)
    buf = np.empty((min(len(picked), _GRAM_CHUNK), V, M, len(X1)))
    out = np.empty(len(picked))
    for c in range(0, len(picked), _GRAM_CHUNK):
        chunk = picked[c:c + _GRAM_CHUNK]
        G = buf[:len(chunk)]
        if cols is None:
            np.matmul(XV[c:c + len(chunk)], X1T, out=G)
        else:
            for t, j in enumerate(chunk):
                np.matmul(XV[j], X1T, out=G[t])
        out[c:c + len(chunk)] = cyclic_dp_gram_costs(G, n1, n2[chunk], skip_cost=opts.get("skip_cost", 0.3),
                                                     n_starts=opts.get("n_starts", 4))
    return out


def _variant_options(spec: dict) -> dict:
    """Matcher options for all variants of a pair at once: ``n_starts`` is per orientation,
    so with ``mirror`` the DP tries the best ``2 · n_starts`` starts over both orientations."""
    opts = dict(spec["matcher_options"])
    if spec["mirror"] and spec["matcher"] == "dp":
        opts["n_starts"] = 2 * opts.get("n_starts", 4)
    return opts


def match_contours(P, Q, method: str = DEFAULT_METHOD, **options) -> tuple[np.ndarray, float]:
    """Point-to-point correspondence and matching cost between two closed contours.

    Parameters
    ----------
    P : (N, 2) array_like
        Contour 1: closed, counter-clockwise, points roughly uniform by arc length (as
        :func:`geoshape.geometry.contour.extract_contour` gives).
    Q : (M, 2) array_like
        Contour 2, same conventions.
    method : str
        A key of ``CONTOUR_METHODS`` (``default``, ``gsc``, ``shape_context``, ``idsc``,
        ``curvature_map``).
    **options
        Overrides of the method's entry: ``matcher`` (``best``, ``proximity``,
        ``hungarian``, ``dp``), ``mirror``, ``skip_cost``, ``n_starts``, ``c1``, ``c2``,
        ``spread_power``.

    Returns
    -------
    p2p_12 : (N,) int64
        For each point of ``P``, the index of its match in ``Q``.
    cost : float
        Per-point matching cost in the direction P → Q (``SimCost / N`` for ``gsc``). The
        retrieval distance of :func:`geoshape.contour.retrieval.shape_distance_matrix` is
        the average of both directions for the (asymmetric) ``best``/``proximity`` matchers.
        With ``mirror`` and a better match to the mirror image of ``Q``, ``p2p_12`` indexes
        the points of ``Q`` all the same.

    Examples
    --------
    >>> t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    >>> P = np.c_[np.cos(t) * (1 + 0.3 * np.cos(3 * t)), np.sin(t) * (1 + 0.3 * np.cos(3 * t))]
    >>> p2p, cost = match_contours(P, 2 * np.roll(P, 5, axis=0), method="idsc")
    >>> int(np.mean(p2p == (np.arange(64) + 5) % 64) > 0.9)  # P[i] is point i + 5 of the rolled copy
    1
    """
    spec = method_spec(method, **options)
    P = check_contour(P, name="contour 1")
    Q = check_contour(Q, name="contour 2")
    sig1 = contour_signature(P, spec=spec, name="contour 1")
    sig2 = contour_signature(Q, spec=spec, name="contour 2")
    M = len(Q)
    candidates = [(sig2.X, sig2.s, np.arange(M))]
    if spec["mirror"]:
        mirror_index = (-np.arange(M)) % M  # mirror point j is the reflection of point -j
        candidates.append((sig2.X_mirror, np.mod(1.0 - sig2.s[mirror_index], 1.0), mirror_index))
    best = None
    for X2, s2, index in candidates:
        C = signature_cost_matrices(sig1.X, X2[None], spec["metric"])[0]
        p2p, cost = _match_one(C, sig1.s, s2, spec)
        if best is None or cost < best[1]:
            best = (index[p2p].astype(np.int64), float(cost))
    cost = _total_costs(np.array([best[1]]), sig1, stack_signatures([sig2]), spec)[0]
    return best[0], float(cost)


def _match_one(C: np.ndarray, s1: np.ndarray, s2: np.ndarray, spec: dict):
    opts = spec["matcher_options"]
    matcher = spec["matcher"]
    if matcher == "best":
        return best_match(C)
    if matcher == "proximity":
        return proximity_match(C, s1, s2, c1=opts.get("c1", 1.0), c2=opts.get("c2", 1.0))
    if matcher == "hungarian":
        return hungarian_match(C)
    return cyclic_dp_match(C, skip_cost=opts.get("skip_cost", 0.3),
                           n_starts=opts.get("n_starts", 4))
