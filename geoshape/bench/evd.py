"""EVD settings on tosca_r5k: samples, kernel width and sample weighting (thesis §4.6.2).

For every mesh, ``max(l)`` max-min samples and their geodesic Voronoi cells are computed
once with the graph backend (:func:`geoshape.geometry.sampling.geodesic_voronoi_sampling`)
together with the block of geodesic distances between them; a smaller ``l`` uses the
first ``l`` samples (a farthest-point prefix is itself a farthest-point run) with the
exact geodesic Voronoi cells of that prefix, read off the same distance rows. Each setting (``l``, width,
weighting) gives the 20-entry EVD of every mesh and NN / FT / mAP of the χ² ranking. The
thesis setting (``l = 60``, unweighted, σ = max) and the library default (``l = 500``,
area-weighted, σ = 0.1 √area) are rows of the same table. A width ``abs:S`` (``S`` in the
meshes' own units) is *not* scale invariant: it shows how much of the remaining error is
size — TOSCA keeps each character's real size. First tier per class is printed for the
library default and the best row.

Reference rows show what exact eigenvalues would give (a reference, not a bound): in the
narrow-kernel limit the Gaussian affinity operator is ``2πσ²`` times the heat kernel at
``t = σ²/2``, whose eigenvalues are ``exp(-σ² μ_k / 2)`` for the Laplace–Beltrami
eigenvalues ``μ_k``; the rows feed the *exact* ``μ_k`` (robust Laplacian, unit area)
through that formula — the EVD without sampling or geodesic error, scale invariant
(``area:ρ``) and size-aware (``abs:S``). Below the table, the two classes the default
confuses most are compared band by band — exact eigenvalues, the exact reference EVD, the
default's sampled EVD — as the gap between their class means against the spread of one
class over its poses, and the same for the size ``√area``.

``geoshape bench evd [DIR]`` writes the section ``evd-settings`` of docs/RESULTS.md.
"""

from __future__ import annotations

import argparse

HELP = "EVD settings on tosca_r5k: samples l, Gaussian width, area weighting (NN/FT/mAP)"

SAMPLES = (60, 150, 300, 500)
WIDTHS = ("max", "mean:0.5", "area:0.05", "area:0.1", "area:0.2", "abs:20")
N_EIGENVALUES = 20


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dir", nargs="?", default=None,
                   help="tosca_r5k folder (default: found under $GEOSHAPE_DATA or ../shared/data)")
    p.add_argument("--samples", default=",".join(map(str, SAMPLES)),
                   help=f"sample counts l (default {','.join(map(str, SAMPLES))})")
    p.add_argument("--widths", default=",".join(WIDTHS),
                   help="Gaussian widths: max, mean:RHO (RHO x mean distance), area:RHO (RHO x sqrt(area)) "
                   f"(default {','.join(WIDTHS)})")
    p.add_argument("--no-results", action="store_true", help="print only; do not write docs/RESULTS.md")


def parse_width(spec: str) -> tuple[str, float]:
    """``"max"`` → ("max", 1); ``"area:0.1"`` → ("area", 0.1); ``"mean:0.5"`` → ("mean", 0.5);
    ``"abs:20"`` → ("abs", 20.0)."""
    from geoshape.errors import InvalidOptionError

    kind, _, rho = spec.strip().partition(":")
    try:
        factor = float(rho) if rho else 1.0
    except ValueError:
        factor = -1.0
    if kind not in ("max", "mean", "area", "abs") or not factor > 0:
        raise InvalidOptionError(
            f"bad width {spec!r}: expected max, mean:RHO, area:RHO or abs:S with RHO, S > 0")
    return kind, factor


def mesh_samples(V, F, n_samples: int, prefixes=()) -> dict:
    """Samples, cell areas and the sample-to-sample geodesic block of one mesh.

    ``cells[l]`` holds the geodesic Voronoi cell areas of the first ``l`` samples for
    ``l`` in ``prefixes`` and ``n_samples``. O(n log n) sampling
    (:func:`geodesic_voronoi_sampling`) plus ``n_samples`` full Dijkstra rows; memory
    O(n_samples n) transiently.
    """
    import numpy as np
    from scipy.sparse.csgraph import dijkstra

    from geoshape.geometry.graph import structural_graph
    from geoshape.geometry.mesh import vertex_areas
    from geoshape.geometry.sampling import geodesic_voronoi_sampling

    graph = structural_graph(V, F, 1)
    samples, owner, _ = geodesic_voronoi_sampling(graph, n_samples)
    rows = dijkstra(graph, directed=True, indices=samples)
    vertex_area = vertex_areas(V, F)
    cells = {n_samples: np.bincount(owner, weights=vertex_area, minlength=n_samples)}
    for l in set(prefixes) - {n_samples}:
        if l < n_samples:
            cells[l] = np.bincount(rows[:l].argmin(axis=0), weights=vertex_area, minlength=l)
    block = rows[:, samples]
    return {"D": 0.5 * (block + block.T), "rows_mean": float(rows.mean()),
            "rows_max": float(rows.max()), "cells": cells, "area": float(vertex_area.sum())}


def evd_from_samples(s: dict, l: int, width: str, weighted: bool) -> np.ndarray:  # noqa: F821
    """The EVD of one mesh for one setting, from :func:`mesh_samples` output."""
    import numpy as np

    from geoshape.retrieval.descriptors.evd import affinity_spectrum

    D = s["D"][:l, :l]
    kind, rho = parse_width(width)
    if kind == "max":  # over the l x n rows in the library; the l_max rows are a close stand-in
        sigma = s["rows_max"]
    elif kind == "mean":
        sigma = rho * s["rows_mean"]
    elif kind == "area":
        sigma = rho * np.sqrt(s["area"])
    else:
        sigma = rho
    K = np.exp(-(D**2) / (2.0 * sigma * sigma))
    return affinity_spectrum(K, s["cells"][l] if weighted else None, N_EIGENVALUES)


def reference_evd(mu_unit, area: float, width: str) -> np.ndarray:  # noqa: F821
    """The noise-free narrow-kernel EVD from exact Laplace–Beltrami eigenvalues.

    Parameters
    ----------
    mu_unit : (k,) float
        The ``k`` smallest eigenvalues of the mesh scaled to unit area (``mu_unit[0] ≈ 0``).
    area : float
        The mesh's own surface area (used by ``abs:S`` widths only).
    width : str
        ``area:ρ`` (σ = ρ √area, scale invariant) or ``abs:S`` (σ = S, size-aware).

    Returns
    -------
    evd : (k,) float64
        :func:`geoshape.retrieval.descriptors.evd.heat_limit_evd` at ``ρ``, or at ``S / √area``. O(k).
    """
    import numpy as np

    from geoshape.retrieval.descriptors.evd import heat_limit_evd

    kind, rho = parse_width(width)
    if kind not in ("area", "abs"):
        from geoshape.errors import InvalidOptionError

        raise InvalidOptionError(f"reference rows take area:RHO or abs:S widths, got {width!r}")
    return heat_limit_evd(mu_unit, rho if kind == "area" else rho / np.sqrt(area))


def most_confused_pair(D, labels) -> tuple[str, str, int]:
    """The two classes whose members most often enter each other's first tier.

    Returns ``(a, b, count)`` with ``a < b``; ``count`` sums, over every query of ``a``
    or ``b``, the first-tier items of the other class. O(N^2 log N).
    """
    import collections

    import numpy as np

    labels = np.asarray(labels)
    sizes = collections.Counter(labels.tolist())
    counts: collections.Counter = collections.Counter()
    Dq = np.array(D, dtype=np.float64)
    np.fill_diagonal(Dq, np.inf)
    order = np.argsort(Dq, axis=1, kind="stable")
    for i, row in enumerate(order):
        tier = row[: sizes[labels[i]] - 1]
        for other in labels[tier][labels[tier] != labels[i]].tolist():
            counts[tuple(sorted((str(labels[i]), str(other))))] += 1
    if not counts:
        return "", "", 0
    (a, b), c = counts.most_common(1)[0]
    return a, b, c


def class_separation(values, labels, a: str, b: str) -> tuple[np.ndarray, np.ndarray]:  # noqa: F821
    """Per column of ``values (N, k)``: the relative gap ``|mean_a / mean_b − 1|`` between
    classes ``a`` and ``b``, and their mean coefficient of variation (std / mean within
    each class, averaged over the two). Both ``(k,)``; NaN where a class mean is 0 or a
    class is missing. O(N k)."""
    import numpy as np

    X = np.asarray(values, dtype=np.float64)
    X = X[:, None] if X.ndim == 1 else X
    labels = np.asarray(labels).astype(str)
    A, B = X[labels == str(a)], X[labels == str(b)]
    if len(A) == 0 or len(B) == 0:
        return np.full(X.shape[1], np.nan), np.full(X.shape[1], np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):  # a zero mean: inf or nan, reported as nan
        gap = np.abs(A.mean(0) / B.mean(0) - 1.0)
        spread = 0.5 * (A.std(0) / A.mean(0) + B.std(0) / B.mean(0))
    return np.where(np.isfinite(gap), gap, np.nan), np.where(np.isfinite(spread), spread, np.nan)


def _separation_table(named_values, labels, a: str, b: str) -> str:
    """Markdown table: per band of columns, the mean class gap, mean spread and their ratio.

    ``named_values``: ``(name, values (N, k), bands)`` triples; ``bands`` lists inclusive
    ``(first, last)`` column ranges (``None``: the single column 0).
    """
    import numpy as np

    from geoshape.bench.results import markdown_table

    def pct(x):
        return f"{100 * x:.1f} %" if np.isfinite(x) else "n/a"

    def ratio(g, w):
        return f"{g / w:.2f}" if np.isfinite(g) and np.isfinite(w) and w > 0 else "n/a"

    rows = []
    for name, values, bands in named_values:
        gap, spread = class_separation(values, labels, a, b)
        for lo, hi in bands or [(0, 0)]:
            g, w = float(gap[lo:hi + 1].mean()), float(spread[lo:hi + 1].mean())
            rows.append([name if bands is None else f"{name}, {lo}–{hi}", pct(g), pct(w), ratio(g, w)])
    return markdown_table([f"{a} vs {b}", "gap of class means", "spread within a class",
                           "gap / spread"], rows)


def run(args: argparse.Namespace) -> int:
    import time

    import numpy as np
    from tqdm import tqdm

    from geoshape.bench.experiments._common import machine_note
    from geoshape.bench.results import markdown_table, update_results_section
    from geoshape.io.datasets import dataset_dir, read_labels
    from geoshape.io.mesh_io import load_mesh
    from geoshape.metrics.retrieval import (
        first_tier,
        first_tier_by_class,
        mean_average_precision,
        nearest_neighbor,
    )
    from geoshape.parallel import single_thread_blas
    from geoshape.retrieval.descriptors.evd import EVD_N_SAMPLES, evd_distance_matrix
    from geoshape.spectral.laplacian import laplacian_basis

    folder = dataset_dir("tosca_r5k", required=True) if args.dir is None else args.dir
    samples = sorted({int(x) for x in str(args.samples).split(",") if x.strip()})
    widths = [w.strip() for w in str(args.widths).split(",") if w.strip()]
    for w in widths:
        parse_width(w)
    items = read_labels(folder)
    files, labels = [it.path for it in items], [it.label for it in items]
    t0 = time.perf_counter()
    with single_thread_blas():
        cache, mu_unit = [], []
        for f in tqdm(files, desc="samples", unit="mesh"):
            V, F = load_mesh(f)
            cache.append(mesh_samples(V, F, max(samples), samples))
            mu_unit.append(laplacian_basis(V, F, k=N_EIGENVALUES).evals)
        mu_unit = np.array(mu_unit)
        areas = np.array([s["area"] for s in cache])
        rows, by_class = [], {}
        focus = ref = None  # (name, EVDs, distances) of the default row (else the first); (width, EVDs)
        for l in samples:
            for width in widths:
                for weighted in (False, True):
                    X = np.array([evd_from_samples(s, l, width, weighted) for s in cache])
                    D = evd_distance_matrix(X)
                    default = l == EVD_N_SAMPLES and width == "area:0.1" and weighted
                    thesis = l == 60 and width == "max" and not weighted
                    note = "library default" if default else "thesis" if thesis else ""
                    if width.startswith("abs"):
                        note = "size-aware (not scale invariant)"
                    rows.append([l, width, "area" if weighted else "none",
                                 nearest_neighbor(D, labels), first_tier(D, labels),
                                 mean_average_precision(D, labels), note])
                    by_class[(l, width, weighted)] = first_tier_by_class(D, labels)
                    if default or focus is None:
                        name = "library default" if default else f"l = {l}, {width}, weights " + (
                            "area" if weighted else "none")
                        focus = (name, X, D)
        for width in [w for w in widths if w.startswith(("area", "abs"))]:
            X = np.array([reference_evd(mu, area, width) for mu, area in zip(mu_unit, areas, strict=True)])
            D = evd_distance_matrix(X)
            note = ("exact Laplace–Beltrami spectrum, "
                    + ("size-aware" if width.startswith("abs") else "scale invariant"))
            rows.append(["exact", width, "(heat limit)", nearest_neighbor(D, labels),
                         first_tier(D, labels), mean_average_precision(D, labels), note])
            by_class[("exact", width, False)] = first_tier_by_class(D, labels)
            if width.startswith("area") and (ref is None or width == "area:0.1"):
                ref = (width, X)
    seconds = time.perf_counter() - t0
    table = markdown_table(["l", "width", "weights", "NN", "FT", "mAP", ""], rows)
    invariant = [r for r in rows if not str(r[1]).startswith("abs") and r[0] != "exact"]
    best = max(invariant, key=lambda r: (r[4], r[3]))
    shown = [("library default", (EVD_N_SAMPLES, "area:0.1", True)),
             (f"best scale-invariant row (l = {best[0]}, {best[1]}, weights {best[2]})",
              (best[0], best[1], best[2] == "area")),
             ("exact spectrum, scale invariant (area:0.1)", ("exact", "area:0.1", False))]
    lines = []
    for name, key in shown:
        if key in by_class:
            lines.append(f"- {name}: " + ", ".join(f"{c} {v:.3f}" for c, v in by_class[key].items()))
    a, b, confused = most_confused_pair(focus[2], labels)
    separation = ""
    if confused:
        k = mu_unit.shape[1]
        bands = [(lo, min(hi, k - 1)) for lo, hi in ((1, 5), (6, 10), (11, k - 1)) if lo <= k - 1]
        named = [("Laplace–Beltrami μ, unit area", mu_unit, bands)]
        if ref is not None:
            named.append((f"exact reference EVD ({ref[0]}), entries", ref[1], bands))
        named += [(f"sampled EVD ({focus[0]}), entries", focus[1], bands),
                  ("size √area", np.sqrt(areas), None)]
        separation = (
            f"\n\nThe most confused classes of the {focus[0]} row are {a} and {b} ({confused} "
            "first-tier places taken by the other class). Per band of eigenvalues (entry i of an "
            "EVD belongs to μ_i), the gap between the two class means against the spread of one "
            "class over its poses (coefficient of variation), averaged over the band and the two "
            "classes:\n\n" + _separation_table(named, labels, a, b) + "\n")
    text = (f"## EVD settings on tosca_r5k (thesis §4.6.2)\n\nCommand: `geoshape bench evd` "
            f"({seconds:.0f} s; {machine_note()}). {len(files)} meshes, {len(set(labels))} classes; "
            "graph geodesics, 20 eigenvalues, χ² distance. Widths: `max` = largest sampled geodesic "
            "distance, `mean:ρ` = ρ × mean sampled distance, `area:ρ` = ρ × √area, `abs:S` = S in the "
            "meshes' units (depends on size, so not scale invariant). Weights `area`: "
            "each sample weighted by its geodesic Voronoi cell (the eigenvalues then approximate "
            "the affinity operator's). Rows `exact`: the narrow-kernel (heat-kernel) limit "
            "computed from the exact Laplace–Beltrami eigenvalues, no sampling or geodesic error "
            "(see `geoshape.bench.evd.reference_evd`).\n\n" + table + "\n\nFirst tier per class:\n\n"
            + "\n".join(lines) + separation + "\n")
    print(text)
    if not args.no_results:
        update_results_section("evd-settings", text)
    return 0
