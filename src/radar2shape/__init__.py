"""radar2shape: 3D shape reconstruction from high-frequency radar (Sortur et al., 2025).

Subpackages: ``radar`` (simulators), ``geometry`` (meshes, sampling, families),
``nn`` (building blocks), ``models`` (Lightning modules), ``metrics`` (shared metrics).
"""

__version__ = "0.1.0"
