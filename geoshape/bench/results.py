"""Writing measured tables into ``docs/RESULTS.md``.

Each benchmark owns one section of the file, delimited by HTML comments
``<!-- BEGIN name -->`` … ``<!-- END name -->``; re-running a benchmark replaces only its
own section, so every number in the file is traceable to the command that wrote it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from geoshape.io.atomic import write_text_atomic

HEADER = (
    "# geoshape — measured results\n\n"
    "Every table below is written by the command named in its section; do not edit by hand.\n"
    "Machine: the project's CI machine kind (2 cores, 24 GB, no GPU) unless a section says otherwise.\n"
)


def default_results_path() -> Path:
    """``$GEOSHAPE_RESULTS`` if set, else ``docs/RESULTS.md`` of the source checkout."""
    env = os.environ.get("GEOSHAPE_RESULTS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "docs" / "RESULTS.md"


def update_results_section(name: str, markdown: str, path: str | os.PathLike | None = None) -> Path:
    """Replace (or append) section ``name`` of the results file with ``markdown``."""
    target = Path(path) if path is not None else default_results_path()
    text = target.read_text(encoding="utf-8") if target.exists() else HEADER
    begin, end = f"<!-- BEGIN {name} -->", f"<!-- END {name} -->"
    block = f"{begin}\n{markdown.rstrip()}\n{end}"
    pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.DOTALL)
    if pattern.search(text):
        text = pattern.sub(lambda _m: block, text)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    write_text_atomic(target, text)
    return target


def markdown_table(header: list[str], rows: list[list]) -> str:
    """A GitHub-flavoured Markdown table; floats printed with 4 significant digits."""

    def fmt(x) -> str:
        if isinstance(x, float):
            return f"{x:.4g}"
        return str(x)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(x) for x in row) + " |" for row in rows]
    return "\n".join(lines)


def workers_note(n: int) -> str:
    """``"1 worker"``, ``"2 workers"``: how many processes a run used, for section headers.

    >>> workers_note(1), workers_note(2)
    ('1 worker', '2 workers')
    """
    return f"{n} worker" + ("" if n == 1 else "s")
