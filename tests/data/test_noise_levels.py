"""scripts/noise_levels.py: the share of cells a noise level buries, on responses with known powers."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from data_modules.manifest import FORMAT
from data_modules.records import record_path, write_record

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("noise_levels", ROOT / "scripts" / "noise_levels.py")
noise_levels = importlib.util.module_from_spec(spec)
spec.loader.exec_module(noise_levels)


def test_buried_shares_match_the_powers(tmp_path):
    """Two responses of 4 cells with powers 1, 1e-1, 1e-3, 1e-5 (x 100 for the second, same shape
    relative to its peak): at -20 dB re peak the cells at -30 and -50 dB are buried (2 of 4), at
    -40 dB one (the -50 dB cell), at 0 dB all but the peak."""
    powers = np.array([1.0, 1e-1, 1e-3, 1e-5])
    ids = []
    for i, scale in enumerate((1.0, 100.0)):
        response = np.sqrt(powers * scale).astype(np.complex64).reshape(2, 1, 2)
        path = record_path(tmp_path, "train", f"{i:06d}")
        path.parent.mkdir(parents=True, exist_ok=True)
        write_record(path, {"radar": response})
        ids.append(f"{i:06d}")
    (tmp_path / "manifest.json").write_text(json.dumps({"format": FORMAT, "splits": {"train": ids}}))
    shares, median, records = noise_levels.buried_shares(tmp_path, "train", [-20.0, -40.0, 0.0], "peak")
    assert records == 2 and shares == pytest.approx({-20.0: 0.5, -40.0: 0.25, 0.0: 0.75})
    assert median == pytest.approx(20.0)  # cells at 0, 10, 30, 50 dB under the peak (both records)
    shares, _, _ = noise_levels.buried_shares(tmp_path, "train", [-25.0], "absolute")
    # first record: 1e-3 and 1e-5 < 10^-2.5; second (x100): 1e-3 < 10^-2.5 (1e-1 is not) -> 3 of 8
    assert shares == pytest.approx({-25.0: 3 / 8})
