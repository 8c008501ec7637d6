"""Non-isometric pairs with exact ground truth (``geoshape gen nonisometric``)."""

from __future__ import annotations

import numpy as np
import pytest
from geoshape_datasets_gen.articulated3d import build_template, make_skeleton
from geoshape_datasets_gen.nonisometric import FAMILIES, make_pair, mirror_map, reproportion

from geoshape.errors import InvalidOptionError


@pytest.fixture(scope="module")
def templates():
    return {c: build_template(make_skeleton(c), target_vertices=900, resolution=64) for c in FAMILIES}


def _volume(V, F):
    return float(np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6.0)


def _area(V, F):
    T = V[F]
    return float(0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1).sum())


def test_unit_factors_keep_the_template(templates):
    for tpl in templates.values():
        same = reproportion(tpl, {})
        np.testing.assert_allclose(same.V, tpl.V, atol=1e-12)
        np.testing.assert_allclose(same.skeleton.positions, tpl.skeleton.positions)


def test_biped_arms_differ_with_exact_ids(templates):
    tpl = templates["biped"]
    p = make_pair(tpl, ("long-armed", "short-armed"), seed=1)
    assert p.source.shape == p.target.shape == tpl.V.shape
    assert p.F is tpl.F
    long_rest, short_rest = (r.V for r in p.rest)
    # the finger tips of the T-pose (same vertex ids in both): arm span differs, height does not
    i, j = int(np.argmax(tpl.V[:, 0])), int(np.argmin(tpl.V[:, 0]))
    span = [np.linalg.norm(R[i] - R[j]) for R in (long_rest, short_rest)]
    assert span[0] / span[1] > 1.3
    top, bottom = int(np.argmax(tpl.V[:, 1])), int(np.argmin(tpl.V[:, 1]))
    height = [np.linalg.norm(R[top] - R[bottom]) for R in (long_rest, short_rest)]
    assert abs(height[0] / height[1] - 1) < 0.02
    # the poses differ too, and the pair is not isometric (edge lengths change)
    E = tpl.F[:, :2]
    ratio = np.linalg.norm(p.target[E[:, 0]] - p.target[E[:, 1]], axis=1) / np.linalg.norm(
        p.source[E[:, 0]] - p.source[E[:, 1]], axis=1)
    assert np.percentile(np.abs(np.log(ratio)), 90) > 0.15


def test_quadruped_heavy_vs_slim(templates):
    tpl = templates["quadruped"]
    p = make_pair(tpl, ("heavy", "slim"), seed=2)
    heavy, slim = (r.V for r in p.rest)
    assert _volume(heavy, tpl.F) / _volume(slim, tpl.F) > 1.8
    assert _area(p.source, tpl.F) / _area(p.target, tpl.F) > 1.15
    # legs: longer on the slim family (lowest vertex of the rest template, same id)
    low = int(np.argmin(tpl.V[:, 1]))
    assert heavy[low, 1] > slim[low, 1]


def test_mirror_map_is_a_near_involution(templates):
    for cls, axis in (("biped", 0), ("quadruped", 2)):
        tpl = templates[cls]
        sym = mirror_map(tpl.V, tpl.F, axis)
        mirrored = tpl.V[sym] * np.where(np.arange(3) == axis, -1.0, 1.0)
        edge = np.linalg.norm(tpl.V[tpl.F[:, 0]] - tpl.V[tpl.F[:, 1]], axis=1).max()
        assert np.linalg.norm(mirrored - tpl.V, axis=1).max() <= edge
        assert np.mean(sym[sym] == np.arange(len(sym))) > 0.5


def test_make_pair_refuses_bad_families(templates):
    with pytest.raises(InvalidOptionError):
        make_pair(templates["biped"], ("heavy", "slim"), seed=0)
    with pytest.raises(InvalidOptionError):
        make_pair(templates["biped"], ("long-armed", "short-armed"), seed=0, jitter=1.0)


def _main(argv):
    from geoshape.__main__ import main

    return main(argv)


def test_cli_nonisometric_layout_and_determinism(tmp_path, capsys):
    import json

    from geoshape.io.datasets import read_labels, read_pairs
    from geoshape.io.mesh_io import load_mesh

    out = tmp_path / "ni"
    argv = ["gen", "nonisometric", "--pairs", "2", "--templates", "1", "--vertices", "600",
            "--resolution", "64", "--seed", "5"]
    assert _main([*argv, "--out", str(out)]) == 0
    pairs = read_pairs(out)
    assert len(pairs) == 2 and len(read_labels(out)) == 4
    meta = json.loads((out / "generator.json").read_text())
    assert "identity" in meta["ground_truth"]
    for pair, detail in zip(pairs, meta["pair_details"], strict=True):
        Vs, Fs = load_mesh(pair.source)
        Vt, Ft = load_mesh(pair.target)
        assert len(Vs) == len(Vt) and np.array_equal(Fs, Ft)
        assert np.array_equal(pair.source_landmarks, np.arange(len(Vs)))
        assert np.array_equal(pair.target_landmarks, pair.source_landmarks)
        assert len(pair.target_symmetric_landmarks) == len(Vs)
        r = detail["target_over_source"]
        key = "arm" if "biped" in detail["template"] else "body"
        what = "length" if key == "arm" else "thickness"
        assert abs(np.log(r[key][what])) > 0.3  # long vs short arms, heavy vs slim bodies
    again = tmp_path / "again"
    assert _main([*argv, "--out", str(again)]) == 0
    for f in out.iterdir():
        if f.is_file():
            assert f.read_bytes() == (again / f.name).read_bytes()
    capsys.readouterr()
    for bad in (["--pairs", "0"], ["--classes", "hand"], ["--jitter", "0.5"], ["--vertices", "10"],
                ["--families", "biped=ape-like"], ["--families", "biped=ape-like:gorilla"],
                ["--families", "hand=ape-like:human-like"], ["--families", "biped=ape-like:ape-like"]):
        assert _main(["gen", "nonisometric", *bad, "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "error" in err
    assert not (tmp_path / "bad").exists()


def test_ape_like_against_human_like_bipeds(tmp_path):
    """The gorilla-like family of the held-out non-isometric benchmark: chosen per class with
    ``paired_families``, exact ground truth kept, and far from isometric (arms longer, legs shorter,
    every part thicker than the human-like body)."""
    import json

    from geoshape_datasets_gen.nonisometric import write_nonisometric_set

    from geoshape.io.datasets import read_pairs
    from geoshape.io.mesh_io import load_mesh

    res = write_nonisometric_set(tmp_path, n_pairs=2, classes=("biped",), templates=1, target_vertices=600,
                                 resolution=64, paired_families={"biped": ("ape-like", "human-like")})
    meta = json.loads((tmp_path / "generator.json").read_text())
    assert meta["paired_families"] == {"biped": ["ape-like", "human-like"]}
    details = meta["pair_details"]
    assert [d["families"] for d in details] == [["ape-like", "human-like"], ["human-like", "ape-like"]]
    r = details[0]["target_over_source"]  # human-like over ape-like
    assert r["arm"]["length"] < 0.85 and r["leg"]["length"] > 1.3
    assert all(r[g]["thickness"] < 0.8 for g in ("arm", "leg", "torso"))
    for pair in read_pairs(tmp_path):
        Vs, Fs = load_mesh(pair.source)
        Vt, Ft = load_mesh(pair.target)
        assert np.array_equal(Fs, Ft) and np.array_equal(pair.source_landmarks, pair.target_landmarks)
    assert len(res["pairs"]) == 2

