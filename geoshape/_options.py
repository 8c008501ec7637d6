"""Checking string options against the registries that define them."""

from __future__ import annotations

from collections.abc import Iterable

from geoshape.errors import InvalidOptionError


def check_choice(name: str, value: str, choices: Iterable[str]) -> str:
    """Return ``value`` if it is one of ``choices``, else raise listing the allowed values.

    >>> check_choice("method", "graph", ["graph", "heat"])
    'graph'
    """
    allowed = list(choices)
    if value not in allowed:
        listed = ", ".join(repr(c) for c in allowed)
        raise InvalidOptionError(f"{name} must be one of {listed}; got {value!r}")
    return value
