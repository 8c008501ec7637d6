"""Reading benchmark folders: ``labels.csv`` and ``pairs.csv`` with ``.vts`` landmarks.

Formats (see ``../shared/data/README.md``):

- ``labels.csv``: columns ``file,label``; ``file`` relative to the folder. Row order is
  the order of any N x N dissimilarity matrix written for the set.
- ``pairs.csv``: columns ``source,target,source_landmarks,target_landmarks,
  target_symmetric_landmarks``; empty landmark columns mean identity ground truth.
  ``.vts`` files hold 1-based vertex ids, one per line (extra columns ignored).

Data is located through ``$GEOSHAPE_DATA`` or ``../shared/data`` beside the checkout.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from geoshape.errors import DatasetError

DATA_ENV = "GEOSHAPE_DATA"


def data_root(required: bool = True) -> Path | None:
    """The folder holding benchmark sets: ``$GEOSHAPE_DATA``, else ``../shared/data``.

    ``../shared/data`` is looked up beside the source checkout and beside the current
    directory. Raises :class:`DatasetError` when nothing is found and ``required``.
    """
    env = os.environ.get(DATA_ENV)
    candidates = [Path(env)] if env else []
    repo = Path(__file__).resolve().parents[2]
    candidates += [repo.parent / "shared" / "data", Path.cwd().parent / "shared" / "data"]
    for c in candidates:
        if c.is_dir():
            return c
    if required:
        where = ", ".join(str(c) for c in candidates)
        raise DatasetError(
            f"benchmark data not found (looked in {where}); set {DATA_ENV} to the data folder"
        )
    return None


def dataset_dir(name: str, required: bool = True) -> Path | None:
    """Folder of one benchmark set, e.g. ``dataset_dir("kimia99")``."""
    root = data_root(required=required)
    if root is None:
        return None
    folder = root / name
    if not folder.is_dir():
        if required:
            raise DatasetError(f"dataset {name!r} not found in {root}")
        return None
    return folder


def _open_csv(path: Path):
    """Open a CSV for reading: UTF-8 with or without a byte-order mark (as spreadsheets
    write it); undecodable bytes are a :class:`DatasetError` naming the file."""
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read: {exc.strerror}") from None
    return io.StringIO(text, newline="")


@dataclass(frozen=True)
class LabelledItem:
    path: Path
    label: str


def read_labels(folder: str | os.PathLike, filename: str = "labels.csv") -> list[LabelledItem]:
    """Rows of ``folder/labels.csv`` as ``(path, label)``, in file order.

    Raises :class:`DatasetError` if the file is missing, lacks the ``file,label``
    columns, is empty, or names a file that does not exist.
    """
    folder = Path(folder)
    path = folder / filename
    if not path.is_file():
        raise DatasetError(f"{path}: no such labels file (expected columns file,label)")
    with _open_csv(path) as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None or not {"file", "label"} <= set(reader.fieldnames):
            raise DatasetError(
                f"{path}: header must contain 'file' and 'label', got {reader.fieldnames}"
            )
        items = []
        for lineno, row in enumerate(reader, start=2):
            if not (row.get("file") or "").strip():
                raise DatasetError(f"{path}:{lineno}: empty 'file' field")
            if not (row.get("label") or "").strip():
                raise DatasetError(f"{path}:{lineno}: row {row['file']!r} has no label")
            item_path = folder / row["file"]
            if not item_path.is_file():
                raise DatasetError(f"{path}:{lineno}: listed file {row['file']!r} does not exist")
            items.append(LabelledItem(item_path, row["label"].strip()))
    if not items:
        raise DatasetError(f"{path}: no rows")
    return items


@dataclass(frozen=True)
class Pair:
    """One correspondence pair. ``landmarks`` are 0-based; ``None`` means identity."""

    source: Path
    target: Path
    source_landmarks: np.ndarray | None = None
    target_landmarks: np.ndarray | None = None
    target_symmetric_landmarks: np.ndarray | None = None

    @property
    def identity(self) -> bool:
        return self.source_landmarks is None


def read_vts(path: str | os.PathLike) -> np.ndarray:
    """0-based vertex ids from a ``.vts`` file (1-based ids, first column used)."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: landmark file does not exist")
    try:
        ids = np.loadtxt(path, ndmin=2, dtype=np.float64)[:, 0]
    except ValueError as exc:
        raise DatasetError(f"{path}: not a list of vertex ids: {exc}") from None
    if ids.size == 0 or np.any(ids < 1) or np.any(ids != np.round(ids)):
        raise DatasetError(f"{path}: vertex ids must be whole numbers >= 1")
    return ids.astype(np.int64) - 1


def scape_feature_points(folder: str | os.PathLike):
    """(ids, mirrored ids) of SCAPE's feature points, or None if absent.

    ``Corrs/1.pid`` holds the 0-based vertex ids, ``Corrs/1.sym.info`` the left/right pairs
    (index pairs into that list); the mirrored ids swap each pair.
    """
    folder = Path(folder)
    pid, sym = folder / "Corrs" / "1.pid", folder / "Corrs" / "1.sym.info"
    if not (pid.is_file() and sym.is_file()):
        return None
    ids = np.loadtxt(pid, ndmin=2)[:, 0].astype(np.int64)
    mirror = np.arange(len(ids))
    for line in sym.read_text().splitlines():
        parts = line.split()
        if len(parts) == 2:
            a, b = int(parts[0]), int(parts[1])
            mirror[a], mirror[b] = b, a
    return ids, ids[mirror]


def _optional_vts(folder: Path, row: dict, column: str) -> np.ndarray | None:
    value = (row.get(column) or "").strip()
    return read_vts(folder / value) if value else None


def read_pairs(
    folder: str | os.PathLike, filename: str = "pairs.csv", check_files: bool = True
) -> list[Pair]:
    """Rows of ``folder/pairs.csv`` (paths resolved relative to ``folder``).

    With ``check_files=False`` missing meshes are not reported here (a batch reports
    and skips them per pair instead). Landmark files are always read eagerly.
    """
    folder = Path(folder)
    path = Path(filename) if Path(filename).is_absolute() else folder / filename
    if not path.is_file():
        raise DatasetError(f"{path}: no such pairs file")
    required = {"source", "target"}
    pairs = []
    with _open_csv(path) as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None or not required <= set(reader.fieldnames):
            raise DatasetError(
                f"{path}: header must contain 'source' and 'target', got {reader.fieldnames}"
            )
        for lineno, row in enumerate(reader, start=2):
            if not (row.get("source") or "").strip() or not (row.get("target") or "").strip():
                raise DatasetError(f"{path}:{lineno}: a row needs both a source and a target mesh")
            src, tgt = folder / row["source"].strip(), folder / row["target"].strip()
            if check_files:
                for p in (src, tgt):
                    if not p.is_file():
                        raise DatasetError(f"{path}:{lineno}: mesh {p.name!r} does not exist")

            sl, tl, ts = (
                _optional_vts(folder, row, col)
                for col in ("source_landmarks", "target_landmarks", "target_symmetric_landmarks")
            )
            if (sl is None) != (tl is None):
                raise DatasetError(f"{path}:{lineno}: give both source and target landmarks or neither")
            if sl is not None and len(sl) != len(tl):
                raise DatasetError(f"{path}:{lineno}: {len(sl)} source vs {len(tl)} target landmarks")
            if ts is not None and tl is not None and len(ts) != len(tl):
                raise DatasetError(
                    f"{path}:{lineno}: symmetric landmarks differ in count from target landmarks"
                )
            pairs.append(Pair(src, tgt, sl, tl, ts))
    if not pairs:
        raise DatasetError(f"{path}: no rows")
    return pairs


def mesh_stem(path: str | os.PathLike) -> str:
    """File name without its mesh and ``.gz`` extensions: ``cat0.off.gz`` -> ``cat0``."""
    name = Path(path).name
    if name.endswith(".gz"):
        name = name[:-3]
    for ext in (".off", ".obj", ".ply", ".stl"):
        if name.lower().endswith(ext):
            return name[: -len(ext)]
    return Path(name).stem
