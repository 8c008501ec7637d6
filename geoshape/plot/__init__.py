"""Headless pictures (Matplotlib Agg) and colour maps for every result: contours, meshes, maps, retrieval."""
