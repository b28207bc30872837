"""radar2shape: 3D shape reconstruction from high-frequency radar (Sortur et al., 2025).

Subpackages: ``radar`` (simulators), ``geometry`` (meshes, sampling, families),
``nn`` (building blocks), ``models`` (Lightning modules), ``metrics`` (shared metrics).

OpenMP threads that finish a parallel region sleep instead of spinning (``OMP_WAIT_POLICY=PASSIVE``,
unless the environment sets it): on a machine where anything else runs (a DataLoader worker
beside 2 training threads on 2 cores already does), spinning threads take the cores the others
need; bench/train_throughput.py measured 2x more Stage-1 shapes/s on a loaded 2-core machine
(docs/throughput.md). It takes effect only if torch is imported after this package.
"""

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

__version__ = "0.1.0"
