"""Shape descriptors, pairwise distances, all-pairs matrices, the persistent index, metrics."""
