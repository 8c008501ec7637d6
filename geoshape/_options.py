"""Checking options: strings against the registries that define them, numbers against ranges."""

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


def is_real_number(value) -> bool:
    """A real number: an int or float (NumPy's too), not a bool, not a string.

    >>> is_real_number(0.25), is_real_number(True), is_real_number("0.25")
    (True, False, False)
    """
    import numpy as np

    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def check_whole(name: str, value, lo: int, hi: int | None = None) -> int:
    """``value`` as an int if it is a whole number in ``[lo, hi]`` (``hi`` None: no upper bound).

    Floats with no fraction pass (``3.0``); bools, fractions, NaN and non-numbers do not.

    >>> check_whole("poses", 3.0, 1, 10)
    3
    >>> check_whole("seed", -1, 0)
    Traceback (most recent call last):
    ...
    geoshape.errors.InvalidOptionError: seed must be a whole number >= 0, got -1
    """
    try:
        ok = not isinstance(value, bool) and float(value).is_integer()
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok or int(value) < lo or (hi is not None and int(value) > hi):
        where = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
        raise InvalidOptionError(f"{name} must be a whole number {where}, got {value!r}")
    return int(value)
