"""The filter registry: declarations in MeshLab's spirit (``filter_plugin.h``), not its code.

A :class:`Filter` declares a stable snake_case ``id`` (what scripts and Python use), a
display ``name``, a description with its citation, category flags, its arity, typed
parameters, preconditions and ``apply(meshset, params, progress) -> dict``. ``apply``
does no file or UI work, reports progress through ``progress(fraction, message)`` and
raises :class:`~geoshape_plugins.params.FilterError` (or another
:class:`~geoshape.errors.GeoshapeError`) only.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from geoshape_plugins.params import FilterError, FilterParameterError, Param

__all__ = [
    "Arity",
    "Precondition",
    "Filter",
    "FILTERS",
    "register",
    "get_filter",
    "find_filter",
    "list_filters",
    "resolve_params",
    "HAS_FACES",
]


class Arity(enum.Enum):
    """How many meshes a filter works on."""

    SINGLE = "one mesh"
    PAIR = "two meshes"
    VARIABLE = "any number of meshes"


@dataclass(frozen=True)
class Precondition:
    """A named requirement on the current mesh: ``check(mesh)`` returns None or what is missing."""

    name: str
    check: Callable[[Any], str | None]


def _has_faces(mesh) -> str | None:
    return None if len(mesh.F) else "has no faces"


HAS_FACES = Precondition("a mesh with faces", _has_faces)


@dataclass(frozen=True)
class Filter:
    """Declaration of one filter.

    Attributes
    ----------
    id : str
        Stable snake_case identifier: the method name on :class:`~geoshape_plugins.meshset.MeshSet`
        and the ``id`` attribute in ``.mlx`` scripts.
    name : str
        Display name (MeshLab style); may change between versions, the id does not.
    description : str
        What it does, with the citation of the method.
    categories : tuple of str
        Category flags, e.g. ``("measure", "quality")``.
    arity : Arity
    params : tuple of Param
    preconditions : tuple of Precondition
    apply : callable
        ``apply(meshset, params, progress) -> dict`` of outputs.
    """

    id: str
    name: str
    description: str
    categories: tuple[str, ...]
    arity: Arity
    params: tuple[Param, ...]
    preconditions: tuple[Precondition, ...]
    apply: Callable[..., dict]

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise FilterParameterError(
            f"parameter {name!r} not found for filter {self.id!r}; "
            f"valid parameters: {', '.join(p.name for p in self.params) or '(none)'}"
        )

    @property
    def param_names(self) -> list[str]:
        return [p.name for p in self.params]


FILTERS: dict[str, Filter] = {}


def register(f: Filter) -> Filter:
    """Add ``f`` to :data:`FILTERS` (ids and display names must be unique)."""
    if f.id in FILTERS:
        raise FilterError(f"filter id {f.id!r} is already registered")
    if any(g.name == f.name for g in FILTERS.values()):
        raise FilterError(f"filter display name {f.name!r} is already registered")
    FILTERS[f.id] = f
    return f


def _ensure_loaded() -> None:
    import geoshape_plugins.geoshape_filters  # noqa: F401  (registers the filters on import)


def list_filters() -> list[Filter]:
    """Every registered filter, in registration order."""
    _ensure_loaded()
    return list(FILTERS.values())


def find_filter(key: str) -> Filter | None:
    """The filter whose id or display name is ``key``, or None."""
    _ensure_loaded()
    if key in FILTERS:
        return FILTERS[key]
    for f in FILTERS.values():
        if f.name == key:
            return f
    return None


def get_filter(key: str) -> Filter:
    """The filter with id or display name ``key``; :class:`FilterError` listing the ids if none."""
    f = find_filter(key)
    if f is None:
        raise FilterError(f"unknown filter {key!r}; geoshape filters: {', '.join(FILTERS)}")
    return f


def resolve_params(f: Filter, given: dict[str, Any], meshset=None) -> dict[str, Any]:
    """Check ``given`` against the declaration of ``f`` and fill in defaults.

    Parameters
    ----------
    f : Filter
    given : dict
        Parameters passed by the caller; unknown names and wrong types are rejected.
    meshset : MeshSet, optional
        Used to compute defaults that depend on the meshes.

    Returns
    -------
    dict with a value for every declared parameter, in declaration order.

    Raises
    ------
    FilterParameterError
        Unknown name (the message lists the valid ones), wrong type, out of range, enum
        value not among the choices.
    """
    unknown = [k for k in given if k not in f.param_names]
    if unknown:
        raise FilterParameterError(
            f"parameter {unknown[0]!r} not found for filter {f.id!r}; "
            f"valid parameters: {', '.join(f.param_names) or '(none)'}"
        )
    out = {}
    for p in f.params:
        value = given[p.name] if p.name in given else p.default_value(meshset)
        out[p.name] = p.coerce(value, f.id)
    return out
