"""Everything about two shapes: 2D descriptors and matchers, 3D spectral correspondence."""
