"""Functional-map refinement on Laplace–Beltrami bases: ZoomOut and descriptor functional maps."""
