"""Perturbed silhouette collections (geoshape_datasets_gen.perturb2d): what each kind does."""

from __future__ import annotations

import numpy as np
import pytest
from geoshape_datasets_gen.perturb2d import PERTURBATIONS, perturb_collection, perturb_mask

from geoshape.errors import InvalidOptionError


def _figure():
    """A 96² mask: a thick disc with one thin 2-pixel-wide leg."""
    y, x = np.mgrid[:96, :96]
    mask = (x - 40) ** 2 + (y - 48) ** 2 < 22**2
    mask[46:48, 60:90] = True
    return mask


def test_mirror_flips_every_other_item():
    rng = np.random.default_rng(0)
    m = _figure()
    out = [perturb_mask(m, "mirror", np.random.default_rng(1), index=i, parity=1) for i in range(4)]
    flipped = [not np.array_equal(o, m) for o in out]
    assert flipped == [False, True, False, True]
    assert any(np.array_equal(o, m[:, ::-1]) for o in out)
    assert perturb_mask(m, "noise", rng).sum() > 0


def test_erode_removes_thin_parts_and_keeps_thick_ones():
    m = _figure()
    e = perturb_mask(m, "erode", np.random.default_rng(0))
    assert not e[46:48, 70:90].any()  # the thin leg is gone
    assert e[48, 40] and abs(int(e.sum()) - int(m[:, :60].sum())) < 0.1 * m.sum()


def test_notch_and_noise_change_only_the_boundary_region():
    from scipy import ndimage

    m = _figure()
    # within the stamp radius of the boundary: 6 % (notch) of the ~83-pixel object size
    edge = m & ~ndimage.binary_erosion(m)
    near = ndimage.distance_transform_edt(~edge) <= 6.5
    for kind in ("notch", "noise"):
        p = perturb_mask(m, kind, np.random.default_rng(2))
        changed = p != m
        assert changed.any() and not (changed & ~near).any(), kind


def test_collections_are_deterministic_and_keep_labels(tmp_path):
    from PIL import Image

    src = tmp_path / "src"
    src.mkdir()
    Image.fromarray((_figure() * 255).astype(np.uint8)).save(src / "a.png")
    Image.fromarray((_figure()[:, ::-1] * 255).astype(np.uint8)).save(src / "b.png")
    (src / "labels.csv").write_text("file,label\na.png,x\nb.png,y\n")
    for kind in PERTURBATIONS:
        one = perturb_collection(src, tmp_path / f"{kind}1", kind, seed=5)
        two = perturb_collection(src, tmp_path / f"{kind}2", kind, seed=5)
        assert [p.read_bytes() for p in one] == [p.read_bytes() for p in two]
        assert (tmp_path / f"{kind}1" / "labels.csv").read_text() == "file,label\na.png,x\nb.png,y\n"
    with pytest.raises(InvalidOptionError, match="mirror, noise, notch, erode"):
        perturb_collection(src, tmp_path / "x", "blur")
    with pytest.raises(InvalidOptionError, match="output folder is the input folder"):
        perturb_collection(src, src, "noise")


def test_a_collection_mirrors_exactly_every_other_item(tmp_path):
    from PIL import Image

    src = tmp_path / "src"
    src.mkdir()
    rows = []
    for i in range(8):
        Image.fromarray((_figure() * 255).astype(np.uint8)).save(src / f"s{i}.png")
        rows.append(f"s{i}.png,c")
    (src / "labels.csv").write_text("file,label\n" + "\n".join(rows) + "\n")
    flipped = [not np.array_equal(np.asarray(Image.open(p)) > 0, _figure())
               for p in perturb_collection(src, tmp_path / "m", "mirror", seed=3)]
    assert flipped in ([True, False] * 4, [False, True] * 4)
