"""Generators of benchmarks whose ground truth is known.

Decimation ladders, outlier spikes, stretching, articulated 3-D figures and 2-D silhouettes.
"""
