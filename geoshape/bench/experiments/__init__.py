"""The thesis' chapter-4 experiments (issue 6), each runnable as ``geoshape experiment NAME``.

Every experiment is one module exposing

- ``HELP``: a one-line description;
- ``add_arguments(parser)``: its options, whose defaults are the keyword defaults of
- ``run_experiment(out_dir, **settings) -> list[dict]``: does the work, writes
  ``DIR/<name>.png``, ``DIR/<name>.csv`` and ``DIR/<name>.json`` atomically, updates its
  section of ``docs/RESULTS.md`` unless ``results=False``, and returns the table (one
  dict per row);
- ``settings(args) -> dict``: the keyword arguments of ``run_experiment`` specific to
  the experiment, from the parsed command line (``out``, ``seed``, ``data`` and
  ``no_results`` are common to all);
- ``SUMMARY``: the columns ``geoshape experiment`` prints.

Experiments run on ``tosca_r5k`` meshes when the data folder is present and on generated
meshes (:mod:`geoshape_datasets_gen`) always; without the data they say so in the table notes and
use the generated meshes only. Modules keep their top-level imports light.
"""

from __future__ import annotations

#: (name, module) pairs, in the order ``geoshape experiment --help`` lists them.
EXPERIMENTS: list[tuple[str, str]] = [
    ("scaling", "geoshape.bench.experiments.scaling"),
    ("gaussian-width", "geoshape.bench.experiments.gaussian_width"),
    ("switching", "geoshape.bench.experiments.switching"),
    ("reordering", "geoshape.bench.experiments.reordering"),
    ("stretching", "geoshape.bench.experiments.stretching"),
]
