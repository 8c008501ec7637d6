"""Doctest collection of the folders that install under another name.

``plugins/`` and ``datasets_gen/`` install as ``geoshape_plugins`` and
``geoshape_datasets_gen``. Collecting their doctests (``--doctest-modules``, see
pyproject.toml) would import each file a second time as ``plugins.<module>``: a second copy
whose import side effects (e.g. registering the filters) clash with the first. Before a
file of these folders is collected, its module is imported under the installed name and
registered under the folder's name too, so pytest finds the one true module (same
``__file__``) instead of importing a copy.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

_ROOT = Path(__file__).resolve().parent
_INSTALLED_AS = {"plugins": "geoshape_plugins", "datasets_gen": "geoshape_datasets_gen"}


def pytest_collect_file(file_path, parent):
    if file_path.suffix != ".py":
        return None
    try:
        folder, *rest = file_path.resolve().relative_to(_ROOT).parts
    except ValueError:
        return None
    if folder not in _INSTALLED_AS or len(rest) != 1:
        return None
    real = _INSTALLED_AS[folder]
    sys.modules.setdefault(folder, importlib.import_module(real))
    stem = Path(rest[0]).stem
    if stem != "__init__":
        sys.modules.setdefault(f"{folder}.{stem}", importlib.import_module(f"{real}.{stem}"))
    return None
