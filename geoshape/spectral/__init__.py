"""Affinities, spectral embeddings (dense, partial, Nyström), Laplace–Beltrami bases, the embedded mesh."""
