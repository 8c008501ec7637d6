"""geoshape: robust correspondence and retrieval of articulated shapes.

2D closed contours (geodesic shape context) and 3D triangle meshes (spectral
embeddings of geodesic affinities). Heavy submodules are imported lazily, so
``import geoshape`` and ``geoshape --help`` stay fast.
"""

from __future__ import annotations

import importlib

from geoshape import errors as _errors
from geoshape.errors import *  # noqa: F403  (the error classes, listed in errors.__all__)

__version__ = "0.1.0"

# name -> module that defines it; resolved on first attribute access.
_LAZY = {
    "load_mesh": "geoshape.io.mesh_io",
    "save_mesh": "geoshape.io.mesh_io",
    "check_mesh": "geoshape.io.validate",
    "check_contour": "geoshape.io.validate",
    "mesh_report": "geoshape.geometry.report",
    "as_arrays": "geoshape.io.interop",
    "load_silhouette": "geoshape.io.silhouette",
    "extract_contour": "geoshape.geometry.contour",
}

__all__ = ["__version__", *_errors.__all__, *_LAZY]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'geoshape' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
