"""Affinities, spectral embeddings (dense, partial, Nyström), eigenvalue scaling, EVD."""
