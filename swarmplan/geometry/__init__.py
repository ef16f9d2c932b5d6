"""Geometry: analytic distances to obstacle shapes and terrain, and FCL collision checking."""
