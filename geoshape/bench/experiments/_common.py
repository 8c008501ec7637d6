"""Helpers shared by the experiments: meshes (TOSCA or generated), mirrored truth, outputs."""

from __future__ import annotations

import csv
import io
import json
import os
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geoshape.errors import InvalidOptionError

#: Note added to every table produced without the tosca_r5k data.
NO_DATA_NOTE = "tosca_r5k not found: generated meshes only"


class TestMesh(NamedTuple):
    """A mesh used by an experiment.

    Attributes
    ----------
    name : str
        ``david0@1500`` (TOSCA, reduced to about 1500 vertices) or ``biped@1000``.
    V : (n, 3) float64
    F : (m, 3) int64
    mirror : (n, 3) float64 or None
        For each vertex, the position of its left-right mirror image on the same surface
        (TOSCA ``.sym.vts``); ``None`` for generated meshes.
    source : str
        ``"tosca_r5k"`` or ``"generated"``.
    """

    name: str
    V: np.ndarray
    F: np.ndarray
    mirror: np.ndarray | None
    source: str


def tosca_folder(data_dir: str | os.PathLike | None = None) -> Path | None:
    """The ``tosca_r5k`` folder (``data_dir`` if given), or ``None`` when it is absent."""
    if data_dir is not None:
        folder = Path(data_dir)
    else:
        from geoshape.io.datasets import dataset_dir

        folder = dataset_dir("tosca_r5k", required=False)
    if folder is None or not (Path(folder) / "vtx_5k").is_dir():
        return None
    return Path(folder)


def mirror_positions(V: np.ndarray, vts: np.ndarray, sym: np.ndarray) -> np.ndarray:
    """Position of each vertex's mirror image, from landmark pairs ``vts[k] ↔ sym[k]``.

    A vertex takes the mirror of its nearest landmark (the landmarks cover about 75 % of
    a tosca_r5k mesh's vertices, so the gap is at most an edge or two). O(n log n).
    """
    from geoshape.geometry.knn import nearest

    _, k = nearest(V[vts], V)
    return V[sym[k]]


def snap(V: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Nearest vertex of ``V`` to each point of ``P`` (``(p,)`` int64), O((n + p) log n)."""
    from geoshape.geometry.knn import nearest

    return nearest(V, P)[1]


def reduce_mesh(V, F, n_vertices: int | None):
    """Decimate to about ``n_vertices`` keeping exact positions; ``(V, F, ids)``.

    ``ids`` maps the kept vertices to input ids. ``None`` or ``n_vertices >= n`` keeps the
    mesh. Time: one quadric-collapse pass, about 0.5 s for 5k vertices.
    """
    from geoshape_datasets_gen.decimate import decimate_exact

    n = len(V)
    if n_vertices is None or n_vertices >= n:
        return V, F, np.arange(n)
    d = decimate_exact(V, F, n_vertices / n)
    return d.V, d.F, d.orig_ids


def load_tosca(folder: Path, name: str, n_vertices: int | None = None) -> TestMesh:
    """tosca_r5k mesh ``name`` (e.g. ``"david0"``), reduced to about ``n_vertices``."""
    from geoshape.io.datasets import read_vts
    from geoshape.io.mesh_io import load_mesh

    path = folder / "vtx_5k" / f"{name}.off.gz"
    if not path.is_file():
        raise InvalidOptionError(f"tosca_r5k has no mesh {name!r} ({path} does not exist)")
    V, F = load_mesh(path)
    corres = folder / "vtx_5k" / "corres"
    mirror = mirror_positions(V, read_vts(corres / f"{name}.vts"), read_vts(corres / f"{name}.sym.vts"))
    Vr, Fr, ids = reduce_mesh(V, F, n_vertices)
    label = name if len(Vr) == len(V) else f"{name}@{len(Vr)}"
    return TestMesh(label, Vr, Fr, mirror[ids], "tosca_r5k")


def experiment_meshes(tosca, generated, base_vertices: int, seed: int = 0,
                      data_dir=None) -> tuple[list[TestMesh], list[str]]:
    """The TOSCA meshes named in ``tosca`` (when the data is there) and the generated
    classes named in ``generated``; plus the notes for the table (missing data).

    Raises InvalidOptionError when nothing is left to run on.
    """
    folder = tosca_folder(data_dir)
    notes, meshes = [], []
    if folder is None and names(tosca):
        notes.append(NO_DATA_NOTE)
    elif folder is not None:
        meshes += [load_tosca(folder, name, base_vertices) for name in names(tosca)]
    meshes += [generated_mesh(cls, base_vertices, seed) for cls in names(generated)]
    if not meshes:
        raise InvalidOptionError("no meshes to run on (give --tosca or --generated)")
    return meshes, notes


def tosca_landmarks(folder: Path, name: str) -> np.ndarray:
    """0-based ``.vts`` landmarks of tosca_r5k mesh ``name`` (5000 ids, with repeats)."""
    from geoshape.io.datasets import read_vts

    return read_vts(folder / "vtx_5k" / "corres" / f"{name}.vts")


def generated_poses(cls: str, n_vertices: int, poses: int = 1, seed: int = 0):
    """``(poses (P, n, 3), F)`` of a generated figure (identity ground truth across poses)."""
    from geoshape_datasets_gen.articulated3d import generate_figure

    resolution = 64 if n_vertices <= 2500 else 96
    fig = generate_figure(cls, poses=poses, seed=seed, target_vertices=n_vertices, resolution=resolution)
    return fig.poses, fig.F


def generated_mesh(cls: str, n_vertices: int, seed: int = 0) -> TestMesh:
    """One random pose of a generated figure of class ``cls``, with about ``n_vertices``.

    The generator makes at least 500 vertices; smaller meshes are decimated from 500.
    """
    P, F = generated_poses(cls, max(n_vertices, 500), 1, seed)
    V, F, _ = reduce_mesh(P[0], F, n_vertices)
    return TestMesh(f"{cls}@{len(V)}", V, F, None, "generated")


def parse_list(text, kind=float) -> tuple:
    """``"0.5,1,2"`` → ``(0.5, 1.0, 2.0)``; a tuple or list passes through (converted)."""
    if isinstance(text, str):
        items = [t.strip() for t in text.split(",") if t.strip()]
    else:
        items = list(text)
    try:
        return tuple(kind(t) for t in items)
    except (TypeError, ValueError):
        raise InvalidOptionError(
            f"expected a comma-separated list of {kind.__name__}, got {text!r}") from None


def names(text) -> tuple[str, ...]:
    """Comma-separated names; ``""`` or ``"none"`` gives an empty tuple."""
    if isinstance(text, str):
        if text.strip().lower() in ("", "none"):
            return ()
        return tuple(t.strip() for t in text.split(",") if t.strip())
    return tuple(text)


def machine_note() -> str:
    """One line on the load under which the times were measured."""
    try:
        load = os.getloadavg()[0]
    except OSError:  # pragma: no cover - not on every platform
        return f"{os.cpu_count()} cores"
    return f"{os.cpu_count()} cores shared with other jobs, 1-min load average {load:.1f} at the end"


def write_table(out_dir: str | os.PathLike, name: str, rows: list[dict], meta: dict) -> tuple[Path, Path]:
    """Write ``rows`` to ``out_dir/name.csv`` and ``{meta, rows}`` to ``out_dir/name.json``."""
    from geoshape.cli._common import to_jsonable
    from geoshape.io.atomic import write_text_atomic

    out = Path(out_dir)
    columns: list[str] = []
    for row in rows:
        columns += [c for c in row if c not in columns]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    csv_path, json_path = out / f"{name}.csv", out / f"{name}.json"
    write_text_atomic(csv_path, buf.getvalue())
    write_text_atomic(json_path, json.dumps(to_jsonable({"meta": meta, "rows": rows}), indent=1) + "\n")
    return csv_path, json_path


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Save a Matplotlib ``Figure`` to ``path`` atomically (format from the extension)."""
    from geoshape.io.atomic import save_figure_atomic

    return save_figure_atomic(fig, path, dpi=110)


class Stopwatch:
    """Wall time since creation, for the tables' ``seconds`` notes."""

    def __init__(self):
        self.t0 = time.perf_counter()

    def __call__(self) -> float:
        return time.perf_counter() - self.t0


def add_common_arguments(p) -> None:
    """``--out``, ``--no-results``, ``--data``, ``--seed`` of every experiment."""
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the PNG, CSV and JSON")
    p.add_argument("--no-results", action="store_true", help="do not update docs/RESULTS.md")
    p.add_argument("--data", default=None, metavar="DIR",
                   help="tosca_r5k folder (default: found under $GEOSHAPE_DATA or ../shared/data)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random choice")


def one_blas_thread(fn):
    """Run ``fn`` with BLAS limited to one thread.

    The experiments are sequences of small dense products (reordering costs on 200
    samples, TPS fits); on busy shared cores several BLAS threads made the exhaustive
    reordering about 2x slower (measured 6.3 s vs 3.0 s for k = 5 on 200 samples).
    """
    import functools

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from geoshape.parallel import single_thread_blas

        with single_thread_blas():
            return fn(*args, **kwargs)

    return wrapper


def publish(out_dir, name: str, rows: list[dict], meta: dict, markdown, plot=None, *,
            results: bool = True, results_path=None) -> list[dict]:
    """Write ``DIR/<name>.{csv,json}`` (and ``.png`` with ``plot(rows, path)``), then the
    ``experiment-<name>`` section of docs/RESULTS.md from ``markdown(rows, meta)``."""
    write_table(out_dir, name, rows, meta)
    if plot is not None:
        plot(rows, Path(out_dir) / f"{name}.png")
    if results:
        from geoshape.bench.results import update_results_section

        update_results_section(f"experiment-{name}", markdown(rows, meta), results_path)
    return rows


def best_error(row: dict) -> float:
    """Symmetry-aware error where a mirrored truth exists, else the direct error."""
    import math

    v = row["mean_error_sym_aware"]
    return v if isinstance(v, float) and math.isfinite(v) else row["mean_error"]
