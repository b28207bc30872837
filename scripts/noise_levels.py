"""How much of a dataset's radar each noise level buries: the share of cells under the noise power.

For every training record, the power of each cell (``|S|^2``) is compared with the noise power of
each level (``radar.signal.noise_power``, the rule the DataModules add noise with); a cell whose
power is below the noise power is "buried" (its SNR < 0 dB). Writes ``noise_levels.md`` with, per
level and reference (``peak``: dB under each response's peak; ``absolute``: dBsm), the share of
buried cells over the split, and the median cell's distance under its response's peak.

    python scripts/noise_levels.py data/frusta_medium [--levels -60 -40 -20] [--reference peak] [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

from data_modules.manifest import read_manifest  # noqa: E402
from data_modules.records import read_record, record_path  # noqa: E402
from radar2shape.radar.signal import noise_power  # noqa: E402


def buried_shares(root: Path, split: str, levels: list[float], reference: str) -> tuple[dict[float, float], float, int]:
    """{level: share of buried cells}, the median cell's dB under its record's peak, records read."""
    manifest = read_manifest(root)
    buried = {level: 0 for level in levels}
    under_peak, total, records = [], 0, 0
    for record_id in manifest["splits"][split]:
        response = read_record(record_path(root, split, record_id), ["radar"])["radar"]
        power = np.abs(response) ** 2
        for level in levels:
            buried[level] += int((power < noise_power(response, level, reference)).sum())
        under_peak.append(10 * np.log10(np.maximum(power.max(), 1e-30) / np.maximum(power.ravel(), 1e-30)))
        total += power.size
        records += 1
    return {level: count / total for level, count in buried.items()}, float(np.median(np.concatenate(under_peak))), records


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path)
    parser.add_argument("--split", default="train")
    parser.add_argument("--levels", type=float, nargs="+", default=[-60.0, -40.0, -20.0])
    parser.add_argument("--reference", choices=("peak", "absolute"), default="peak")
    parser.add_argument("--out", type=Path, help="report folder (default reports/<dataset name>)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    shares, median_under_peak, records = buried_shares(args.root, args.split, args.levels, args.reference)
    unit = "dB re peak" if args.reference == "peak" else "dBsm"
    lines = [f"# Noise levels on {args.root.name} ({args.split} split, {records} records)", "",
             f"Made by `python scripts/noise_levels.py {args.root} --split {args.split} --reference {args.reference}`. "
             "A cell is buried when its power |S|^2 is below the noise power of the level (SNR < 0 dB).", "",
             f"Median cell: {median_under_peak:.1f} dB under its response's peak.", "",
             f"| noise level ({unit}) | cells buried |", "|---|---|"]
    lines += [f"| {level:g} | {100 * share:.1f} % |" for level, share in shares.items()]
    lines += ["", f"{time.perf_counter() - start:.1f} s."]
    out = args.out or ROOT / "reports" / args.root.name
    out.mkdir(parents=True, exist_ok=True)
    (out / "noise_levels.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
