"""Geometry of one shape: mesh graphs, structural graph, geodesics, sampling, areas, curvature."""
