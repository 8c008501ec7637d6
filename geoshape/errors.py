"""The error hierarchy of geoshape.

Every error that a user can cause (bad file, bad array, bad option) is raised as a
subclass of :class:`GeoshapeError`, with a message naming the input and what is wrong.
The command line turns these into a one-line message and exit code 2.
"""

from __future__ import annotations

__all__ = [
    "GeoshapeError",
    "InvalidMeshError",
    "InvalidContourError",
    "InvalidImageError",
    "DatasetError",
    "MissingDependencyError",
    "InvalidOptionError",
    "ResourceLimitError",
    "OutputError",
]


class GeoshapeError(Exception):
    """Base class of every error geoshape raises on purpose."""


class InvalidMeshError(GeoshapeError, ValueError):
    """A mesh (file or ``(V, F)`` arrays) cannot be used: wrong shape, NaN, bad faces…"""


class InvalidContourError(GeoshapeError, ValueError):
    """A 2D contour ``(N, 2)`` cannot be used: too few points, open, NaN, degenerate…"""


class InvalidImageError(GeoshapeError, ValueError):
    """A silhouette image cannot be used: unreadable, empty, all foreground, too small…"""


class DatasetError(GeoshapeError):
    """A benchmark folder, ``labels.csv`` or ``pairs.csv`` is missing or malformed."""


class MissingDependencyError(GeoshapeError, ImportError):
    """An optional dependency needed by the requested feature is not installed."""


class InvalidOptionError(GeoshapeError, ValueError):
    """A string option names no registered choice, or a parameter is out of range."""


class ResourceLimitError(GeoshapeError, MemoryError):
    """The request would need more memory than this machine can give (e.g. all-pairs n x n)."""


class OutputError(GeoshapeError, OSError):
    """An output path cannot be written: missing or read-only folder, a folder where a file
    should go, an extension no writer supports, a full disk."""
