"""``geoshape experiment NAME --out DIR``: the thesis' chapter-4 experiments (issue 6).

Each experiment writes ``DIR/NAME.png`` (plot), ``DIR/NAME.csv`` and ``DIR/NAME.json``
(table and settings), updates its section of ``docs/RESULTS.md`` (unless
``--no-results``) and prints a summary table. The registry is
:data:`geoshape.bench.experiments.EXPERIMENTS`.
"""

from __future__ import annotations

import argparse

from geoshape.cli._common import import_if_present


def register(subparsers) -> None:
    from geoshape.bench.experiments import EXPERIMENTS

    p = subparsers.add_parser(
        "experiment",
        help="run a thesis experiment (scaling, gaussian-width, switching, reordering)",
        description="Chapter-4 experiments of the thesis on tosca_r5k and generated meshes; each "
        "writes a PNG plot and a CSV/JSON table to --out and its section of docs/RESULTS.md.",
    )
    sub = p.add_subparsers(dest="experiment", metavar="NAME")
    for name, module_name in EXPERIMENTS:
        module = import_if_present(module_name)
        if module is None:
            continue
        ep = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(ep)
        ep.set_defaults(handler=lambda args, m=module: run(args, m))
    p.set_defaults(handler=lambda args: _no_experiment(p))


def _no_experiment(parser) -> int:
    parser.print_help()
    return 2


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def run(args: argparse.Namespace, module) -> int:
    rows = module.run_experiment(args.out, seed=args.seed, data_dir=args.data,
                                 results=not args.no_results, **module.settings(args))
    columns = [c for c in module.SUMMARY if rows and c in rows[0]]
    table = [columns] + [[_fmt(r.get(c, "")) for c in columns] for r in rows]
    widths = [max(len(line[i]) for line in table) for i in range(len(columns))]
    for line in table:
        print("  ".join(cell.rjust(w) for cell, w in zip(line, widths, strict=False)))
    print(f"wrote {args.out}/{module.NAME}.png, .csv, .json")
    return 0
