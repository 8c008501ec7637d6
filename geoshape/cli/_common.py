"""Helpers shared by command modules (output of JSON, tables)."""

from __future__ import annotations

import importlib
import json
import sys
from types import ModuleType
from typing import Any


def import_if_present(module_name: str) -> ModuleType | None:
    """Import ``module_name``, or return None if that module itself does not exist.

    Registries of sub-commands list modules that a feature adds; a missing one is skipped,
    while an import error *inside* an existing module still propagates.
    """
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:
            return None
        raise


def to_jsonable(value: Any) -> Any:
    """Convert NumPy scalars/arrays (recursively) into plain JSON types."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover - numpy is a hard dependency
        np = None
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if np is not None:
        if isinstance(value, np.ndarray):
            return to_jsonable(value.tolist())
        if isinstance(value, np.generic):
            return value.item()
    if isinstance(value, float) and value != value:  # NaN is not JSON
        return None
    return value


def print_json(obj: Any) -> None:
    json.dump(to_jsonable(obj), sys.stdout, indent=2)
    sys.stdout.write("\n")
