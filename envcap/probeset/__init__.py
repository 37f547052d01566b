"""Probe sets: placement along streets, the bake, the manifest, reading and writing."""
