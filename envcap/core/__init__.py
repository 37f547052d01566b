"""Shared foundations: cube conventions and sampling, lat-long maps, the lobe ladder, the one
luminance (``color``), shared validation (``checks``), memory budgets, image reading, data files."""
