"""radar2shape: 3D shape reconstruction from high-frequency radar (Sortur et al., 2025).

Subpackages: ``radar`` (simulators), ``geometry`` (meshes, sampling, families),
``nn`` (building blocks), ``models`` (Lightning modules), ``metrics`` (shared metrics).

OpenMP threads that finish a parallel region spin ``GOMP_SPINCOUNT=10000`` times (some
microseconds) before they sleep, unless the environment sets ``GOMP_SPINCOUNT`` or
``OMP_WAIT_POLICY``. libgomp's default (300,000) keeps spinning threads on cores that other work
needs; sleeping at once (``OMP_WAIT_POLICY=PASSIVE``) pays a wake-up at every region. Measured on
the table1-medium-fast Stage-2 fit, 2 cores (bench/omp_wait.py, docs/throughput.md): quiet, 0.091
s a step against 0.138 sleeping at once; beside two busy processes, 0.274 against 0.248. It takes
effect only if torch is imported after this package.
"""

import os

if "OMP_WAIT_POLICY" not in os.environ:
    os.environ.setdefault("GOMP_SPINCOUNT", "10000")

__version__ = "0.1.0"
