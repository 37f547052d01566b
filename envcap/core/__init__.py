"""Shared foundations: cube conventions, lat-long maps, lobe ladder, colour, validation, atomic outputs, data files."""
