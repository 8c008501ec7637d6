"""``geoshape bench tari1000``: 2D retrieval on Tari-1000 (bull's-eye)."""

from __future__ import annotations

from geoshape.bench.retrieval2d import add_common_arguments, run_benchmark

HELP = "2D retrieval on Tari-1000: bull's-eye for every method, all-pairs wall time"

INTRO = (
    "Tari-1000 articulated silhouettes (50 classes x 20), the processed 128x128 copy of "
    "`../shared/data` (contains within-class duplicates, see its MANIFEST). Bull's-eye: share "
    "of the 20 class members among the 40 nearest shapes (query counted), averaged. "
    "Published: inner-distance shape context ~95 %."
)


def add_arguments(parser) -> None:
    add_common_arguments(parser)


def run(args) -> int:
    return run_benchmark("tari1000", args, intro=INTRO, primary="bull's-eye")
