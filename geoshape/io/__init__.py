"""Files in, arrays out: meshes, silhouettes, contours, datasets, atomic writers, validation."""
