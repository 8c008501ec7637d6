"""3D retrieval: global mesh descriptors and their registry, all-pairs matrices, the persistent index."""
