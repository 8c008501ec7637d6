"""Mirror-aware 2D matching: the default method matches both orientations; the off switch
(``mirror=False`` in the API, ``--method default_nomirror`` on the command line) matches the
direct orientation only, with everything else the default's."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.contour.methods import CONTOUR_METHODS, match_contours, method_spec
from geoshape.contour.retrieval import shape_distance_matrix
from geoshape.geometry.contour import mirror_contour

#: The default's matcher with mirror images off (the same starts per orientation).
DIRECT_ONLY = dict(mirror=False, n_starts=CONTOUR_METHODS["default"]["matcher_options"]["n_starts"])


@pytest.fixture(scope="module")
def contours():
    from geoshape_datasets_gen.silhouettes2d import articulated_silhouette

    from geoshape.geometry.contour import extract_contour

    return [extract_contour(articulated_silhouette(cls, seed=s), n_points=60)
            for cls, s in (("quadruped", 1), ("quadruped", 2), ("person", 3), ("crab", 4),
                           ("hand", 5))]


def _mirrored_copy(P):
    """A mirror image of ``P``, rotated, scaled and starting at another point."""
    th = 0.7
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    return np.roll(1.8 * mirror_contour(P) @ R.T + [5.0, -3.0], 11, axis=0)


def test_default_matches_mirror_images():
    spec = method_spec("default")
    assert spec["mirror"] is True
    off = method_spec("default", mirror=False)
    old = method_spec("default_nomirror")
    for key, value in DIRECT_ONLY.items():
        assert off.get(key, off["matcher_options"].get(key)) == value
        assert old.get(key, old["matcher_options"].get(key)) == value
    assert old["parts"] == spec["parts"] and old["matcher"] == spec["matcher"]
    assert old["matcher_options"] == spec["matcher_options"] == off["matcher_options"]


def test_mirrored_silhouette_retrieves_its_original_first(contours):
    query = _mirrored_copy(contours[0])
    D = shape_distance_matrix([*contours, query], backend="serial")
    assert int(np.argmin(D[-1, :-1])) == 0
    assert D[-1, 0] < 0.2 * np.sort(D[-1, :-1])[1]
    _, cost = match_contours(query, contours[0])
    assert cost <= D[-1, 0] + 1e-12 and cost < 0.2 * np.sort(D[-1, :-1])[1]


def test_off_switch_is_the_direct_orientation_only(contours):
    query = _mirrored_copy(contours[0])
    shapes = [*contours, query]
    on = shape_distance_matrix(shapes, backend="serial")
    off = shape_distance_matrix(shapes, backend="serial", mirror=False)
    named = shape_distance_matrix(shapes, "default_nomirror", backend="serial")
    explicit = shape_distance_matrix(shapes, backend="serial", **DIRECT_ONLY)
    assert np.array_equal(off, named) and np.array_equal(off, explicit)
    assert off[-1, 0] > 3 * on[-1, 0]  # without mirror images the reflection is far
    assert (on <= off + 1e-12).all()  # here no pair is worse with both orientations


def test_cli_default_and_off_switch(tmp_path):
    from geoshape_datasets_gen.silhouettes2d import generate_silhouettes
    from PIL import Image

    from geoshape.__main__ import main

    generate_silhouettes(tmp_path, per_class=2, classes=("quadruped", "person", "crab"), seed=0)
    src = tmp_path / "quadruped_0.png"
    Image.open(src).transpose(Image.Transpose.FLIP_LEFT_RIGHT).save(tmp_path / "flipped.png")
    labels = tmp_path / "labels.csv"
    labels.write_text(labels.read_text().rstrip("\n") + "\nflipped.png,flipped\n")
    names = [line.split(",")[0] for line in labels.read_text().splitlines()[1:]]
    D = {}
    for method in ("default", "default_nomirror"):
        out = tmp_path / f"{method}.npy"
        assert main(["retrieval2d", str(tmp_path), "--method", method, "--matrix", str(out),
                     "--backend", "serial"]) == 0
        D[method] = np.load(out)
    q, orig = names.index("flipped.png"), names.index("quadruped_0.png")
    row = np.where(np.arange(len(names)) == q, np.inf, D["default"][q])
    assert int(np.argmin(row)) == orig
    # (a re-extracted contour is not an exact reflection: an image turned by 90° costs as much)
    assert D["default_nomirror"][q, orig] > 1.5 * D["default"][q, orig]
    assert set(CONTOUR_METHODS) >= {"default", "default_nomirror"}
