"""labels.csv and pairs.csv as users write them: BOMs, missing labels, short rows."""

from __future__ import annotations

import pytest

from geoshape.errors import DatasetError
from geoshape.io.datasets import read_labels, read_pairs


def _files(tmp_path, *names):
    for n in names:
        (tmp_path / n).write_text("x")


def test_labels_with_a_byte_order_mark_are_read(tmp_path):
    _files(tmp_path, "a.png", "b.png")
    (tmp_path / "labels.csv").write_bytes("file,label\na.png,cat\nb.png, dog\n".encode("utf-8-sig"))
    items = read_labels(tmp_path)
    assert [i.label for i in items] == ["cat", "dog"]


@pytest.mark.parametrize("row", ["b.png", "b.png,", "b.png,  "])
def test_a_row_without_a_label_is_refused_with_its_line(tmp_path, row):
    _files(tmp_path, "a.png", "b.png")
    (tmp_path / "labels.csv").write_text(f"file,label\na.png,cat\n{row}\n")
    with pytest.raises(DatasetError, match=r"labels.csv:3: row 'b.png' has no label"):
        read_labels(tmp_path)


def test_labels_that_are_not_utf8_name_the_file(tmp_path):
    (tmp_path / "labels.csv").write_bytes(b"file,label\n\xff\xfe,\x80\n")
    with pytest.raises(DatasetError, match="not UTF-8"):
        read_labels(tmp_path)


@pytest.mark.parametrize("row", ["a.off", "a.off,", ",b.off"])
def test_a_pairs_row_without_a_target_is_refused(tmp_path, row):
    _files(tmp_path, "a.off", "b.off")
    (tmp_path / "pairs.csv").write_text(f"source,target\n{row}\n")
    with pytest.raises(DatasetError, match=r"pairs.csv:2: a row needs both a source and a target"):
        read_pairs(tmp_path)
