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


NO_LABEL = r"labels.csv:3: row 'b.png' has no label"
NO_TARGET = r"pairs.csv:2: a row needs both a source and a target"


@pytest.mark.parametrize("reader, name, text, match", [
    *[(read_labels, "labels.csv", f"file,label\na.png,cat\n{row}\n", NO_LABEL)
      for row in ("b.png", "b.png,", "b.png,  ")],
    *[(read_pairs, "pairs.csv", f"source,target\n{row}\n", NO_TARGET)
      for row in ("a.png", "a.png,", ",b.png")],
])
def test_short_rows_are_refused_with_their_line(tmp_path, reader, name, text, match):
    _files(tmp_path, "a.png", "b.png")
    (tmp_path / name).write_text(text)
    with pytest.raises(DatasetError, match=match):
        reader(tmp_path)


def test_labels_that_are_not_utf8_name_the_file(tmp_path):
    (tmp_path / "labels.csv").write_bytes(b"file,label\n\xff\xfe,\x80\n")
    with pytest.raises(DatasetError, match="not UTF-8"):
        read_labels(tmp_path)
