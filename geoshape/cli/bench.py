"""``geoshape bench NAME …``: benchmarks that write their tables into ``docs/RESULTS.md``.

Registration is table-driven: :data:`BENCHMARKS` lists ``(name, module)`` pairs and a
module that does not exist (yet) is skipped. To add a benchmark, write
``geoshape/bench/<name>.py`` exposing

- ``HELP``: a one-line description (str),
- ``add_arguments(parser)``: add the benchmark's options to its ``argparse`` parser,
- ``run(args) -> int``: do the work, call
  :func:`geoshape.bench.results.update_results_section`, return an exit code,

keep its top-level imports light (NumPy at most; heavy imports inside ``run``), and append
``("<name>", "geoshape.bench.<name>")`` to :data:`BENCHMARKS`.
"""

from __future__ import annotations

from geoshape.cli._common import import_if_present

#: (sub-command, module) pairs, in the order ``geoshape bench --help`` lists them.
BENCHMARKS: list[tuple[str, str]] = [
    ("kimia99", "geoshape.bench.kimia99"),
    ("tari1000", "geoshape.bench.tari1000"),
    ("geodesics", "geoshape.bench.geodesics"),
    ("spectral", "geoshape.bench.spectral"),
    ("correspondence", "geoshape.bench.correspondence"),
    ("retrieval3d", "geoshape.bench.retrieval3d"),
    ("evd", "geoshape.bench.evd"),
    ("knn", "geoshape.bench.knn"),
    ("reliability", "geoshape.bench.reliability"),
    ("rerank", "geoshape.bench.rerank"),
    ("mirror2d", "geoshape.bench.mirror2d"),
    ("speed2d", "geoshape.bench.speed2d"),
    ("coarse2d", "geoshape.bench.coarse2d"),
    ("decimate", "geoshape.bench.decimate"),
    ("mlx", "geoshape.bench.mlx"),
    ("index", "geoshape.bench.index"),
    ("fusion", "geoshape.bench.fusion"),
]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "bench",
        help="run a benchmark and write its table into docs/RESULTS.md",
        description="Benchmarks on the data of ../shared/data (or $GEOSHAPE_DATA); each writes "
        "its own section of docs/RESULTS.md (or $GEOSHAPE_RESULTS).",
    )
    sub = p.add_subparsers(dest="benchmark", metavar="BENCHMARK")
    for name, module_name in BENCHMARKS:
        module = import_if_present(module_name)
        if module is None:
            continue
        bp = sub.add_parser(name, help=getattr(module, "HELP", None),
                            description=getattr(module, "HELP", None))
        module.add_arguments(bp)
        bp.set_defaults(handler=module.run)
    p.set_defaults(handler=lambda args: _no_benchmark(p))


def _no_benchmark(parser) -> int:
    parser.print_help()
    return 2
