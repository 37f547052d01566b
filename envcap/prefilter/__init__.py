"""Cosine-lobe mip chains: the exact reference and the fast GPU filter."""
