"""The package's OpenMP spin setting (src/radar2shape/__init__.py): set before torch, never over the user's."""

import os
import subprocess
import sys

import pytest

PROBE = "import os, radar2shape; print(os.environ.get('GOMP_SPINCOUNT', 'unset'), os.environ.get('OMP_WAIT_POLICY', 'unset'))"


@pytest.mark.parametrize("given, expected", [
    ({}, "10000 unset"),                                  # nothing set: a short spin before sleeping
    ({"GOMP_SPINCOUNT": "500"}, "500 unset"),             # the user's spin count stays
    ({"OMP_WAIT_POLICY": "PASSIVE"}, "unset PASSIVE"),    # a wait policy alone decides the spin
])
def test_spin_count_is_a_default_only(given, expected):
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**env, **given}, capture_output=True, text=True, check=True)
    assert out.stdout.split() == expected.split()
