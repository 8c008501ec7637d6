"""The mixed articulated + rigid retrieval collection (``geoshape gen mixed3d``).

One small collection (all 20 classes x 2, light meshes, coarse voxels) is generated once
through the command line and checked for its promises: the class list and labels.csv
format that ``geoshape retrieval3d`` reads, meshes that load, the defect share and kinds,
distinct shapes within a class, and byte-identical output for the same seed.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from geoshape_datasets_gen._topology import topology_report
from geoshape_datasets_gen.defects3d import DEFECTS, add_debris, flip_patches, punch_holes
from geoshape_datasets_gen.mixed3d import CLASSES, write_collection
from geoshape_datasets_gen.rigid3d import box, sphere
from geoshape_datasets_gen.union3d import fuse_parts, winding_grid

from geoshape.errors import InvalidOptionError
from geoshape.geometry.mesh import signed_volume
from geoshape.io.mesh_io import load_mesh

PER_CLASS, VERTICES, RESOLUTION = 2, 400, 48


def _main(argv):
    from geoshape.__main__ import main

    return main(argv)


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def collection(tmp_path_factory):
    out = tmp_path_factory.mktemp("mixed3d")
    argv = ["gen", "mixed3d", "--out", str(out), "--per-class", str(PER_CLASS), "--seed", "5",
            "--vertices", str(VERTICES), "--resolution", str(RESOLUTION)]
    assert _main(argv) == 0
    return out


def test_classes_and_labels_csv(collection):
    assert len(CLASSES) >= 15 and len(set(CLASSES)) == len(CLASSES)
    text = (collection / "labels.csv").read_text()
    assert text.splitlines()[0] == "file,label"
    rows = _rows(collection / "labels.csv")
    assert len(rows) == len(CLASSES) * PER_CLASS
    labels = [r["label"] for r in rows]
    assert sorted(set(labels)) == sorted(CLASSES)
    assert all(labels.count(c) == PER_CLASS for c in CLASSES)
    assert [r["file"] for r in rows][:2] == [f"{CLASSES[0]}_00.off", f"{CLASSES[0]}_01.off"]
    assert all((collection / r["file"]).is_file() for r in rows)
    params = json.loads((collection / "generator.json").read_text())
    assert params["per_class"] == PER_CLASS and params["seed"] == 5
    assert len(params["articulated"]) == 10 and len(params["rigid"]) == 10
    readme = (collection / "README.txt").read_text()
    assert "20 classes" in readme and "labels.csv" in readme


def test_every_mesh_loads_and_is_light(collection):
    counts = []
    for r in _rows(collection / "labels.csv"):
        V, F = load_mesh(collection / r["file"])
        assert len(F) > 0 and np.isfinite(V).all()
        # a thin coil cannot keep its topology with very few vertices: loose upper bound
        assert 0.5 * VERTICES <= len(V) <= 3.0 * VERTICES, (r["file"], len(V))
        counts.append(len(V))
    assert 0.8 * VERTICES <= np.median(counts) <= 1.3 * VERTICES


def test_defects_share_and_kinds(collection):
    rows = _rows(collection / "defects.csv")
    assert list(rows[0]) == ["file", "defect", "tessellation"]
    bad = [r for r in rows if r["defect"] != "none"]
    assert len(bad) == round(0.1 * len(rows))
    assert {r["defect"] for r in bad} == set(DEFECTS)  # 4 defects, kinds cycled
    assert {r["tessellation"] for r in rows} == {"uniform", "decimated"}
    for r in bad:
        rep = topology_report(load_mesh(collection / r["file"])[1])
        if r["defect"] == "holes":
            assert rep.n_boundary_edges > 0, r
        elif r["defect"] == "flipped":
            assert rep.n_inconsistent_edges > 0, r
        elif r["defect"] == "components":
            assert rep.n_components > 1, r


def _invariants(V):
    """Rotation/translation/scale-invariant summary: normalised covariance eigenvalues."""
    X = V - V.mean(axis=0)
    ev = np.linalg.eigvalsh(X.T @ X / len(X))
    return ev / ev.sum()


def test_shapes_differ_within_a_class(collection):
    rows = _rows(collection / "labels.csv")
    for c in CLASSES:
        meshes = [load_mesh(collection / r["file"])[0] for r in rows if r["label"] == c]
        a, b = (_invariants(V) for V in meshes)
        assert np.abs(a - b).max() > 1e-3, c


def test_same_seed_same_bytes_other_seed_other_shapes(tmp_path):
    kw = dict(classes=("pliers", "gear"), per_class=2, vertices=VERTICES, resolution=RESOLUTION,
              defect_fraction=0.5)
    write_collection(tmp_path / "a", seed=11, **kw)
    write_collection(tmp_path / "b", seed=11, **kw)
    write_collection(tmp_path / "c", seed=12, **kw)
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "b").iterdir())
    for n in names:
        assert (tmp_path / "a" / n).read_bytes() == (tmp_path / "b" / n).read_bytes(), n
    assert (tmp_path / "a" / "gear_00.off").read_bytes() != (tmp_path / "c" / "gear_00.off").read_bytes()


def test_bad_options(tmp_path):
    with pytest.raises(InvalidOptionError):
        write_collection(tmp_path, classes=("cup", "dragon"))
    with pytest.raises(InvalidOptionError):
        write_collection(tmp_path, classes=("cup", "cup"))
    with pytest.raises(InvalidOptionError):
        write_collection(tmp_path, classes=("cup",), defect_fraction=1.5)
    assert _main(["gen", "mixed3d", "--out", str(tmp_path), "--classes", "dragon"]) == 2
    assert _main(["gen", "mixed3d", "--out", str(tmp_path), "--per-class", "0"]) == 2


# ----------------------------------------------------------------------------- building blocks


def test_winding_grid_counts_overlapping_parts():
    a = box((1.0, 1.0, 1.0))
    b = box((1.0, 1.0, 1.0), t=(0.5, 0.0, 0.0))
    V = np.concatenate([a[0], b[0]])
    F = np.concatenate([a[1], b[1] + len(a[0])])
    h = 0.05
    lo = np.array([-0.7, -0.7, -0.7]) + 0.0123
    W = winding_grid(V, F, lo, h, (40, 29, 29))
    P = lo + h * np.stack(np.meshgrid(np.arange(40), np.arange(29), np.arange(29), indexing="ij"), -1)
    in_a = (np.abs(P) < 0.5).all(-1)
    in_b = (np.abs(P - (0.5, 0, 0)) < 0.5).all(-1)
    assert np.array_equal(W, in_a.astype(float) + in_b)


def test_fuse_parts_gives_one_closed_union():
    parts = [box((1.0, 0.2, 1.0)), sphere((0.0, 0.3, 0.0), 0.3), sphere((2.0, 0.0, 0.0), 0.2)]
    V, F = fuse_parts(parts, resolution=64)
    rep = topology_report(F)
    assert rep.watertight and rep.n_components == 1  # the far sphere is dropped
    vol = signed_volume(V, F)
    # box 0.2 + cap of the sphere above the box (height 0.5 of radius 0.3)
    expected = 0.2 + np.pi * 0.5**2 * (3 * 0.3 - 0.5) / 3
    assert abs(vol - expected) < 0.03 * expected


def test_defect_functions():
    V, F = sphere((0.0, 0.0, 0.0), 1.0, subdivisions=3)
    rng = np.random.default_rng(0)
    Vh, Fh = punch_holes(V, F, rng, count=3)
    assert len(Fh) < len(F) and topology_report(Fh).n_boundary_edges > 0
    assert len(np.unique(Fh)) == len(Vh)  # no unreferenced vertex left
    Ff = flip_patches(V, F, rng, fraction=0.1)
    changed = (Ff != F).any(axis=1).mean()
    assert 0.05 < changed < 0.15 and topology_report(Ff).n_inconsistent_edges > 0
    Vd, Fd = add_debris(V, F, rng, count=2)
    assert topology_report(Fd).n_components == 3 and np.array_equal(Vd[: len(V)], V)
