"""The ``MAP.txt`` format: one line per source vertex, its 0-based target vertex id."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from geoshape.errors import InvalidOptionError
from geoshape.io.atomic import write_text_atomic


def write_map(path: str | os.PathLike, p2p_12) -> Path:
    """Write ``p2p_12 (n1,)`` atomically, one integer per line."""
    p2p = np.asarray(p2p_12)
    if p2p.ndim != 1 or p2p.dtype.kind not in "iu":
        raise InvalidOptionError(f"a vertex map must be a 1-D integer array, got {p2p.dtype} {p2p.shape}")
    write_text_atomic(path, "".join(f"{int(j)}\n" for j in p2p))
    return Path(path)


def read_map(path: str | os.PathLike) -> np.ndarray:
    """Read a ``MAP.txt`` file back as an (n1,) int64 array."""
    return np.loadtxt(path, dtype=np.int64, ndmin=1)
