"""Skies: analytic daylight, lat-long HDR files, the sun."""
