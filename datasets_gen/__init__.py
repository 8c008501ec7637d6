"""Generators of benchmarks whose ground truth is known (decimation, spikes, stretching, articulated shapes)."""
