"""Output paths checked before any work: the folder exists and is writable, the path is not a
folder, and the extension is one the writer supports.

Each command declares its output options with :func:`declare_outputs`; the command line checks
them all (:func:`check_declared_outputs`) before the command starts, so a bad ``--plot`` fails
in milliseconds with exit status 2 instead of after minutes of computation, and nothing is
written. The writes themselves are all-or-nothing (:func:`geoshape.io.atomic.staged_outputs`).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from geoshape.errors import OutputError

#: Extensions Matplotlib writes (Agg, PDF, SVG, PS backends), for ``picture`` outputs.
PICTURE_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg", "tif", "tiff", "eps", "ps", "webp")

#: What each kind of output accepts: a tuple of extensions, or None for any name.
OUTPUT_KINDS: dict[str, tuple[str, ...] | None] = {
    "picture": PICTURE_FORMATS,
    "mesh": None,  # checked by geoshape.io.mesh_io.mesh_format
    "npy": ("npy",),
    "text": None,
    "folder": None,
    "html": ("html", "htm"),  # geoshape.viewer pages
}


def _extension(path: Path) -> str:
    return path.suffix.lstrip(".").lower()


def check_output_path(path: str | os.PathLike, kind: str, *, option: str = "output") -> Path:
    """Return ``path`` if a ``kind`` output can be written there, else raise :class:`OutputError`.

    Parameters
    ----------
    path : str or PathLike
        The output file (or, for ``kind="folder"``, the output folder, created later if absent).
    kind : str
        One of :data:`OUTPUT_KINDS`: ``picture``, ``mesh``, ``npy``, ``text``, ``folder``, ``html``.
    option : str
        How the output is named in the message (e.g. ``--plot``).

    Raises
    ------
    OutputError
        The parent folder is missing, not a folder or not writable; the path is an existing
        folder (for a file) or file (for a folder); the extension is not supported.

    >>> check_output_path("/nonexistent-folder/m.npy", "npy", option="--matrix")
    Traceback (most recent call last):
    ...
    geoshape.errors.OutputError: --matrix /nonexistent-folder/m.npy: folder /nonexistent-folder does not exist
    """
    if kind not in OUTPUT_KINDS:
        raise ValueError(f"unknown output kind {kind!r}")
    path = Path(path)
    where = f"{option} {path}"
    if kind == "folder":
        if path.exists() and not path.is_dir():
            raise OutputError(f"{where}: exists and is not a folder")
        folder = path if path.is_dir() else path.parent
    else:
        if path.is_dir():
            raise OutputError(f"{where}: is a folder, expected a file name")
        folder = path.parent
        allowed = OUTPUT_KINDS[kind]
        if kind == "mesh":
            from geoshape.errors import InvalidMeshError
            from geoshape.io.mesh_io import mesh_format

            try:
                mesh_format(path)
            except InvalidMeshError as exc:
                raise OutputError(f"{option} {exc}") from None
        elif allowed is not None and _extension(path) not in allowed:
            listed = ", ".join(f".{e}" for e in allowed)
            raise OutputError(
                f"{where}: unsupported extension {path.suffix or '(none)'!r} (supported: {listed})"
            )
    folder = folder if str(folder) else Path(".")
    if not folder.exists():
        raise OutputError(f"{where}: folder {folder} does not exist")
    if not folder.is_dir():
        raise OutputError(f"{where}: {folder} is not a folder")
    try:  # the honest test of writability (root ignores permission bits, not read-only mounts)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        raise OutputError(f"{where}: folder {folder} is not writable") from None
    return path


def declare_outputs(parser, *, all_or_nothing: bool = True, **kinds: str) -> None:
    """Declare which options of a sub-command ``parser`` are output paths, and of what kind.

    ``declare_outputs(p, out="text", plot="picture")`` — the keys are ``argparse`` dests.
    With ``all_or_nothing`` (the default) the command line commits the command's files
    together at the end (:func:`geoshape.io.atomic.staged_outputs`); batch commands that must
    keep each finished file when interrupted pass ``all_or_nothing=False`` (each file is still
    written atomically).
    """
    for kind in kinds.values():
        if kind not in OUTPUT_KINDS:
            raise ValueError(f"unknown output kind {kind!r}")
    parser.set_defaults(outputs=dict(kinds), outputs_all_or_nothing=all_or_nothing)


def check_declared_outputs(args) -> None:
    """Check every declared output option of parsed ``args`` that was given; also refuse two
    outputs of one command that name the same file."""
    seen: dict[Path, str] = {}
    for dest, kind in (getattr(args, "outputs", None) or {}).items():
        value = getattr(args, dest, None)
        if value in (None, "", False):
            continue
        option = "--" + dest.replace("_", "-")
        path = check_output_path(value, kind, option=option)
        key = Path(os.path.abspath(path))
        if key in seen:
            raise OutputError(f"{option} and {seen[key]} name the same file {path}")
        seen[key] = option
