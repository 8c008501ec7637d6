"""The articulated silhouette generator: determinism, readability, bending robustness."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from geoshape_datasets_gen.silhouettes2d import CLASSES, articulated_silhouette, generate_silhouettes

from geoshape.errors import InvalidOptionError
from geoshape.geometry.contour import contour_from_image
from geoshape.io.datasets import read_labels


def _digest(paths):
    return [hashlib.sha256(p.read_bytes()).hexdigest() for p in paths]


def test_same_seed_same_images(tmp_path):
    a = generate_silhouettes(tmp_path / "a", per_class=2, seed=5)
    b = generate_silhouettes(tmp_path / "b", per_class=2, seed=5)
    c = generate_silhouettes(tmp_path / "c", per_class=2, seed=6)
    assert _digest(a) == _digest(b)
    assert _digest(a) != _digest(c)
    assert (tmp_path / "a" / "labels.csv").read_text() == (tmp_path / "b" / "labels.csv").read_text()


def test_every_image_gives_a_contour(tmp_path):
    generate_silhouettes(tmp_path, per_class=2, seed=1)
    items = read_labels(tmp_path)
    assert len(items) == 2 * len(CLASSES)
    assert {it.label for it in items} == set(CLASSES)
    for it in items:
        P = contour_from_image(it.path, 100)
        assert P.shape == (100, 2) and np.isfinite(P).all()


def test_poses_differ_within_a_class():
    a = articulated_silhouette("person", seed=0)
    b = articulated_silhouette("person", seed=1)
    assert a.any() and (a != b).sum() > 100


def test_unknown_class():
    with pytest.raises(InvalidOptionError, match="person"):
        articulated_silhouette("dragon", seed=0)


@pytest.mark.slow
def test_bent_shapes_retrieve_their_own_class_first(tmp_path):
    """Bending robustness: for every pose, the nearest other shape is a pose of its class."""
    from geoshape.contour.retrieval import retrieval_on_folder

    generate_silhouettes(tmp_path, per_class=3, seed=2)
    res = retrieval_on_folder(tmp_path, "default", backend="serial")
    D = res["D"].copy()
    np.fill_diagonal(D, np.inf)
    labels = np.array(res["labels"])
    nearest = labels[D.argmin(axis=1)]
    assert np.array_equal(nearest, labels)
