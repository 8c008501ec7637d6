"""Method variants of the 2D benchmarks: ``default+skip0.4@128`` and the like.

A variant name is a registered contour method (:data:`geoshape.contour.methods.CONTOUR_METHODS`)
with modifiers that override one of its constants and, after ``@``, a contour point count
(:func:`parse_variant`). ``geoshape bench mirror2d --methods`` cross-validates such variants;
:func:`matrix_cache_name` keys a variant's saved matrix by a digest of what it computes (its
contour tracing and its method spec with the overrides applied), so ``bench mirror2d``'s cache
and the ``.spec`` files of ``bench kimia99|tari1000|rerank``
(:func:`geoshape.bench.retrieval2d.matrix_spec`) recompute a matrix whose registry entry
changed, and share one with another name of the same computation.
"""

from __future__ import annotations


def parse_variant(method: str) -> tuple[str, int, dict]:
    """``"default@128"`` → ``("default", 128, {})``: a registered method on that many contour
    points (the method's own unless given: 144 for default, 100 for most); ``+skipX``
    overrides the DP skip cost (X > 0), ``+startsK`` the cyclic DP's starts per orientation (K
    ≥ 1), ``+wNAME=X`` the weight of the method's descriptor part ``NAME`` (X ≥ 0),
    ``+partsX`` the contour tracer's part fraction (X ≥ 0, returned as ``part_fraction``; see
    :func:`geoshape.geometry.contour.join_parts`), ``+smoothX`` its boundary smoothing (0 ≤ X ≤
    :data:`~geoshape.geometry.contour.MAX_SMOOTHING`,
    as ``smoothing``; see :func:`geoshape.geometry.contour.smooth_contour`); ``+spreadX`` the
    main term's spread power (0 ≤ X ≤ 1, as ``spread_power``; see
    :func:`geoshape.contour.methods.spread_scale`); ``+hNAME=X`` and
    ``+rNAME=X`` a setting of the method's height-functions or region term; in any order,
    before ``@``. Anything else raises :class:`~geoshape.errors.InvalidOptionError` naming it,
    before any work.

    >>> parse_variant("default_hf"), parse_variant("default_100pt+skip0.4@128")
    (('default_hf', 100, {}), ('default_100pt', 128, {'skip_cost': 0.4}))
    >>> parse_variant("default+starts8+skip0.2"), parse_variant("default+parts0@100")
    (('default', 144, {'n_starts': 8, 'skip_cost': 0.2}), ('default', 100, {'part_fraction': 0.0}))
    >>> [p[:2] for p in parse_variant("default_2026_11+wshape_context=1")[2]["parts"]]
    [('idsc', 1.0), ('shape_context', 1.0), ('gsc', 0.005)]
    """
    from geoshape.contour.methods import CONTOUR_METHODS, contour_tracing
    from geoshape.errors import InvalidOptionError
    from geoshape.geometry.contour import MAX_SMOOTHING

    rest, at, n = method.partition("@")
    base, *mods = rest.split("+")
    overrides: dict = {}
    for mod in mods:
        try:
            if mod.startswith("skip") and float(mod[4:]) > 0:
                overrides["skip_cost"] = float(mod[4:])
                continue
            if mod.startswith("smooth") and 0 <= float(mod[6:]) <= MAX_SMOOTHING:
                overrides["smoothing"] = float(mod[6:])
                continue
            if mod.startswith("parts") and float(mod[5:]) >= 0:
                overrides["part_fraction"] = float(mod[5:])
                continue
            if mod.startswith("starts") and int(mod[6:]) >= 1:
                overrides["n_starts"] = int(mod[6:])
                continue
            if mod.startswith("spread") and 0 <= float(mod[6:]) <= 1:
                overrides["spread_power"] = float(mod[6:])
                continue
            name, eq, weight = mod[1:].partition("=")
            key, options = _TERM_MODIFIERS.get(mod[:1], (None, {}))
            term = overrides.get(key, CONTOUR_METHODS.get(base, {}).get(key)) if key else None
            if eq and term and name in options:
                path, kind = options[name]
                overrides[key] = _with_option(term, path, kind(weight))
                continue
            parts = overrides.get("parts", CONTOUR_METHODS.get(base, {}).get("parts", ()))
            if mod.startswith("w") and eq and float(weight) >= 0 and name in [p[0] for p in parts]:
                overrides["parts"] = tuple((p[0], float(weight), *p[2:]) if p[0] == name else p
                                           for p in parts)
                continue
        except ValueError:
            pass
        raise InvalidOptionError(f"{method!r}: bad modifier {'+' + mod!r} (use +skipX with X > 0, "
                                 "+startsK with K >= 1, +wNAME=X with NAME a part of the method, "
                                 "+hweight=X, +hskip=X, +hgroups=K, +hstep=K, +hstarts=K, "
                                 "+hphases=0|1 for a "
                                 "method with a heights term, +rweight=X, +rorder=K, +rradius=X "
                                 "for one with a region term, "
                                 f"+partsX with X >= 0, +smoothX with 0 <= X <= {MAX_SMOOTHING:g}, "
                                 "+spreadX with 0 <= X <= 1)")
    if at and not (n.isdigit() and int(n) >= 8):
        raise InvalidOptionError(f"{method!r}: bad contour point count {'@' + n!r} (use @N with N >= 8)")
    return base, int(n) if n else contour_tracing(base)["n_points"], overrides


def _flag(value: str) -> bool:
    """``"1"`` → True, ``"0"`` → False; anything else raises ``ValueError``."""
    if value not in ("0", "1"):
        raise ValueError(value)
    return value == "1"


#: Modifiers of a method's extra terms: ``+<prefix><NAME>=X`` -> (term key, {NAME: (path of the
#: option inside the term, type)}). The values are checked by ``method_spec``.
_TERM_MODIFIERS = {
    "h": ("heights", {"weight": (("weight",), float), "skip": (("skip_cost",), float),
                      "groups": (("descriptor", "n_groups"), int), "step": (("step",), int),
                      "starts": (("n_starts",), int), "phases": (("all_phases",), _flag)}),
    "r": ("region", {"weight": (("weight",), float), "order": (("order",), int),
                     "radius": (("radius",), float)}),
}


def _with_option(term: dict, path: tuple, value) -> dict:
    """``term`` with the option at ``path`` (keys into nested dicts) set to ``value``; the keys
    keep their order, so the spec's digest depends on the values only."""
    head, *rest = path
    return dict(term, **{head: _with_option(term[head], tuple(rest), value) if rest else value})


def variant_tracing(base: str, n_points: int, overrides: dict) -> dict:
    """:func:`~geoshape.contour.methods.contour_tracing` of method ``base`` on ``n_points``
    points with the tracer's overrides, popped from ``overrides``."""
    from geoshape.contour.methods import contour_tracing

    tracing = contour_tracing(base, n_points)
    tracing.update({k: overrides.pop(k) for k in ("part_fraction", "smoothing") if k in overrides})
    return tracing


def effective_spec(method: str) -> tuple[tuple, dict]:
    """``(contour tracing, method spec with the overrides applied)`` of a ``--methods`` name:
    two names with the same effective spec compute the same matrix."""
    from geoshape.contour.methods import method_spec

    base, n, over = parse_variant(method)
    tracing = tuple(variant_tracing(base, n, over).values())
    return tracing, {k: v for k, v in method_spec(base, **over).items() if k not in ("summary", "tracing")}


def matrix_cache_name(name: str, method: str) -> str:
    """Cache file stem of a collection's matrix for ``method``: its name and a digest of its
    effective spec, so a method whose registry entry changed (e.g. ``default``) is recomputed."""
    import hashlib

    digest = hashlib.sha1(repr(effective_spec(method)).encode()).hexdigest()[:8]
    return f"{name}_{method}_{digest}"
