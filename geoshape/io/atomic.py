"""Atomic file writing: never leave a half-written output behind, nor half of a command's outputs.

Every writer in geoshape goes through :func:`atomic_path` (or :func:`write_bytes_atomic`):
the content is written to a temporary file in the destination folder, flushed, and only
then renamed over the destination. An exception or Ctrl-C in between removes the
temporary file and leaves any previous destination untouched.

Inside :func:`staged_outputs` (the command line wraps every command in it) the renames wait
until the whole block has succeeded: a command that writes a matrix and then fails on its
picture leaves neither. An ``OSError`` while writing (full disk, permissions) becomes an
:class:`~geoshape.errors.OutputError` naming the file.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from geoshape.errors import OutputError
from geoshape.parallel import UNFINISHED_FILES

#: Pending ``(temporary, destination)`` renames of the innermost :func:`staged_outputs`.
_STAGE: contextvars.ContextVar[list | None] = contextvars.ContextVar("geoshape_output_stage", default=None)


def _default_mode() -> int:
    """Permissions a plain ``open(path, "w")`` would give: 0o666 minus the umask."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


_FILE_MODE = _default_mode()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    ``suffix`` defaults to the destination's full suffix (``.off.gz`` stays ``.off.gz``)
    so that writers which choose a format by extension see the right one.

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_path(d / "a.txt") as tmp:
    ...     _ = tmp.write_text("hi")
    >>> (d / "a.txt").read_text()
    'hi'
    """
    dest = Path(path)
    if suffix is None:
        suffix = "".join(dest.suffixes[-2:]) if dest.suffixes else ""
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=f".tmp{suffix}", dir=dest.parent)
        # (the name pattern is what leftover_temporaries() looks for)
    except OSError as exc:
        raise _output_error(dest, exc) from None
    tmp = Path(tmp_name)
    UNFINISHED_FILES.add(tmp)  # until renamed or removed (staged: until the block commits)
    os.close(fd)
    stage = _STAGE.get()
    try:
        try:
            yield tmp
            os.chmod(tmp, _FILE_MODE)  # mkstemp creates 0o600 files
            if stage is None:
                os.replace(tmp, dest)
                UNFINISHED_FILES.discard(tmp)
        except OSError as exc:
            raise _output_error(dest, exc) from None
        if stage is not None:
            stage.append((tmp, dest))
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        UNFINISHED_FILES.discard(tmp)
        raise


def leftover_temporaries(path: str | os.PathLike) -> list[Path]:
    """Temporaries that :func:`atomic_path` writes beside ``path`` and that a killed process
    leaves behind (``.NAME.*.tmp*``); for a folder, also those inside it."""
    path = Path(path)
    found = list(path.parent.glob(f".{path.name}.*.tmp*"))
    if path.is_dir():
        found += list(path.glob(".*.tmp*"))
    return found


def _output_error(dest: Path, exc: OSError) -> OutputError:
    reason = "no space left on the device" if exc.errno == errno.ENOSPC else (exc.strerror or str(exc))
    return OutputError(f"{dest}: cannot write: {reason}")


@contextlib.contextmanager
def staged_outputs() -> Iterator[list]:
    """Commit every :func:`atomic_path` output of the block together, or none of them.

    Files written inside the block stay temporaries beside their destinations; when the
    block ends without an exception they are renamed into place (each rename is atomic,
    and nothing slow happens between them), otherwise all are removed and earlier files
    stay untouched. Nested blocks join the outermost one.

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> try:
    ...     with staged_outputs():
    ...         write_text_atomic(d / "a.txt", "first")
    ...         raise RuntimeError("the second output failed")
    ... except RuntimeError:
    ...     pass
    >>> sorted(p.name for p in d.iterdir())
    []
    """
    if _STAGE.get() is not None:  # nested: the outer block commits
        yield _STAGE.get()
        return
    pending: list[tuple[Path, Path]] = []
    token = _STAGE.set(pending)
    try:
        yield pending
    except BaseException:
        for tmp, _dest in pending:
            with contextlib.suppress(OSError):
                tmp.unlink()
        UNFINISHED_FILES.difference_update(tmp for tmp, _dest in pending)
        raise
    finally:
        _STAGE.reset(token)
    try:
        for i, (tmp, dest) in enumerate(pending):
            try:
                os.replace(tmp, dest)
            except OSError as exc:
                for later, _ in pending[i:]:
                    with contextlib.suppress(OSError):
                        later.unlink()
                raise _output_error(dest, exc) from None
    finally:
        UNFINISHED_FILES.difference_update(tmp for tmp, _dest in pending)


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes_atomic(path, text.encode("utf-8"))


def save_npy_atomic(path: str | os.PathLike, array) -> None:
    """Save a NumPy array to ``path`` (``.npy``) atomically."""
    import numpy as np

    with atomic_path(path, suffix=".npy") as tmp:
        np.save(tmp, array)


def save_figure_atomic(fig, path: str | os.PathLike, **savefig_kwargs) -> Path:
    """Save a matplotlib figure atomically; the format follows ``path``'s extension."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_path(path, suffix=path.suffix) as tmp:
        fig.savefig(tmp, format=fmt, **savefig_kwargs)
    return path
