"""The options of the ``geoshape`` correspondence method (``GeoshapeOptions``): checked before
any work, frozen, every field documented; and the stage records of the pipeline."""

from __future__ import annotations

import ast
import dataclasses
import inspect
from types import SimpleNamespace

import numpy as np
import pytest

import geoshape.correspondence.mesh_matching as mm
import geoshape.correspondence.pipeline as pipeline
from geoshape.correspondence.pipeline import Candidate, GeoshapeOptions
from geoshape.correspondence.reorder import Alignment
from geoshape.errors import InvalidOptionError
from geoshape.geometry.knn import KNNIndex, nearest


def _octahedron():
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return V, F


@pytest.fixture
def no_work(monkeypatch):
    """Every step after the option check raises: preparing a mesh and running a stage."""

    def forbidden(*args, **kwargs):
        raise AssertionError("work started before the options were checked")

    monkeypatch.setattr(mm, "_prepared", forbidden)
    monkeypatch.setattr(mm, "run_geoshape", forbidden)
    monkeypatch.setattr(pipeline, "candidate_alignments", forbidden)


def test_unknown_option_fails_before_any_work_naming_the_valid_ones(no_work):
    V, F = _octahedron()
    with pytest.raises(InvalidOptionError) as info:
        mm.correspond(V, F, V, F, method="geoshape", lb_kk=40)
    message = str(info.value)
    assert "unexpected keyword" in message and "'lb_kk'" in message
    assert "did you mean 'lb_k'" in message
    assert "valid options: " + ", ".join(GeoshapeOptions.names()) in message
    with pytest.raises(InvalidOptionError, match="'frobnicate'.*valid options: k, reorder"):
        mm.correspond(V, F, V, F, frobnicate=3)  # geoshape is the default method
    with pytest.raises(InvalidOptionError, match="'anchors'"):  # an option of jz, not of geoshape
        mm.correspond(V, F, V, F, anchors=3)


def test_unknown_option_leaves_prepared_meshes_untouched(monkeypatch):
    V, F = _octahedron()
    V = np.vstack([V, 0.5 * V])  # enough vertices for a PreparedMesh
    F = np.vstack([F, F + 6])
    m1, m2 = mm.PreparedMesh(V, F), mm.PreparedMesh(V, F)
    with pytest.raises(InvalidOptionError, match="valid options"):
        mm.correspond(m1, m2, zoomout_sample=100)
    assert not m1._cache and not m2._cache


def test_misspelled_prefer_fails_with_the_valid_choices(no_work):
    V, F = _octahedron()
    expected = "prefer must be one of 'preserving', 'reversing'; got 'preserve'"
    with pytest.raises(InvalidOptionError, match=expected):
        mm.correspond(V, F, V, F, prefer="preserve")
    with pytest.raises(InvalidOptionError, match="'preserving', 'reversing'"):
        GeoshapeOptions(prefer="Reversing")


@pytest.mark.parametrize("name, value", [
    ("lb_k", 0), ("lb_k", 2.5), ("k", True), ("n_refine", -1), ("seed", -1), ("n_samples", 0),
    ("symmetry_completion", "yes"), ("descriptor_map", 1), ("distortion_samples", 0),
    ("distortion_samples", 1.5), ("descriptor_k", "30"), ("reorder", "random"),
    ("distinct_spacing", -0.5), ("distinct_spacing", float("nan")), ("distinct_spacing", "1"),
    ("distinct_spacing", True), ("distortion_power", 0.25), ("distortion_power", "2"),
    ("soft_temperature", -0.5), ("soft_temperature", float("inf")), ("soft_rings", 0), ("soft_rings", 2.5),
    ("final_vertices_per_eigenpair", 0.5), ("final_vertices_per_eigenpair", float("nan")),
])
def test_values_of_the_wrong_type_or_range_fail(no_work, name, value):
    V, F = _octahedron()
    with pytest.raises(InvalidOptionError, match=name):
        mm.correspond(V, F, V, F, **{name: value})


def test_options_are_frozen_and_checked_again_when_replaced():
    options = GeoshapeOptions()
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.lb_k = 30
    with pytest.raises(InvalidOptionError, match="prefer"):
        dataclasses.replace(options, prefer="mirror")
    changed = dataclasses.replace(options, prefer="reversing", symmetry_completion=False)
    assert (changed.prefer, changed.symmetry_completion, options.prefer) == ("reversing", False, "preserving")


def test_defaults_and_accepted_values():
    options = GeoshapeOptions.from_options({})
    assert options == GeoshapeOptions()
    assert len(GeoshapeOptions.names()) == 31
    assert (options.k, options.lb_k, options.n_keep, options.prefer, options.n_samples) == (
        5, 60, 8, "preserving", None)
    numpy_values = GeoshapeOptions(lb_k=np.int64(40), distortion_samples=np.int32(64),
                                   descriptor_map=np.bool_(False))
    assert numpy_values.lb_k == 40 and not numpy_values.descriptor_map
    assert GeoshapeOptions(n_refine=0, icp_iterations=0, n_samples=300).n_refine == 0
    assert GeoshapeOptions(distinct_spacing=0).distinct_spacing == 0
    assert GeoshapeOptions(distinct_spacing=np.float32(2.0)).distinct_spacing == 2.0


def test_every_option_has_a_one_line_docstring():
    """Each field of GeoshapeOptions is followed by a one-line string saying what it is."""
    tree = ast.parse(inspect.getsource(GeoshapeOptions))
    body = tree.body[0].body
    documented = {}
    for node, after in zip(body, body[1:], strict=False):
        if (isinstance(node, ast.AnnAssign) and isinstance(after, ast.Expr)
                and isinstance(after.value, ast.Constant)):
            documented[node.target.id] = after.value.value
    assert set(documented) == set(GeoshapeOptions.names())
    assert all(doc and "\n" not in doc.strip() for doc in documented.values())


def test_candidate_summary_keeps_the_alternatives_fields():
    """The JSON of ``geoshape correspond --json`` lists these fields, in this order."""
    spectral = Candidate(alignment=Alignment((1, 0), (1, -1), 2.5), coarse_map=np.zeros(3, dtype=np.int64),
                         zoomout_energy=0.1, orientation=0.3)
    assert list(spectral.summary()) == ["perm", "signs", "cost", "zoomout_energy", "orientation"]
    assert spectral.cost == 2.5 and not spectral.refined
    spectral.refined_map, spectral.refined_energy, spectral.refined_orientation = np.zeros(3), 0.05, 0.8
    assert list(spectral.summary())[-2:] == ["refined_energy", "refined_orientation"]
    spectral.coarse_distortion = 0.2
    assert list(spectral.summary())[5] == "coarse_distortion"
    assert pipeline.screening_score(spectral) == pytest.approx(0.02)
    spectral.coarse_curvature = 0.5
    assert list(spectral.summary())[6] == "coarse_curvature"
    assert pipeline.screening_score(spectral) == pytest.approx(0.01)
    descriptors = Candidate(source="descriptors", refined_map=np.zeros(3), refined_energy=0.04,
                            refined_orientation=0.7)
    assert descriptors.summary() == {"source": "descriptors", "refined_energy": 0.04,
                                     "refined_orientation": 0.7}
    assert descriptors.cost is None


def test_decision_prefers_the_wanted_orientation_then_the_lowest_score():
    def refined(energy, distortion, unwanted, source="spectral"):
        return Candidate(source=source, refined_map=np.zeros(2, dtype=np.int64), refined_energy=energy,
                         refined_orientation=-0.5 if unwanted else 0.5, unwanted=unwanted,
                         distortion=distortion)

    mirrored, direct, other = refined(0.01, 0.1, True), refined(0.03, 0.1, False), refined(0.05, 0.1, False)
    assert pipeline.decide([mirrored, other, direct]) is direct
    # distortion × energy: less distortion outweighs a little more energy, and the reverse
    smooth_but_wrong, right = refined(0.02, 0.30, False, "descriptors"), refined(0.03, 0.10, False)
    assert pipeline.decide([smooth_but_wrong, right]) is right
    assert pipeline.decision_score(right) == pytest.approx(0.003)
    # scaling either factor by the same amount for every candidate never changes the choice
    for scale in (0.1, 10.0):
        pool = [refined(c.refined_energy * scale, c.distortion, False) for c in (smooth_but_wrong, right)]
        assert pipeline.decide(pool) is pool[1]
    # nothing of the wanted orientation: the best mirrored map rather than nothing
    assert pipeline.decide([mirrored, refined(0.02, 0.1, True)]) is mirrored
    # a map mirrored on half the surface (orientation near 0, its sign barely right) counts
    # its distortion × energy per share of correctly oriented surface
    half_mirrored = dataclasses.replace(refined(0.02, 0.1, False), orientation_share=0.52)
    kept = dataclasses.replace(refined(0.025, 0.1, False), orientation_share=0.9)
    assert pipeline.decide([half_mirrored, kept]) is kept
    assert pipeline.decision_score(kept) == pytest.approx(0.0025 / 0.9)


def test_a_half_turn_as_isometric_as_the_right_map_loses_on_curvature():
    """Front↔back composed with left↔right keeps the orientation and, on a body, nearly the
    geodesics: here it is even a little less distorted and smoother than the right map, and
    only the curvature disagreement (toes on heels) tells them apart. Without that factor
    (exponent 0) the half-turn would win; a map whose curvature was not measured counts 1."""
    def refined(distortion, energy, curvature):
        return Candidate(refined_map=np.zeros(2, dtype=np.int64), refined_energy=energy,
                         refined_orientation=0.7, unwanted=False, orientation_share=0.85,
                         distortion=distortion, curvature_disagreement=curvature)

    right, half_turn = refined(0.0100, 0.030, 0.05), refined(0.0090, 0.028, 0.08)
    assert pipeline.decide([half_turn, right]) is right
    assert pipeline.decision_score(right) == pytest.approx(0.0100 * 0.030 * 0.05 / 0.85)
    assert pipeline.decide([half_turn, right], exponents=(1.0, 1.0, 0.0, 1.0)) is half_turn
    assert right.summary()["curvature_disagreement"] == 0.05
    unmeasured = dataclasses.replace(right, curvature_disagreement=None)
    assert pipeline.decision_score(unmeasured) == pytest.approx(0.0100 * 0.030 / 0.85)


def test_the_landmark_twins_are_decided_by_local_rigidity():
    """The repaired and the polished map come out of one landmark solve that fits geodesic
    distances: between the two, the more rigid wins whatever their scores; elsewhere
    rigidity plays no part."""
    def refined(source, score, rigidity, unwanted=False):
        return Candidate(source=source, refined_map=np.zeros(2, dtype=np.int64), refined_energy=score,
                         refined_orientation=-0.5 if unwanted else 0.5, unwanted=unwanted,
                         distortion=1.0, rigidity=rigidity)

    half_turn, right = refined("repaired", 0.01, 0.30), refined("polished", 0.02, 0.20)
    spectral = refined("spectral", 0.03, None)
    assert pipeline.decide([spectral, half_turn, right]) is right
    more_rigid_repair = dataclasses.replace(half_turn, rigidity=0.1)
    assert pipeline.decide([spectral, right, more_rigid_repair]) is more_rigid_repair
    # the polished map winning on the score gives way to a more rigid repaired map too
    repaired_right = refined("repaired", 0.03, 0.15)
    polished_turn = refined("polished", 0.01, 0.25)
    assert pipeline.decide([polished_turn, repaired_right]) is repaired_right
    # not measured (rigidity_patch = 0), or the twin is mirrored: the score decides
    assert pipeline.decide([half_turn, dataclasses.replace(right, rigidity=None)]) is half_turn
    assert pipeline.decide([half_turn, dataclasses.replace(right, unwanted=True)]) is half_turn
    # a spectral map that wins on the score is not second-guessed by the twins' rigidity
    best_spectral = refined("spectral", 0.001, None)
    assert pipeline.decide([best_spectral, half_turn, right]) is best_spectral


def test_local_rigidity_sees_a_front_back_half_turn_through_stretching():
    """A tube with one foot pointing forward; mesh 2 is another, denser sampling of it,
    stretched 1.5 × along the axis. Both maps are read off by nearest points: the direct one
    and the half-turn about the axis (front to back, left to right), which has to fold the
    foot onto the heel. Without the foot (a control) the two are equally rigid."""
    rng = np.random.default_rng(1)

    def body(n, foot):
        t, h = rng.uniform(0, 2 * np.pi, n), rng.uniform(0, 4, n)
        points = np.c_[np.cos(t), h, np.sin(t)]
        if foot:
            m = n // 6
            points = np.vstack([points, np.c_[rng.uniform(-0.3, 0.3, m), rng.uniform(0, 0.4, m),
                                              rng.uniform(1, 2, m)]])
        return points

    ratios = {}
    for foot in (True, False):
        X1, X2 = body(4000, foot), body(16000, foot) * [1.0, 1.5, 1.0]
        stretched = X1 * [1.0, 1.5, 1.0]
        direct = nearest(X2, stretched)[1]
        half_turn = nearest(X2, stretched * [-1.0, 1.0, -1.0])[1]
        patches = KNNIndex(X1).query(X1[::10], k=12)[1]
        ratios[foot] = (pipeline.local_rigidity(X1, X2[half_turn], patches)
                        / pipeline.local_rigidity(X1, X2[direct], patches))
    assert ratios[True] > 1.3 and abs(ratios[False] - 1) < 0.1


def test_measure_rigidity_fills_only_when_asked_and_sees_a_fold():
    """On a flat grid the identity is perfectly rigid; folding half the grid onto the other
    half is not; ``rigidity_patch = 0`` measures nothing."""
    grid = _grid_context(False)
    ctx = SimpleNamespace(m1=grid.m2, m2=grid.m2, s1=np.arange(441), large=False)
    x = np.arange(441) % 21
    folded_ids = np.arange(441) - x + np.where(x > 10, 20 - x, x)  # column x > 10 onto 20 − x
    identity = Candidate(source="repaired", refined_map=np.arange(441))
    folded = Candidate(source="polished", refined_map=folded_ids)
    pipeline.measure_rigidity(ctx, [identity, folded], GeoshapeOptions(rigidity_patch=0), {})
    assert identity.rigidity is None and folded.rigidity is None
    timings = {}
    pipeline.measure_rigidity(ctx, [identity, folded], GeoshapeOptions(), timings)
    assert identity.rigidity == pytest.approx(0, abs=1e-9) and folded.rigidity > 0.01
    assert "rigidity" in timings and identity.summary()["rigidity"] == identity.rigidity


def _grid_context(large: bool):
    """A 21 × 21 unit grid (mesh 2 = mesh 1), its 441 vertices all screening samples."""
    from types import SimpleNamespace

    x, y = np.meshgrid(np.arange(21.0), np.arange(21.0))
    V = np.c_[x.ravel(), y.ravel(), np.zeros(441)]
    q = (np.arange(20)[:, None] * 21 + np.arange(20)[None, :]).ravel()
    F = np.vstack([np.c_[q, q + 1, q + 22], np.c_[q, q + 22, q + 21]])
    samples = np.arange(441)
    return SimpleNamespace(m2=mm.PreparedMesh(V, F), c1=samples, c2=samples, large=large)


@pytest.mark.parametrize("large", [False, True])
def test_refinement_goes_to_distinct_hypotheses(large):
    """Planted coarse maps on a grid whose sample spacing is 400 / 441 ≈ 0.95: a map, the same
    map moved by 0.5 (one hypothesis), the same moved by 2 (another), and its mirror image.
    The 2 refinement slots go to the first map and the mirror; the near-copies wait in order."""
    ctx = _grid_context(large)
    base = np.arange(441)
    i, j = np.divmod(base, 21)
    near = np.where(base % 2 == 0, base, i * 21 + np.minimum(j + 1, 20))  # half of them moved by 1
    far = i * 21 + np.clip(j + 2, 0, 20)
    mirror = i * 21 + (20 - j)
    ranked = [Candidate(coarse_map=m) for m in (base, near, mirror, far)]
    picked, rest = pipeline.distinct_hypotheses(ctx, ranked, 2, 1.0)
    assert picked == [ranked[0], ranked[2]] and rest == [ranked[1], ranked[3]]
    picked, rest = pipeline.distinct_hypotheses(ctx, ranked, 3, 1.0)
    assert picked == [ranked[0], ranked[2], ranked[3]] and rest == [ranked[1]]
    assert pipeline.distinct_hypotheses(ctx, ranked, 2, 0.0) == (ranked[:2], ranked[2:])  # off
    assert pipeline.distinct_hypotheses(ctx, ranked, 4, 3.0)[0] == [ranked[0], ranked[2]]  # coarser unit


def test_the_mirrored_fallback_skips_copies_of_refined_maps(monkeypatch):
    """Every refined map mirrored: the fallback refines the candidate of most wanted coarse
    orientation that is not a copy of a map already refined (a near-copy of the refined
    mirror, with a better coarse orientation score, waits)."""
    ctx = _grid_context(False)
    base = np.arange(441)
    i, j = np.divmod(base, 21)
    mirror = i * 21 + (20 - j)
    near_mirror = np.where(base % 2 == 0, mirror, i * 21 + np.maximum(20 - j - 1, 0))
    far = i * 21 + np.clip(j + 2, 0, 20)
    monkeypatch.setattr(pipeline, "refine_map", lambda *a, **k: (np.zeros(3, dtype=np.int64), 0.1, -0.8))
    ranked = [Candidate(coarse_map=m, orientation=o, zoomout_energy=0.1)
              for m, o in ((mirror, -0.9), (near_mirror, 0.5), (far, 0.2))]
    refined = pipeline.refine(ctx, ranked, GeoshapeOptions(n_refine=1), {})
    assert refined == [ranked[0], ranked[2]]  # the copy (coarse orientation 0.5) is skipped
    # with the rule off, the copy is refined, as before the rule
    off = pipeline.refine(ctx, [dataclasses.replace(c) for c in ranked],
                          GeoshapeOptions(n_refine=1, distinct_spacing=0.0), {})
    assert [c.orientation for c in off] == [-0.9, 0.5]


def test_refinement_records_the_share_of_the_asked_orientation(monkeypatch):
    monkeypatch.setattr(pipeline, "refine_map", lambda *a, **k: (np.zeros(3, dtype=np.int64), 0.1, 0.6))
    for prefer, share, unwanted in (("preserving", 0.8, False), ("reversing", 0.2, True)):
        c = pipeline._refine_into(None, Candidate(), None, GeoshapeOptions(prefer=prefer))
        assert c.orientation_share == pytest.approx(share) and c.unwanted is unwanted


def test_the_adding_stages_say_when_they_fire():
    """``repair_sources`` and ``may_complete_symmetry`` are the one home of the firing conditions
    the speculative full-resolution map is decided on: the repair re-solves the mirrored map
    of lowest decision score (here also the most isometric one); neither can fire without a
    map of the unwanted orientation."""
    def refined(energy, unwanted):
        return Candidate(refined_map=np.zeros(2, dtype=np.int64), refined_energy=energy, distortion=0.1,
                         refined_orientation=-0.5 if unwanted else 0.5, unwanted=unwanted)

    ctx = SimpleNamespace(lb_k=60)
    options = GeoshapeOptions()
    direct, worse_mirror, better_mirror = refined(0.01, False), refined(0.05, True), refined(0.02, True)
    assert pipeline.repair_sources(ctx, [direct, worse_mirror, better_mirror], options) == [better_mirror]
    assert pipeline.may_complete_symmetry([direct, worse_mirror], options)
    for pool in ([], [direct]):
        assert pipeline.repair_sources(ctx, pool, options) == []
        assert not pipeline.may_complete_symmetry(pool, options)
        assert pipeline.complete_symmetry(ctx, pool, options, {}) is None
        assert pipeline.orientation_repair(ctx, pool, options, {}) == []
    def changed(**kw):
        return dataclasses.replace(options, **kw)

    assert pipeline.repair_sources(ctx, [better_mirror], changed(orientation_repair=False)) == []
    assert pipeline.repair_sources(SimpleNamespace(lb_k=2), [better_mirror], options) == []  # < 3 eigenpairs
    assert not pipeline.may_complete_symmetry([better_mirror], changed(prefer="reversing"))
    assert not pipeline.may_complete_symmetry([better_mirror], changed(symmetry_completion=False))


def test_the_repair_also_takes_the_most_isometric_mirror_whatever_its_mirrored_share():
    """The repair keeps its source's landmark images and replaces its orientation: besides
    the mirrored map of best decision score (here a half-mirrored map, orientation -0.2, that
    leads only through its share) it re-solves the most isometric one (a torso-only mirror,
    orientation -0.7), whatever the order of the pool; one map when both are the same."""
    def mirror(distortion, orientation):
        c = Candidate(refined_map=np.zeros(2, dtype=np.int64), refined_energy=0.02, distortion=distortion)
        return pipeline._store_refined(c, (c.refined_map, 0.02, orientation), GeoshapeOptions())

    torso_only, half_mirrored = mirror(0.0083, -0.7), mirror(0.0094, -0.2)
    assert torso_only.unwanted and half_mirrored.unwanted
    assert pipeline.decision_score(half_mirrored) < pipeline.decision_score(torso_only)
    ctx = SimpleNamespace(lb_k=60)
    for pool in ([torso_only, half_mirrored], [half_mirrored, torso_only]):
        assert pipeline.repair_sources(ctx, pool, GeoshapeOptions()) == [half_mirrored, torso_only]
    assert pipeline.repair_sources(ctx, [torso_only, mirror(0.0094, -0.8)], GeoshapeOptions()) == [torso_only]


def test_the_repair_sources_ignore_the_curvature_factor():
    """A clean left↔right mirror carries curvature over as well as the right map (low
    disagreement), a torso-only front↔back mirror does not; the repair replaces exactly that,
    so the sources are the ones the other factors pick (the torso-only mirror, whose repair
    is the direct map), however the curvatures compare."""
    def mirror(distortion, orientation, curvature):
        c = Candidate(refined_map=np.zeros(2, dtype=np.int64), refined_energy=0.02, distortion=distortion,
                      curvature_disagreement=curvature)
        return pipeline._store_refined(c, (c.refined_map, 0.02, orientation), GeoshapeOptions())

    torso_only, clean = mirror(0.0083, -0.25, 0.09), mirror(0.0089, -0.66, 0.015)
    assert pipeline.decision_score(clean) < pipeline.decision_score(torso_only)  # through curvature
    ctx = SimpleNamespace(lb_k=60)
    assert pipeline.repair_sources(ctx, [clean, torso_only], GeoshapeOptions()) == [torso_only]


@pytest.mark.slow
def test_orientation_repair_turns_a_front_back_mirror_into_the_direct_map(monkeypatch):
    """A planted mirrored candidate: a standing figure matched to itself through its front↔back
    reflection (hands and head stay, the feet point backwards). Re-solved with the
    orientation term, pinned by its own landmarks, it becomes the orientation-preserving map
    through the same ends: the identity."""
    from geoshape_datasets_gen.articulated3d import generate_figure

    from geoshape.correspondence.mesh_matching import PreparedMesh
    from geoshape.geometry.knn import nearest

    fig = generate_figure("biped", poses=1, seed=3, target_vertices=900, resolution=64)
    V, F = fig.poses[0], fig.F
    m1, m2 = PreparedMesh(V, F), PreparedMesh(V.copy(), F.copy())
    options = GeoshapeOptions()
    A, B, _ = pipeline.candidate_alignments(m1, m2, options, {})
    ctx = pipeline.pair_context(m1, m2, A, B, options, {})
    front_back = nearest(V * [1, 1, -1], V)[1]  # the figure faces +z
    size = np.ptp(V, axis=0).max()
    mirrored = Candidate(refined_map=front_back, refined_energy=1.0, distortion=1.0, unwanted=True,
                         refined_orientation=pipeline.orientation_of(ctx, front_back, ctx.s1))
    assert mirrored.refined_orientation < -0.5
    assert np.median(np.linalg.norm(V[front_back] - V, axis=1)) > 0.05 * size
    direct = Candidate(refined_map=np.arange(len(V)), refined_energy=0.5, distortion=0.5, unwanted=False)

    [repaired] = pipeline.orientation_repair(ctx, [direct, mirrored], options, {})
    assert repaired.source == "repaired" and not repaired.unwanted and repaired.refined_orientation > 0.5
    assert np.median(np.linalg.norm(V[repaired.refined_map] - V, axis=1)) < 0.02 * size
    # the repaired map would win (lower score than the direct one): the direct map goes through
    # the same solve (like against like), and the exact map stays exact
    repaired.distortion, repaired.refined_energy = 0.1, 0.1  # score 0.01 against the direct map's 0.25
    [polished] = pipeline.polish_against_repair(ctx, [direct, mirrored, repaired], options, {})
    assert polished.source == "polished" and not polished.unwanted
    assert np.median(np.linalg.norm(V[polished.refined_map] - V, axis=1)) < 0.02 * size
    # no polish when the repair would not win, or when it is off
    repaired.distortion, repaired.refined_energy = 10.0, 1.0
    assert pipeline.polish_against_repair(ctx, [direct, mirrored, repaired], options, {}) == []
    repaired.distortion, repaired.refined_energy = 0.1, 0.1
    off = dataclasses.replace(options, polish_wanted=False)
    assert pipeline.polish_against_repair(ctx, [direct, mirrored, repaired], off, {}) == []
    # large-mesh mode: maps live on the refinement samples; the same repair
    monkeypatch.setattr(pipeline, "LARGE_MESH", 500)
    small = dataclasses.replace(options, zoomout_samples=400, screen_samples=200)
    ctx_large = pipeline.pair_context(m1, m2, A, B, small, {})
    assert ctx_large.large
    s1 = ctx_large.s1
    on_samples = [dataclasses.replace(c, refined_map=c.refined_map[s1]) for c in (direct, mirrored)]
    [repaired_large] = pipeline.orientation_repair(ctx_large, on_samples, small, {})
    assert repaired_large.refined_map.shape == s1.shape and repaired_large.refined_orientation > 0.5
    assert np.median(np.linalg.norm(V[repaired_large.refined_map] - V[s1], axis=1)) < 0.02 * size
    # nothing mirrored, or the stage turned off: no repair
    assert pipeline.orientation_repair(ctx, [direct], options, {}) == []
    off = dataclasses.replace(options, orientation_repair=False)
    assert pipeline.orientation_repair(ctx, [direct, mirrored], off, {}) == []


@pytest.mark.parametrize(("n1", "n2", "expected"), [
    (5000, 5000, 100),     # resolution bound: one eigenpair per 50 vertices
    (4999, 5010, 100),     # rounded to the final_step grid, not cut to 95
    (4344, 4344, 85),
    (12500, 12500, 210),   # cost bound: 150 * sqrt(25000 / 12500) = 212
    (27894, 27894, 140),
    (50000, 5000, 100),    # resolution from the smaller mesh, cost from the larger (106)
    (900, 900, 60),        # too small for a final ZoomOut: lb_k
])
def test_final_basis_grows_with_resolution_at_constant_cost(n1, n2, expected):
    from geoshape.correspondence.pipeline import final_basis_size

    assert final_basis_size(SimpleNamespace(n=n1), SimpleNamespace(n=n2), GeoshapeOptions()) == expected


def test_final_basis_is_off_at_final_k_zero_and_clipped_to_the_mesh():
    from geoshape.correspondence.pipeline import final_basis_size

    off = GeoshapeOptions(lb_k=30, final_k=0)
    assert final_basis_size(SimpleNamespace(n=20000), SimpleNamespace(n=20000), off) == 30
    # a cost bound under lb_k on a large mesh also leaves the refined basis (no special case)
    small = GeoshapeOptions(lb_k=60, final_k=40)
    assert final_basis_size(SimpleNamespace(n=25000), SimpleNamespace(n=25000), small) == 60
    # ... while on a small mesh the same final_k grows past lb_k (it is a bound at 25k vertices)
    assert final_basis_size(SimpleNamespace(n=2500), SimpleNamespace(n=2500),
                            GeoshapeOptions(lb_k=30, final_k=40, final_vertices_per_eigenpair=10.0)) == 125
    fine = GeoshapeOptions(final_vertices_per_eigenpair=1.0)
    # at most n - 1 of either mesh
    assert final_basis_size(SimpleNamespace(n=200), SimpleNamespace(n=120), fine) == 119


def test_screening_ranks_by_the_decision_objective_without_orientation():
    """The coarse curvature disagreement multiplies the screening score like the refined one
    multiplies the decision's: of two coarse maps of equal stress and energy, the one that
    carries the curvature field over is refined first; an unmeasured one counts 1."""
    right = Candidate(coarse_map=np.zeros(3, dtype=np.int64), zoomout_energy=0.1, coarse_distortion=0.2,
                      coarse_curvature=0.05)
    half_turn = dataclasses.replace(right, coarse_curvature=0.4)
    assert sorted([half_turn, right], key=pipeline.screening_score)[0] is right
    assert pipeline.screening_score(dataclasses.replace(right, coarse_curvature=None)) == pytest.approx(0.02)
    assert pipeline.screening_score(right) == pytest.approx(0.001)
