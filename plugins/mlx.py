"""Reading and writing MeshLab ``.mlx`` filter scripts.

Format (MeshLab's)::

    <!DOCTYPE FilterScript>
    <FilterScript>
     <filter name="Display Name">
      <Param type="RichInt" name="Name" value="3"/>
     </filter>
    </FilterScript>

geoshape writes its own filters with their stable id as well:
``<filter id="spectral_correspondence" name="Spectral Correspondence">``; on reading, ``id``
takes precedence over ``name`` (MeshLab keys scripts by display name, which breaks them
when a name changes). Reading is lenient: MeshLab's documentation attributes (``tooltip``,
``description``, ``isxmlparam``, ``isxmlfilter``…, entities decoded) are skipped silently,
other attributes and elements not needed to run a filter are ignored with one warning per
script; ``<xmlfilter>``/``<xmlparam>`` elements of MeshLab 2016's XML filters are read
like ``<filter>``/``<Param>`` (without a ``type``, a value takes the type of the filter's
default). Malformed XML raises :class:`FilterScriptError` with the line number.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat
from xml.sax.saxutils import quoteattr

from geoshape_plugins.params import FilterError

__all__ = ["FilterScriptError", "ScriptParam", "ScriptFilter", "read_mlx", "parse_mlx", "write_mlx",
           "mlx_text"]


class FilterScriptError(FilterError):
    """A filter script cannot be read or run (malformed XML, unknown filter, …)."""


#: attributes of <Param> needed to run a filter (others are documentation, ignored)
_PARAM_ATTRS = {"name", "type", "value", "x", "y", "z", "r", "g", "b", "a", "min", "max",
                "enum_cardinality"}
_FILTER_ATTRS = {"name", "id"}
#: attributes MeshLab writes for people, not for running the filter (skipped silently)
_DOC_ATTRS = {"tooltip", "description", "isxmlparam", "isxmlfilter", "category", "help"}


@dataclass
class ScriptParam:
    """One ``<Param>``: its name and the attributes that carry its value."""

    name: str
    attrs: dict[str, str]
    line: int = 0


@dataclass
class ScriptFilter:
    """One ``<filter>`` of a script.

    Attributes
    ----------
    id : str or None
        Stable id (geoshape filters, and PyMeshLab filters written by geoshape).
    name : str or None
        Display name.
    params : list of ScriptParam
    line : int
        Line of the ``<filter>`` element in the file (0 when built in memory).
    """

    id: str | None
    name: str | None
    params: list[ScriptParam] = field(default_factory=list)
    line: int = 0

    @property
    def key(self) -> str:
        """What identifies the filter: the id if present, else the display name."""
        return self.id or self.name or ""


def _is_param_attr(key: str) -> bool:
    return key in _PARAM_ATTRS or key.startswith(("enum_val", "val"))


def parse_mlx(text: str | bytes, source: str = "<script>") -> list[ScriptFilter]:
    """Parse the text of an ``.mlx`` script.

    Parameters
    ----------
    text : str or bytes
    source : str
        Name used in messages (the file name).

    Returns
    -------
    list of ScriptFilter, in script order.

    Raises
    ------
    FilterScriptError
        Malformed XML, no ``<FilterScript>`` root, a filter without ``name`` and ``id``,
        a parameter without ``name``.

    Warns
    -----
    UserWarning
        Once per script, naming the ignored attributes.
    """
    parser = expat.ParserCreate()
    filters: list[ScriptFilter] = []
    ignored: set[str] = set()
    state = {"root": False, "current": None}

    def start(tag, attrs):
        line = parser.CurrentLineNumber
        if tag == "FilterScript":
            state["root"] = True
        elif tag in ("filter", "xmlfilter"):
            if not (attrs.get("name") or attrs.get("id")):
                raise FilterScriptError(f"{source}:{line}: <{tag}> has neither 'name' nor 'id'")
            ignored.update(k for k in attrs if k not in _FILTER_ATTRS | _DOC_ATTRS)
            f = ScriptFilter(attrs.get("id") or None, attrs.get("name") or None, [], line)
            filters.append(f)
            state["current"] = f
        elif tag in ("Param", "xmlparam"):
            if state["current"] is None:
                raise FilterScriptError(f"{source}:{line}: <{tag}> outside a <filter>")
            if "name" not in attrs:
                raise FilterScriptError(f"{source}:{line}: <{tag}> has no 'name'")
            ignored.update(k for k in attrs if not _is_param_attr(k) and k not in _DOC_ATTRS)
            kept = {k: v for k, v in attrs.items() if _is_param_attr(k)}
            state["current"].params.append(ScriptParam(attrs["name"], kept, line))
        else:
            ignored.add(f"<{tag}>")

    def end(tag):
        if tag in ("filter", "xmlfilter"):
            state["current"] = None

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(text, True)
    except expat.ExpatError as exc:
        raise FilterScriptError(f"{source}:{exc.lineno}: malformed XML: {expat.ErrorString(exc.code)}") \
            from None
    if not state["root"]:
        raise FilterScriptError(f"{source}: not a MeshLab filter script (no <FilterScript> element)")
    if ignored:
        warnings.warn(
            f"{source}: ignored attributes/elements not needed to run the filters: "
            f"{', '.join(sorted(ignored))}",
            UserWarning,
            stacklevel=2,
        )
    return filters


def read_mlx(path: str | os.PathLike) -> list[ScriptFilter]:
    """Read an ``.mlx`` file (see :func:`parse_mlx`); :class:`FilterScriptError` if unreadable."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FilterScriptError(f"{path}: cannot read the script: {exc.strerror or exc}") from None
    return parse_mlx(data, str(path))


def mlx_text(filters: list[ScriptFilter]) -> str:
    """The ``.mlx`` text of ``filters`` (id before name; parameters with name, type, value…)."""
    lines = ["<!DOCTYPE FilterScript>", "<FilterScript>"]
    for f in filters:
        head = []
        if f.id:
            head.append(f"id={quoteattr(f.id)}")
        if f.name:
            head.append(f"name={quoteattr(f.name)}")
        if not f.params:
            lines.append(f" <filter {' '.join(head)}/>")
            continue
        lines.append(f" <filter {' '.join(head)}>")
        for p in f.params:
            attrs = {"name": p.name, **{k: v for k, v in p.attrs.items() if k != "name"}}
            order = ["name", "type", "value"]
            keys = [k for k in order if k in attrs] + [k for k in attrs if k not in order]
            body = " ".join(f"{k}={quoteattr(str(attrs[k]))}" for k in keys)
            lines.append(f"  <Param {body}/>")
        lines.append(" </filter>")
    lines.append("</FilterScript>")
    return "\n".join(lines) + "\n"


def write_mlx(path: str | os.PathLike, filters: list[ScriptFilter]) -> Path:
    """Write ``filters`` to ``path`` atomically; returns the path."""
    from geoshape.io.atomic import write_text_atomic

    write_text_atomic(path, mlx_text(filters))
    return Path(path)
