"""Radar tests: make the PO oracle (po_reference.py, beside this file) importable by name."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
