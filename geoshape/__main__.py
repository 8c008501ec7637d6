"""The ``geoshape`` command line.

Each sub-command lives in its own module ``geoshape/cli/<name>.py`` exposing
``register(subparsers)``; that module must import nothing heavy at top level, so
``geoshape --help`` stays instant. Heavy imports happen inside the command's handler.

Exit codes: 0 success, 1 the command ran but reported failures (e.g. some files of a
batch were skipped), 2 bad usage or bad input (one line on stderr, no traceback),
130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

# Sub-command modules, in the order --help lists them. A module that does not exist
# yet is skipped, so each feature registers itself by adding its file.
COMMAND_MODULES = [
    "info",
    "match2d",
    "retrieval2d",
    "embed",
    "correspond",
    "retrieval3d",
    "index",
    "gen",
    "experiment",
    "bench",
    "filters",
    "run",
    "demo",
]


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line (``geoshape embed: error: argument --seed: …``), exit 2; the
    full usage stays one ``--help`` away."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from geoshape import __version__

    parser = _Parser(
        prog="geoshape",
        description="Correspondence and retrieval of articulated 2D contours and 3D meshes.",
    )
    parser.add_argument("--version", action="version", version=f"geoshape {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    from geoshape.cli._common import import_if_present

    for name in COMMAND_MODULES:
        module = import_if_present(f"geoshape.cli.{name}")
        if module is not None:
            module.register(subparsers)
    from geoshape.cli._common import state_limits

    state_limits(parser)
    return parser


def main(argv: list[str] | None = None, *, isolate: bool | None = None) -> int:
    """Run one command line; return its exit status.

    With ``isolate`` (default: only when ``argv`` is None, i.e. the real command line) the
    command runs in a forked child so that a crash in native code is reported in one line
    (:mod:`geoshape.cli.isolation`).
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # --help, --version, or a usage error already printed
        return stop.code if isinstance(stop.code, int) else 2
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "handler", None):
        parser.print_help()
        return 2
    import contextlib

    from geoshape.errors import GeoshapeError
    from geoshape.io.atomic import staged_outputs
    from geoshape.io.outputs import check_declared_outputs

    try:
        check_declared_outputs(args)  # before any work: a bad output path costs nothing
    except GeoshapeError as exc:
        print(f"geoshape {args.command}: error: {exc}", file=sys.stderr)
        return 2

    def work() -> int:
        try:
            all_or_nothing = getattr(args, "outputs_all_or_nothing", False)
            with staged_outputs() if all_or_nothing else contextlib.nullcontext():
                status = args.handler(args)
        except GeoshapeError as exc:
            print(f"geoshape {args.command}: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"geoshape {args.command}: interrupted", file=sys.stderr)
            return 130
        except BrokenPipeError:
            return 0
        except OSError as exc:  # a path the system refuses (too long, no permission, ...)
            where = f"{exc.filename}: " if exc.filename else ""
            print(f"geoshape {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
            return 2
        return int(status or 0)

    from geoshape.cli.isolation import can_isolate, run_isolated

    if isolate is None:
        isolate = argv is None  # the real command line; in-process callers (tests) see exceptions
    if not (isolate and can_isolate()):
        return work()
    outputs = [Path(getattr(args, dest)) for dest in (getattr(args, "outputs", None) or {})
               if getattr(args, dest, None)]
    given = sys.argv[1:] if argv is None else argv
    inputs = [a for a in given if not a.startswith("-") and _is_path(a) and Path(a) not in outputs]
    return run_isolated(work, command=args.command, inputs=inputs, outputs=outputs)


def _is_path(arg: str) -> bool:
    """Whether a command-line argument names an existing file or folder (a list of names
    longer than the system allows, or one with a NUL byte, is not one)."""
    try:
        return Path(arg).exists()
    except (OSError, ValueError):
        return False


if __name__ == "__main__":
    sys.exit(main())
