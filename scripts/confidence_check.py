"""Does the radar consistency that `reconstruct` prints say which reconstructions are poor?

    python scripts/confidence_check.py --ckpt MODEL.ckpt --data data/parts_unseen \
        [--observability full partial] [--limit 60] --out reports/.../confidence.md

For each test record: the model reconstructs it from the record's radar (masked as the DataModule
masks the test split), the reconstruction is scored against the record (IoU, as the evaluator), and
its radar consistency is computed (``radar2shape.metrics.consistency``: re-simulated with PO, residual
in power over the observed cells after one gain). The report gives the Spearman rank correlation of
consistency with IoU (negative = a lower residual goes with a better reconstruction), per
observability, and the per-shape values.

    python scripts/confidence_check.py --scores reports/GRID/scores/RUN.csv ... --out REPORT.md

reads the same from per-shape score files of runs whose evaluator had the ``ConsistencyScorer``
(columns ``iou`` and ``radar_consistency``) instead of running a model, and the verifier's predicted IoU
where the run logged one (column ``predicted_iou``: ``CheckpointModel`` with a verifier).
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from pathlib import Path

import numpy as np


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", type=Path, help="a RadarDiffusion checkpoint")
    parser.add_argument("--data", type=Path)
    parser.add_argument("--scores", type=Path, nargs="+", help="per-shape score files instead of --ckpt/--data")
    parser.add_argument("--observability", nargs="+", default=["full"], choices=["full", "partial"])
    parser.add_argument("--limit", type=int, default=0, help="first N test records (0: all)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if (args.scores is None) == (args.ckpt is None or args.data is None):
        parser.error("give --ckpt and --data, or --scores")
    return args


CONFIDENCES = {"radar_consistency": "consistency", "predicted_iou": "predicted IoU"}  # score column: its name


def from_scores(paths: list[Path], out: Path) -> int:
    """The Spearman correlation with IoU of each logged confidence (radar consistency, a verifier's
    predicted IoU), per score file."""
    import csv

    from scipy.stats import spearmanr

    from radar2shape.atomic import write_text_atomic

    lines = ["# Confidence against IoU, from per-shape test scores", ""]
    for path in paths:
        if not path.is_file():
            raise SystemExit(f"error: {path}: not found (expected a per-shape score file, scores/<run>.csv)")
        with path.open() as handle:
            rows = list(csv.DictReader(handle))
        present = [column for column in CONFIDENCES if rows and column in rows[0]]
        if not present:
            raise SystemExit(f"error: {path}: no radar_consistency or predicted_iou column (test the run with the "
                             "ConsistencyScorer, or a model with a verifier)")
        for column in present:
            pairs = [(float(r[column]), float(r["iou"])) for r in rows]
            pairs = [p for p in pairs if all(np.isfinite(p))]
            rho, p = spearmanr(*zip(*pairs))
            name = CONFIDENCES[column]
            lines.append(f"- `{path}`: Spearman({name}, IoU) = {rho:+.3f} (p = {p:.2g}) over {len(pairs)} shapes; "
                         f"mean IoU {np.mean([b for _, b in pairs]):.3f}, mean {name} {np.mean([a for a, _ in pairs]):.3f}")
            print(lines[-1])
    write_text_atomic(out, "\n".join(lines + ["", "`scripts/confidence_check.py --scores`", ""]))
    print(f"wrote {out}")
    return 0


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.scores:
        return from_scores(args.scores, args.out)
    import torch
    from scipy.stats import spearmanr

    from data_modules.datamodules import ShapeDataModule
    from radar2shape.atomic import write_text_atomic
    from radar2shape.metrics.consistency import radar_consistency
    from radar2shape.metrics.scoring import score_reconstruction
    from radar2shape.models.checkpoint_model import renormalise
    from radar2shape.pretrained import load_model

    torch.set_num_threads(2)
    model = load_model(args.ckpt)
    start = time.perf_counter()
    lines = [f"# Radar consistency against IoU: {args.ckpt}", ""]
    rows = []
    for observability in args.observability:
        dm = ShapeDataModule(root=str(args.data), observability=observability, mask_rule="cells", test_keep=0.3,
                             points={"test": {"surface": 2048, "sdf": 0, "eval": 30000, "occ": 100000}})
        dataset, records = dm.dataset("test"), dm.records("test")
        count = len(records) if not args.limit else min(args.limit, len(records))
        iou, residual = [], []
        for i in range(count):
            item = dataset[(0, i)]
            record = records[i]
            mask = item["radar_mask"].numpy()
            batch = {"radar": renormalise(item["radar"][None], item["radar_mask"][None], dm.radar_spec, model.radar_spec),
                     "radar_mask": item["radar_mask"][None], "index": torch.tensor([i]),
                     "surface_points": item["surface_points"][None]}
            recon = model.reconstruct(batch)[0]
            score = score_reconstruction(recon, item["eval_points"].numpy(), item["occ_points"].numpy(),
                                         item["occ_inside"].numpy())
            db = model.radar_spec.to_db(record["radar"])
            r = radar_consistency(recon.mesh, db, mask, model.radar_spec)
            iou.append(score["iou"])
            residual.append(r)
            rows.append((observability, records.record_ids[i], dm.class_names[dm.manifest["labels"]["test"][i]],
                         score["iou"], r))
        rho, p = spearmanr(residual, iou, nan_policy="omit")
        lines.append(f"- {observability} observability, {count} test shapes of `{args.data}`: Spearman(consistency, IoU) "
                     f"= {rho:+.3f} (p = {p:.2g}); mean IoU {np.nanmean(iou):.3f}, mean consistency {np.nanmean(residual):.3f}")
        print(lines[-1])
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    writer.writerow(["observability", "record", "class", "iou", "radar_consistency"])
    writer.writerows(rows)
    lines += ["", f"`scripts/confidence_check.py`, {time.perf_counter() - start:.0f} s. Per shape:", "", "```csv",
              buffer.getvalue().rstrip(), "```", ""]
    write_text_atomic(args.out, "\n".join(lines))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
