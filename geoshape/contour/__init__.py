"""2D closed contours once extracted: point descriptors, matchers, the method registry, 2D retrieval."""
