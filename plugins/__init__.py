"""MeshLab-style filters built on the geoshape library (installed as ``geoshape_plugins``).

- :mod:`geoshape_plugins.params` — typed parameters (bool, int, float, percentage of the
  bounding-box diagonal, enum, mesh reference, file path, string, list of ints) and
  :class:`~geoshape_plugins.params.FilterError`;
- :mod:`geoshape_plugins.registry` — :class:`~geoshape_plugins.registry.Filter` declarations and the registry;
- :mod:`geoshape_plugins.geoshape_filters` — geoshape's filters (thin ``apply`` over the library);
- :mod:`geoshape_plugins.meshset` — ``geoshape_plugins.MeshSet`` with one generated method per filter;
- :mod:`geoshape_plugins.mlx` — reading and writing MeshLab ``.mlx`` scripts;
- :mod:`geoshape_plugins.pymeshlab_bridge` — running PyMeshLab filters on a geoshape MeshSet;
- :mod:`geoshape_plugins.docs` — ``docs/filters.md`` generated from the registry.
"""

from __future__ import annotations

import importlib

__all__ = ["MeshSet"]


def __getattr__(name: str):
    if name == "MeshSet":  # lazy: importing the package does not load PyMeshLab or the filters
        return importlib.import_module("geoshape_plugins.meshset").MeshSet
    raise AttributeError(f"module 'geoshape_plugins' has no attribute {name!r}")
