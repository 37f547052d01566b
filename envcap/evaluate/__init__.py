"""Parallax-error evaluation against fresh captures: sweep, truth, metrics, report."""
