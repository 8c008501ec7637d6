"""``geoshape filters``: list the registered filters with their parameters and defaults.

``--json`` prints one JSON list; ``--markdown`` prints the page ``docs/filters.md``
(regenerate it with ``geoshape filters --markdown > docs/filters.md``).
"""

from __future__ import annotations

import argparse


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "filters",
        help="list the MeshLab-style filters (ids, parameters, defaults)",
        description="List geoshape's filters, usable from Python (geoshape_plugins.MeshSet), in .mlx "
        "scripts and with 'geoshape run'.",
    )
    group = p.add_mutually_exclusive_group()
    group.add_argument("--json", action="store_true", help="print one JSON list")
    group.add_argument("--markdown", action="store_true",
                       help="print the Markdown reference page (docs/filters.md)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from geoshape_plugins.docs import filter_summary, filters_markdown
    from geoshape_plugins.registry import list_filters

    if args.markdown:
        print(filters_markdown(), end="")
        return 0
    filters = list_filters()
    if args.json:
        from geoshape.cli._common import print_json

        print_json([filter_summary(f) for f in filters])
        return 0
    for f in filters:
        print(f"{f.id}  ({f.name}; {f.arity.value}; {', '.join(f.categories)})")
        for p in f.params:
            print(f"    {p.name}: {p.type_text()} = {p.describe_default()}")
    print(f"{len(filters)} filters; PyMeshLab filters may be used in scripts by name as well")
    return 0
