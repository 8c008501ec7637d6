"""MeshLab-style filters built on the geoshape library.

- :mod:`plugins.params` — typed parameters (bool, int, float, percentage of the
  bounding-box diagonal, enum, mesh reference, file path, string, list of ints) and
  :class:`~plugins.params.FilterError`;
- :mod:`plugins.registry` — :class:`~plugins.registry.Filter` declarations and the registry;
- :mod:`plugins.geoshape_filters` — geoshape's filters (thin ``apply`` over the library);
- :mod:`plugins.meshset` — ``geoshape.MeshSet`` with one generated method per filter;
- :mod:`plugins.mlx` — reading and writing MeshLab ``.mlx`` scripts;
- :mod:`plugins.pymeshlab_bridge` — running PyMeshLab filters on a geoshape MeshSet;
- :mod:`plugins.docs` — ``docs/filters.md`` generated from the registry.
"""
