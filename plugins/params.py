"""Typed filter parameters, in the spirit of MeshLab's ``RichParameter``.

Each parameter declares its name, default, label and tooltip, and knows how to

- check and coerce a Python value (:meth:`Param.coerce`), never clamping silently: a
  wrong type or an out-of-range value raises :class:`FilterParameterError` quoting it;
- read itself from the text of an ``.mlx`` ``<Param>`` element (:meth:`Param.from_mlx`);
- write itself as ``.mlx`` attributes (:meth:`Param.to_mlx`).

A default is a value or a callable ``default(meshset) -> value`` computed from the
meshes (e.g. "the other mesh", or a sample count capped at the vertex count).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from geoshape.errors import GeoshapeError

__all__ = [
    "FilterError",
    "FilterParameterError",
    "AbsoluteValue",
    "Param",
    "BoolParam",
    "IntParam",
    "FloatParam",
    "PercentageParam",
    "EnumParam",
    "MeshParam",
    "FilePathParam",
    "StringParam",
    "IntListParam",
]


class FilterError(GeoshapeError, ValueError):
    """A filter cannot run: bad parameter, unmet precondition, unknown filter, bad script."""


class FilterParameterError(FilterError):
    """A filter parameter is unknown, of the wrong type or out of range."""


class AbsoluteValue(float):
    """A length in world units given to a :class:`PercentageParam` instead of a percentage.

    >>> AbsoluteValue(0.25)
    AbsoluteValue(0.25)
    """

    def __repr__(self) -> str:
        return f"AbsoluteValue({float(self)!r})"


@dataclass(frozen=True)
class Param:
    """Base class of filter parameters.

    Attributes
    ----------
    name : str
        Keyword of the parameter (snake_case).
    default : value or callable(meshset) -> value
        Used when the parameter is not given.
    label : str
        Short human name (MeshLab's ``description``).
    tooltip : str
        One or two sentences on what it does.
    """

    name: str
    default: Any
    label: str = ""
    tooltip: str = ""

    kind = "value"
    mlx_type = "RichString"

    def error(self, filter_id: str, message: str) -> FilterParameterError:
        return FilterParameterError(f"filter {filter_id!r}, parameter {self.name!r}: {message}")

    def default_value(self, meshset=None) -> Any:
        """The default, computed from ``meshset`` when it is a callable."""
        if callable(self.default):
            return self.default(meshset)
        return self.default

    def describe_default(self) -> str:
        """The default as documentation text."""
        if callable(self.default):
            return getattr(self.default, "__doc__", None) or "computed from the mesh"
        return repr(self.default)

    def coerce(self, value: Any, filter_id: str = "?") -> Any:
        """Check ``value`` and return it in canonical form; raise :class:`FilterParameterError`."""
        return value

    def from_mlx(self, attrs: dict[str, str], filter_id: str = "?") -> Any:
        """Value from the attributes of an ``.mlx`` ``<Param>`` element."""
        if "value" not in attrs:
            raise self.error(filter_id, "the <Param> element has no 'value' attribute")
        return self.coerce(self.parse_text(attrs["value"], filter_id), filter_id)

    def parse_text(self, text: str, filter_id: str) -> Any:
        return text

    def _parse_with(self, convert, text: str, filter_id: str, expected: str) -> Any:
        """``convert(text)``, or this parameter's error saying what was ``expected``."""
        try:
            return convert(text.strip())
        except ValueError:
            raise self.error(filter_id, f"expected {expected}, got {text!r}") from None

    def to_mlx(self, value: Any) -> dict[str, str]:
        """Attributes (``type``, ``value``, …) that write ``value`` to an ``.mlx`` file."""
        return {"type": self.mlx_type, "value": str(value)}

    def type_text(self) -> str:
        """The type as documentation text."""
        return self.kind


def _is_int(value) -> bool:
    return isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, (bool, np.bool_))


def _is_real(value) -> bool:
    return isinstance(value, (numbers.Real, np.floating, np.integer)) and not isinstance(
        value, (bool, np.bool_)
    )


@dataclass(frozen=True)
class BoolParam(Param):
    kind = "bool"
    mlx_type = "RichBool"

    def coerce(self, value, filter_id="?"):
        if not isinstance(value, (bool, np.bool_)):
            raise self.error(filter_id, f"expected a bool, got {value!r} ({type(value).__name__})")
        return bool(value)

    def parse_text(self, text, filter_id):
        low = text.strip().lower()
        if low in ("true", "1"):
            return True
        if low in ("false", "0"):
            return False
        raise self.error(filter_id, f"expected 'true' or 'false', got {text!r}")

    def to_mlx(self, value):
        return {"type": self.mlx_type, "value": "true" if value else "false"}


@dataclass(frozen=True)
class _Ranged(Param):
    min: float | None = None
    max: float | None = None

    def _check_range(self, value, filter_id):
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            lo = "-inf" if self.min is None else f"{self.min:g}"
            hi = "inf" if self.max is None else f"{self.max:g}"
            raise self.error(filter_id, f"must lie in [{lo}, {hi}], got {value!r}")
        return value

    def type_text(self):
        if self.min is None and self.max is None:
            return self.kind
        lo = "-inf" if self.min is None else f"{self.min:g}"
        hi = "inf" if self.max is None else f"{self.max:g}"
        return f"{self.kind} in [{lo}, {hi}]"


@dataclass(frozen=True)
class IntParam(_Ranged):
    kind = "int"
    mlx_type = "RichInt"

    def coerce(self, value, filter_id="?"):
        if not _is_int(value):
            raise self.error(filter_id, f"expected an int, got {value!r} ({type(value).__name__})")
        return self._check_range(int(value), filter_id)

    def parse_text(self, text, filter_id):
        return self._parse_with(int, text, filter_id, "an integer")


@dataclass(frozen=True)
class FloatParam(_Ranged):
    kind = "float"
    mlx_type = "RichFloat"

    def coerce(self, value, filter_id="?"):
        if not _is_real(value):
            raise self.error(filter_id, f"expected a number, got {value!r} ({type(value).__name__})")
        value = float(value)
        if not math.isfinite(value):
            raise self.error(filter_id, f"must be finite, got {value!r}")
        return self._check_range(value, filter_id)

    def parse_text(self, text, filter_id):
        return self._parse_with(float, text, filter_id, "a number")

    def to_mlx(self, value):
        return {"type": self.mlx_type, "value": repr(float(value))}


@dataclass(frozen=True)
class PercentageParam(_Ranged):
    """A length given as a percentage of the mesh's bounding-box diagonal.

    The value is a percentage in ``[min, max]`` (default ``[0, 100]``), or an
    :class:`AbsoluteValue` in world units (MeshLab's ``RichAbsPerc``), which is kept as is
    and converted by :meth:`absolute`.
    """

    min: float | None = 0.0
    max: float | None = 100.0
    kind = "percentage of the bounding-box diagonal"
    mlx_type = "RichPercentage"

    def coerce(self, value, filter_id="?"):
        if isinstance(value, AbsoluteValue):
            if not math.isfinite(value) or value < 0:
                raise self.error(filter_id, f"absolute length must be finite and >= 0, got {value!r}")
            return value
        if not _is_real(value):
            raise self.error(
                filter_id, f"expected a percentage (number), got {value!r} ({type(value).__name__})"
            )
        value = float(value)
        if not math.isfinite(value):
            raise self.error(filter_id, f"must be finite, got {value!r}")
        return self._check_range(value, filter_id)

    def from_mlx(self, attrs, filter_id="?"):
        if attrs.get("type") == "RichAbsPerc":  # MeshLab writes the absolute value
            try:
                return self.coerce(AbsoluteValue(float(attrs.get("value", ""))), filter_id)
            except ValueError:
                raise self.error(filter_id, f"expected a number, got {attrs.get('value')!r}") from None
        return super().from_mlx(attrs, filter_id)

    def parse_text(self, text, filter_id):
        return self._parse_with(float, text, filter_id, "a number")

    def to_mlx(self, value):
        if isinstance(value, AbsoluteValue):
            return {"type": "RichAbsPerc", "value": repr(float(value))}
        return {"type": self.mlx_type, "value": repr(float(value))}

    @staticmethod
    def absolute(value, diagonal: float) -> float:
        """World length of ``value`` on a mesh whose bounding-box diagonal is ``diagonal``."""
        if isinstance(value, AbsoluteValue):
            return float(value)
        return float(value) / 100.0 * float(diagonal)


@dataclass(frozen=True)
class EnumParam(Param):
    choices: tuple[str, ...] = ()
    kind = "enum"
    mlx_type = "RichEnum"

    def coerce(self, value, filter_id="?"):
        if not isinstance(value, str) or value not in self.choices:
            listed = ", ".join(repr(c) for c in self.choices)
            raise self.error(filter_id, f"must be one of {listed}; got {value!r}")
        return value

    def from_mlx(self, attrs, filter_id="?"):
        text = attrs.get("value", "")
        if text in self.choices:
            return text
        try:  # MeshLab writes the index of the choice
            index = int(text)
        except ValueError:
            return self.coerce(text, filter_id)
        if not 0 <= index < len(self.choices):
            raise self.error(filter_id, f"enum index {index} out of range [0, {len(self.choices) - 1}]")
        return self.choices[index]

    def to_mlx(self, value):
        attrs = {"type": self.mlx_type, "value": str(self.choices.index(value)),
                 "enum_cardinality": str(len(self.choices))}
        for i, c in enumerate(self.choices):
            attrs[f"enum_val{i}"] = c
        return attrs

    def type_text(self):
        return "enum: " + " | ".join(self.choices)


@dataclass(frozen=True)
class MeshParam(Param):
    """A reference to another mesh of the MeshSet, by its index."""

    kind = "mesh"
    mlx_type = "RichMesh"

    def coerce(self, value, filter_id="?"):
        if not _is_int(value) or value < 0:
            raise self.error(filter_id, f"expected a mesh index (int >= 0), got {value!r}")
        return int(value)

    def parse_text(self, text, filter_id):
        return self._parse_with(int, text, filter_id, "a mesh index")


@dataclass(frozen=True)
class FilePathParam(Param):
    """A file path (the filter receives the string; it does no file work itself)."""

    kind = "file path"
    mlx_type = "RichFileOpen"

    def coerce(self, value, filter_id="?"):
        if not isinstance(value, (str, os.PathLike)):
            raise self.error(filter_id, f"expected a file path, got {value!r} ({type(value).__name__})")
        return os.fspath(value)


@dataclass(frozen=True)
class StringParam(Param):
    kind = "str"
    mlx_type = "RichString"

    def coerce(self, value, filter_id="?"):
        if not isinstance(value, str):
            raise self.error(filter_id, f"expected a string, got {value!r} ({type(value).__name__})")
        return value


@dataclass(frozen=True)
class IntListParam(Param):
    """A list of non-negative integers (e.g. vertex ids); in ``.mlx`` a space-separated string."""

    kind = "list of int"
    mlx_type = "RichString"
    default: Any = field(default_factory=tuple)

    def coerce(self, value, filter_id="?"):
        if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
            raise self.error(filter_id, f"expected a list of ints, got {value!r} ({type(value).__name__})")
        out = []
        for v in list(value):
            if not _is_int(v) or v < 0:
                raise self.error(filter_id, f"expected ints >= 0, got {v!r} in the list")
            out.append(int(v))
        return tuple(out)

    def parse_text(self, text, filter_id):
        try:
            return [int(t) for t in text.replace(",", " ").split()]
        except ValueError:
            raise self.error(filter_id, f"expected space-separated integers, got {text!r}") from None

    def to_mlx(self, value):
        return {"type": self.mlx_type, "value": " ".join(str(v) for v in value)}


ParamDefault = Callable[[Any], Any]
