"""Train and score the candidate verifier of a RadarDiffusion model on shapes it never saw.

    python scripts/train_verifier.py --ckpt src/radar2shape/weights/radar2shape_parts_medium.ckpt \
        --data data/parts_unseen --fit-shapes 300 --eval-shapes 100 --candidates 8 \
        --cache runs/verifier/parts_unseen_full.pt \
        --out src/radar2shape/weights/radar2shape_parts_medium.verifier.pt \
        --report reports/shipped-model/verifier_parts_unseen.md

For each shape of the data's train split (records the model was not trained on when the data is
a fresh seed): K candidate latents from the model (DDIM, sampling seed 0, as `reconstruct`), their
verifier features (``radar2shape.models.verifier``) and each candidate's IoU on the record's
occupancy points (SDF sign of the decoded latent). The first ``--fit-shapes`` train the
verifier; the last ``--eval-shapes`` (disjoint) score it: each selection rule's candidate is meshed
and scored as the evaluator scores (marching cubes at the model's resolution, IoU by containment),
paired by shape: the first sample, the K-sample mean SDF (what `reconstruct --samples K` returns),
the most-agreed candidate (consensus, no learning), the verifier's choice, the mean SDF of its 2 and
3 best-scored candidates, the oracle best of K.
Collection is cached per shape in ``--cache`` and resumes.

More folders after the first in ``--data`` (other seeds of the family) add fit shapes: the fit takes
the first folder's records first, then each further folder's ``--split`` records in turn, while the
scored shapes stay the first folder's; so a verifier fitted on more shapes is scored on the same ones.

With ``--verifier FILE --fit-shapes 0`` a trained verifier is only scored, e.g. on another family's
test split (``--split test``) to see whether its choice carries over.

With ``--eval-split S`` the verifier is fitted on the first ``--fit-shapes`` records of ``--split``
and scored on the first ``--eval-shapes`` of ``S`` (for a model trained on a dataset's train split:
fit on what is left to it, score on the test split the evaluator uses). ``--turns T`` adds, per
fit record, T - 1 copies turned about the aspect axis by a random whole number of roll steps and
mirrored half the time (exact: ``data_modules.augment``), so the verifier sees each object in
headings the stored radar does not show. ``--observability partial`` collects the samples from
masked radar (the fit split's records under random windows, the scored split's under the
evaluator's mask; ``--mask-rule``), in a cache of its own.
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
    parser.add_argument("--ckpt", type=Path, required=True, help="a RadarDiffusion checkpoint")
    parser.add_argument("--data", type=Path, nargs="+", required=True, help="records the model did not train on; "
                        "further folders' --split records add fit shapes after the first folder's (scored shapes are "
                        "the first folder's)")
    parser.add_argument("--split", default="train", help="the data split whose records are used (default train)")
    parser.add_argument("--eval-split", help="score on this split's first --eval-shapes records instead of the "
                        "last records of --split")
    parser.add_argument("--turns", type=int, default=1, help="views per fit record: the stored heading and "
                        "T - 1 exact whole-step turns (default 1)")
    parser.add_argument("--observability", choices=["full", "partial"], default="full",
                        help="radar as the DataModule serves it: partial masks the fit split's records with random "
                        "windows and the scored split's as the evaluator does (default full; use its own --cache)")
    parser.add_argument("--mask-rule", choices=["cells", "per_axis"], default="cells",
                        help="the partial mask (data_modules.ShapeDataModule; default cells, the protocol's)")
    parser.add_argument("--verifier", type=Path, help="score this trained verifier instead of fitting one")
    parser.add_argument("--fit-shapes", type=int, default=300)
    parser.add_argument("--eval-shapes", type=int, default=100)
    parser.add_argument("--candidates", type=int, default=8)
    parser.add_argument("--cache", type=Path, required=True, help="collected features (resumes)")
    parser.add_argument("--out", type=Path, help="write the verifier file here")
    parser.add_argument("--report", type=Path, required=True)
    return parser.parse_args(argv)


Key = tuple  # (data folder, split, record index, view): view 0 the stored heading, view v > 0 a seeded exact turn


def fit_keys_of(available: list[tuple[str, int]], split: str, fit_shapes: int, turns: int) -> list[Key]:
    """The fit shapes: the first records of each ``(folder, records free to fit)`` in turn, until ``fit_shapes``."""
    keys, left = [], fit_shapes
    for source, count in available:
        take = min(left, count)
        keys += [(source, split, i, view) for i in range(take) for view in range(turns)]
        left -= take
    if left:
        folders = ", ".join(f"{source} ({count})" for source, count in available)
        raise SystemExit(f"error: --fit-shapes {fit_shapes}: only {fit_shapes - left} {split} records free to fit in {folders}")
    return keys


def upgrade_keys(store: dict, source: str) -> dict:
    """A cache written before keys named their data folder: its (split, index, view) keys belong to ``source``."""
    return {(key if len(key) == 4 else (source, *key)): value for key, value in store.items()}


def view_of(dm, split: str, index: int, view: int) -> dict:
    """The record's evaluation item in view ``view``: as stored, or turned by a seeded random whole
    number of roll steps and maybe mirrored (radar, mask and point sets together)."""
    import torch

    from data_modules.augment import turn_and_mirror

    item = dm.dataset(split)[(0, index)]
    if view == 0:
        return item
    roll = dm.radar_spec.grid.roll_rad
    draw = np.random.default_rng([index, view])
    shift, mirror = int(draw.integers(len(roll))), bool(draw.integers(2))
    arrays = {key: item[key].numpy() for key in ("radar", "radar_mask", "occ_points", "eval_points")}
    turned = turn_and_mirror(arrays, shift, mirror, roll_rad=roll)
    return {**item, **{key: torch.from_numpy(np.ascontiguousarray(value)) for key, value in turned.items()}}


def collect(model, dms: dict, keys: list[Key], k, cache: Path, keep_latents: set[Key]) -> dict:
    """Per key: features [K, F], candidate IoUs [K] (and latents for ``keep_latents``), cached; ``dms`` maps
    each data folder to its DataModule, the first being the folder of caches whose keys name none."""
    import torch

    from radar2shape.atomic import atomic_path
    from radar2shape.models.checkpoint_model import renormalise
    from radar2shape.models.verifier import candidate_features, probe_points
    from tqdm import tqdm

    store = upgrade_keys(torch.load(cache, weights_only=False), next(iter(dms))) if cache.exists() else {}
    probe = probe_points(float(model.stage1.hparams.bound))
    todo = [key for key in keys if key not in store or (key in keep_latents and "latents" not in store[key])]
    for count, key in enumerate(tqdm(todo, desc="candidates", unit="shape")):
        source, *record = key  # record: (split, index, view)
        dm = dms[source]
        item = view_of(dm, *record)
        batch = {"radar": renormalise(item["radar"][None], item["radar_mask"][None], dm.radar_spec, model.radar_spec),
                 "radar_mask": item["radar_mask"][None]}
        latents = model.sample_latents(batch, num_samples=k, sample_seed=0)[0]
        tokens = model.encode_radar(batch["radar"], batch["radar_mask"])
        inside = model.sdf_function(latents)(item["occ_points"]) < 0
        truth = item["occ_inside"].bool()
        iou = ((inside & truth).sum(1) / (inside | truth).sum(1).clamp_min(1)).float()
        store[key] = {"features": candidate_features(model, tokens, latents, probe), "iou": iou}
        if key in keep_latents:
            store[key]["latents"] = latents
        if count % 20 == 19 or count == len(todo) - 1:
            with atomic_path(cache) as tmp:
                torch.save(store, tmp)
    return store


TOP = (2, 3)  # (holds models.verifier.KEEP) besides the single pick: the mean SDF of the verifier's best 2 and best 3
SIZES = ((64, 400), (64, 1000), (128, 1000))  # (hidden width, full-batch epochs) tried
FOLDS = 4


def cross_validated_gain(features, iou, hidden: int, epochs: int) -> float:
    """Mean IoU gain of the fitted verifier's pick over the first sample on held-out folds of the fit shapes."""
    import torch

    from radar2shape.models.verifier import fit_verifier

    fold = torch.arange(len(features)) % FOLDS
    gains = []
    for k in range(FOLDS):
        verifier = fit_verifier(features[fold != k], iou[fold != k], hidden=hidden, epochs=epochs)
        with torch.no_grad():
            pick = verifier(features[fold == k]).argmax(1)
        held = iou[fold == k]
        gains.append(float((held.gather(1, pick[:, None]).squeeze(1) - held[:, 0]).mean()))
    return sum(gains) / FOLDS


def mesh_iou(model, latents, item) -> float:
    """IoU of the mesh of the mean SDF of ``latents [K, L, Z]`` as the evaluator scores it."""
    from radar2shape.metrics.scoring import score_reconstruction
    from radar2shape.reconstruction import Reconstruction

    mesh, _ = model.mean_mesh(latents)
    return score_reconstruction(Reconstruction(mesh=mesh), item["eval_points"].numpy(), item["occ_points"].numpy(),
                                item["occ_inside"].numpy())["iou"]


def main(argv=None) -> int:
    args = parse_args(argv)
    import torch
    from scipy.stats import spearmanr

    from data_modules.datamodules import ShapeDataModule
    from radar2shape.atomic import write_text_atomic
    from radar2shape.geometry.families.folder import sha256_of
    from radar2shape.models.verifier import (
        KEEP, feature_names, fit_verifier, kept_candidates, load_verifier, save_verifier,
    )
    from radar2shape.pretrained import load_model

    torch.set_num_threads(2)
    start = time.perf_counter()
    model = load_model(args.ckpt)
    split, eval_split = args.split, args.eval_split or args.split
    sampled = {"surface": 0, "sdf": 0, "eval": 30000, "occ": 100000}
    dms = {str(data): ShapeDataModule(root=str(data), observability=args.observability, mask_rule=args.mask_rule,
                                      points={split: sampled, eval_split: sampled}) for data in args.data}
    source, dm = next(iter(dms.items()))  # the scored shapes' folder
    n, n_eval = len(dm.records(split)), len(dm.records(eval_split))
    if args.turns < 1:
        raise SystemExit(f"error: --turns: expected a positive integer, got {args.turns}")
    if args.eval_shapes > (n if eval_split == split else n_eval):
        raise SystemExit(f"error: {source}: {n_eval} {eval_split} records, fewer than --eval-shapes {args.eval_shapes}")
    if (args.verifier is None) == (args.fit_shapes == 0):
        raise SystemExit("error: fit a verifier (--fit-shapes N > 0) or score one (--verifier FILE --fit-shapes 0)")
    first_eval = n - args.eval_shapes if eval_split == split else 0
    available = [(source, first_eval if eval_split == split else n)]
    available += [(data, len(other.records(split))) for data, other in list(dms.items())[1:]]
    fit_keys = fit_keys_of(available, split, args.fit_shapes, args.turns)
    eval_keys = [(source, eval_split, i, 0) for i in range(first_eval, first_eval + args.eval_shapes)]
    args.cache.parent.mkdir(parents=True, exist_ok=True)
    store = collect(model, dms, fit_keys + eval_keys, args.candidates, args.cache, set(eval_keys))

    if args.verifier is not None:
        verifier = load_verifier(args.verifier, model.n_levels)
        trained = f"Verifier `{args.verifier}` (not refitted), scored on {args.eval_shapes} {eval_split} records"
        cv_lines = []
    else:
        features = torch.stack([store[key]["features"] for key in fit_keys])
        iou = torch.stack([store[key]["iou"] for key in fit_keys])
        cv = {size: cross_validated_gain(features, iou, *size) for size in SIZES}
        hidden, epochs = max(cv, key=cv.get)
        verifier = fit_verifier(features, iou, hidden=hidden, epochs=epochs)
        cv_lines = ["", f"Size chosen by {FOLDS}-fold cross-validation on the fit shapes (mean gain of the pick over the first "
                    "sample, decoded-SDF IoU): " + ", ".join(f"{h} wide x {e} epochs {g:+.4f}" for (h, e), g in cv.items())
                    + f"; kept {hidden} x {epochs}."]
        views = f", each in {args.turns} headings (stored + exact whole-step turns)" if args.turns > 1 else ""
        scored_on = (f"{args.eval_shapes} others (last records)" if eval_split == split
                     else f"the first {args.eval_shapes} {eval_split} records")
        per_folder = {data: sum(key[0] == data and key[3] == 0 for key in fit_keys) for data in dms}
        more = "".join(f"; {count} of them from `{data}`" for data, count in list(per_folder.items())[1:] if count)
        trained = (f"Verifier trained on {args.fit_shapes} shapes ({split} split, first records{views}{more}), "
                   f"scored on {scored_on}")
    names = feature_names(model.n_levels)
    consensus_column = names.index("consensus")

    dataset = dm.dataset(eval_split)
    rows = []
    for key in eval_keys:
        i = key[2]
        entry, item = store[key], dataset[(0, i)]
        latents, cand_iou = entry["latents"], entry["iou"]
        with torch.no_grad():
            predicted = verifier(entry["features"])
        picks = {"first": 0, "consensus": int(entry["features"][:, consensus_column].argmax()),
                 "verifier": int(predicted.argmax()), "oracle": int(cand_iou.argmax())}
        scored = {rule: mesh_iou(model, latents[j:j + 1], item) for rule, j in picks.items()}
        scored["mean_of_k"] = mesh_iou(model, latents, item)
        for m in TOP:  # the mean SDF of the verifier's m best-scored candidates
            scored[f"verifier_top{m}"] = mesh_iou(model, latents[kept_candidates(predicted, m)], item)
        consensus = entry["features"][:, consensus_column]  # the same averaging without learning
        scored[f"consensus_top{KEEP}"] = mesh_iou(model, latents[kept_candidates(consensus, KEEP)], item)
        rows.append({"record": dm.records(eval_split).record_ids[i],
                     "class": dm.class_names[dm.manifest["labels"][eval_split][i]],
                     **{f"iou_{rule}": value for rule, value in scored.items()},
                     "verifier_pick": picks["verifier"], "predicted_iou": float(predicted[picks["verifier"]]),
                     f"predicted_iou_top{KEEP}": float(predicted[kept_candidates(predicted, KEEP)].mean()),
                     "mean_consensus": float(entry["features"][:, consensus_column].mean())})

    def column(name):
        return np.array([row[name] for row in rows], dtype=float)

    eval_features = torch.stack([store[key]["features"] for key in eval_keys])
    eval_iou = torch.stack([store[key]["iou"] for key in eval_keys])
    first_sdf, oracle_sdf = float(eval_iou[:, 0].mean()), float(eval_iou.max(1).values.mean())

    def picked(index):
        return float(eval_iou.gather(1, index[:, None]).mean())

    single_feature_rows = [f"| {name} | {picked(eval_features[..., n].argmax(1)):.3f} | "
                           f"{picked(eval_features[..., n].argmin(1)):.3f} |"
                           for n, name in enumerate(names) if not name.startswith(("mean_", "log_mean", "log_denoise_0"))]

    first = column("iou_first")
    rules = ["first", "mean_of_k", "consensus", f"consensus_top{KEEP}", "verifier", *(f"verifier_top{m}" for m in TOP),
             "oracle"]
    lines = [f"# Choosing among K = {args.candidates} Stage-2 samples: {args.ckpt}", "",
             f"{trained} of `{source}`, {args.observability} observability; every IoU below meshed and scored as the "
             "evaluator does, paired by shape (gain: mean and standard error of the per-shape difference).", "",
             "| returned shape | IoU | gain over first sample | gain over K-sample mean |", "|---|---|---|---|"]
    mean_k = column("iou_mean_of_k")
    for rule in rules:
        values = column(f"iou_{rule}")
        def gain(base):
            d = values - base
            return f"{d.mean():+.3f} ± {d.std(ddof=1) / np.sqrt(len(d)):.3f}"
        lines.append(f"| {rule.replace('_', ' ')} | {values.mean():.3f} | {gain(first)} | {gain(mean_k)} |")
    chosen = column("iou_verifier")
    rho_pred, p_pred = spearmanr(column("predicted_iou"), chosen)
    rho_cons, p_cons = spearmanr(column("mean_consensus"), chosen)
    rho_kept, p_kept = spearmanr(column(f"predicted_iou_top{KEEP}"), column(f"iou_verifier_top{KEEP}"))
    gap = column("iou_oracle").mean() - first.mean()
    learned = column(f"iou_verifier_top{KEEP}") - column(f"iou_consensus_top{KEEP}")
    lines += ["", f"- share of the first-to-oracle gap the verifier closes: "
              f"{(chosen.mean() - first.mean()) / gap:.0%}" if gap > 0 else "- no gap between first sample and oracle",
              f"- what the learning adds: the verifier's best {KEEP} against the {KEEP} most agreed-with candidates "
              f"(both averaged), paired: {learned.mean():+.3f} ± {learned.std(ddof=1) / np.sqrt(len(learned)):.3f}",
              f"- confidence: Spearman(predicted IoU, IoU of the returned shape) = {rho_pred:+.3f} (p = {p_pred:.2g}); "
              f"Spearman(mean consensus of the K samples, IoU) = {rho_cons:+.3f} (p = {p_cons:.2g}); what "
              f"`reconstruct --candidates` returns by default (the mean of the best {KEEP}): Spearman(their mean "
              f"predicted IoU, its IoU) = {rho_kept:+.3f} (p = {p_kept:.2g})",
              f"- features ({len(names)}): {', '.join(names)}",
              *cv_lines,
              "", "Picking by one feature alone (its largest or smallest value among the K), scored by the decoded SDF's "
              f"sign on the occupancy points (no meshing; first sample {first_sdf:.3f}, oracle {oracle_sdf:.3f} the same way):",
              "", "| feature | largest | smallest |", "|---|---|---|",
              *single_feature_rows,
              "", f"`scripts/train_verifier.py`, {time.perf_counter() - start:.0f} s (collection cached in `{args.cache}`). "
              "Per evaluation shape:", "", "```csv"]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in row.items()} for row in rows)
    lines += [buffer.getvalue().rstrip(), "```", ""]
    write_text_atomic(args.report, "\n".join(lines))
    print("\n".join(lines[:12 + len(rules)]))
    if args.out and args.verifier is None:
        save_verifier(verifier, args.out, model.n_levels,
                      {"checkpoint": args.ckpt.name, "checkpoint_sha256": sha256_of(args.ckpt),  # the exact model whose samples trained it
                       "data": [str(data) for data in args.data], "split": split, "observability": args.observability,
                       "fit_shapes": args.fit_shapes, "turns": args.turns,
                       "candidates": args.candidates, "report": str(args.report)})
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
