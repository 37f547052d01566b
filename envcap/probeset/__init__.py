"""Probe sets: placement along streets, the planes, the bake, the typed manifest, the directory store."""
