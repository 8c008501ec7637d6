"""Helpers shared by command modules: range-checked option types, JSON output, optional imports."""

from __future__ import annotations

import argparse
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


class RangeType:
    """An ``argparse`` type for a number in ``[low, high]``; its limits are appended to the
    option's ``--help`` by :func:`state_limits`, and a value outside them is a one-line error.

    >>> RangeType(int, 0)("3")
    3
    >>> RangeType(int, 0)("-1")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: must be an integer ≥ 0, got -1
    """

    def __init__(self, kind: type, low=None, high=None):
        self.kind, self.low, self.high = kind, low, high
        self.__name__ = "integer" if kind is int else "number"  # argparse names the type in errors

    @property
    def limits(self) -> str:
        if self.low is not None and self.high is not None:
            return f"{self.low}–{self.high}"
        return f"≥ {self.low}" if self.low is not None else f"≤ {self.high}"

    def __call__(self, text: str):
        try:
            value = self.kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be {'an integer' if self.kind is int else 'a number'}, got {text!r}"
            ) from None
        if (
            value != value
            or (self.low is not None and value < self.low)
            or (self.high is not None and value > self.high)
        ):
            article = "an integer" if self.kind is int else "a number"
            raise argparse.ArgumentTypeError(
                f"must be {article} {self.limits.replace('–', ' to ')}, got {text}"
            )
        return value


#: Shared limits. Seeds are NumPy's (0 to 2³²−1); contour points and workers are capped where
#: more cannot help (4000 points is below one point per boundary pixel of a 1000² image).
SEED = RangeType(int, 0, 2**32 - 1)
WORKERS = RangeType(int, 1, 1024)
CONTOUR_POINTS = RangeType(int, 8, 4000)

#: --n-points help, one home: each method traces its own count (``contour_tracing(method)``),
#: so the text names no number that a new default would leave stale.
N_POINTS_HELP = ("contour points (default: each method's own, geoshape.contour.methods."
                 "contour_tracing)")
POSITIVE_INT = RangeType(int, 1)
NONNEGATIVE_INT = RangeType(int, 0)
POSITIVE_FLOAT = RangeType(float, 1e-12)
NONNEGATIVE_FLOAT = RangeType(float, 0.0)


def state_limits(parser: argparse.ArgumentParser) -> None:
    """Append ``[limits]`` to the help of every option whose type is a :class:`RangeType`,
    in ``parser`` and all its sub-command parsers."""
    for action in parser._actions:
        if isinstance(action.type, RangeType) and action.help and "[" not in action.help:
            action.help = f"{action.help} [{action.type.limits}]"
        elif isinstance(action.type, RangeType) and not action.help:
            action.help = f"[{action.type.limits}]"
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                state_limits(sub)
