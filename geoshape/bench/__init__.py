"""Benchmarks: seeded runs that measure accuracy and time and write docs/RESULTS.md."""
