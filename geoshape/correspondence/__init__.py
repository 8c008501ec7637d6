"""Two 3D meshes: candidate alignments, functional-map refinement, the method registry, batches, map files."""
