"""``geoshape bench kimia99``: 2D retrieval on Kimia-99 (top-1..10 counts, of 990)."""

from __future__ import annotations

from geoshape.bench.retrieval2d import add_common_arguments, run_benchmark

HELP = "2D retrieval on Kimia-99: top-1..10 counts for every method, all-pairs wall time"

INTRO = (
    "Kimia-99 (9 classes x 11), the processed 128x128 re-oriented copy of `../shared/data`. "
    "For each query, the k-th column counts the queries whose k-th nearest other shape is of "
    "the same class (max 99 each, 990 in all). Published on the original images: shape "
    "context 756, inner-distance shape context + DP ~958, shape tree ~969."
)


def add_arguments(parser) -> None:
    add_common_arguments(parser)


def run(args) -> int:
    return run_benchmark("kimia99", args, intro=INTRO, primary="top-10 total")
