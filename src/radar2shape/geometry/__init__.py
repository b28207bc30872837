"""Geometry: mesh loading and repair, normalisation, sampling, families, marching cubes."""
