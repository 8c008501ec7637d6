"""Database-level re-ranking (geoshape.retrieval.rerank): known behaviour on planted matrices."""

from __future__ import annotations

import numpy as np
import pytest

from geoshape.errors import InvalidOptionError
from geoshape.metrics.retrieval import retrieval_metrics
from geoshape.retrieval.rerank import RERANK_METHODS, rerank


def _planted(noise: float, seed: int = 0, classes: int = 6, size: int = 10):
    """Block-structured dissimilarities: 0.5 within a class, 1 between, plus noise."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.arange(classes), size)
    D = np.where(labels[:, None] == labels[None, :], 0.5, 1.0) + noise * rng.random((len(labels),) * 2)
    np.fill_diagonal(D, 0.0)
    return D, labels


def test_a_noisy_block_matrix_gets_sharper_blocks():
    D, labels = _planted(noise=0.7)
    before = retrieval_metrics(D, labels)
    after = retrieval_metrics(rerank(D), labels)
    assert after["map"] > before["map"] + 0.05
    assert after["first_tier"] >= before["first_tier"]


def test_a_perfect_matrix_stays_perfect():
    D, labels = _planted(noise=0.1)
    assert retrieval_metrics(D, labels)["map"] == pytest.approx(1.0)
    R = rerank(D)
    assert retrieval_metrics(R, labels)["map"] == pytest.approx(1.0)
    assert np.allclose(np.diag(R), 0.0) and R.min() >= 0.0 and R.max() <= 1.0


def test_rerank_is_deterministic_and_ignores_scale_and_transposition():
    D, _ = _planted(noise=0.5, seed=3)
    R = rerank(D)
    assert np.array_equal(R, rerank(D.copy()))
    np.testing.assert_allclose(rerank(7.0 * D), R, atol=1e-12)  # unit-free
    np.testing.assert_allclose(rerank(D.T), R, atol=1e-12)  # symmetrised first


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((3, 4)), "square"),
        (np.zeros((2, 2)), "at least 3"),
        (np.array([[0, 1, np.nan], [1, 0, 1], [1, 1, 0]]), "NaN"),
    ],
)
def test_bad_matrices_are_refused(bad, match):
    with pytest.raises(InvalidOptionError, match=match):
        rerank(bad)


def test_bad_names_and_parameters_list_what_is_valid():
    D, _ = _planted(noise=0.1)
    with pytest.raises(InvalidOptionError, match="must be one of " + repr(RERANK_METHODS[0])):
        rerank(D, "graph-magic")
    with pytest.raises(InvalidOptionError, match="k must be an integer"):
        rerank(D, k=0)
    with pytest.raises(InvalidOptionError, match="iterations must be an integer"):
        rerank(D, iterations=-1)


def test_cli_writes_the_reranked_matrix_and_refuses_bad_names(tmp_path, capsys):
    from PIL import Image, ImageDraw

    from geoshape.__main__ import main

    rows = []
    for i, (w, h) in enumerate([(40, 40), (42, 38), (38, 42), (60, 20), (58, 22), (62, 18)]):
        img = Image.new("L", (96, 96), 0)
        ImageDraw.Draw(img).ellipse([48 - w // 2, 48 - h // 2, 48 + w // 2, 48 + h // 2], fill=255)
        img.save(tmp_path / f"s{i}.png")
        rows.append(f"s{i}.png,{'round' if i < 3 else 'long'}")
    (tmp_path / "labels.csv").write_text("file,label\n" + "\n".join(rows) + "\n")
    plain, ranked = tmp_path / "D.npy", tmp_path / "R.npy"
    assert main(["retrieval2d", str(tmp_path), "--matrix", str(plain), "--backend", "serial"]) == 0
    assert (
        main(
            ["retrieval2d", str(tmp_path), "--matrix", str(ranked), "--backend", "serial", "--rerank", "lcdp"]
        )
        == 0
    )
    np.testing.assert_allclose(np.load(ranked), rerank(np.load(plain)), atol=1e-12)
    capsys.readouterr()
    assert main(["retrieval2d", str(tmp_path), "--matrix", str(tmp_path / "x.npy"), "--rerank", "nope"]) == 2
    assert "'lcdp'" in capsys.readouterr().err and not (tmp_path / "x.npy").exists()
