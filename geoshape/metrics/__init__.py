"""Scores of results against ground truth: geodesic correspondence error and retrieval metrics."""
