"""Offline interactive HTML viewers of correspondences, embeddings, 2D matchings and queries.

One self-contained file per view (three.js inlined, no network): see :mod:`geoshape.viewer.html`.
"""

from geoshape.viewer.html import (
    contour_matching_html,
    correspondence_html,
    embedding_html,
    query_html,
    write_html,
)

__all__ = ["contour_matching_html", "correspondence_html", "embedding_html", "query_html", "write_html"]
