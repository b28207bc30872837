"""Near-duplicate guard for a built dataset: the IoU of each held-out shape's nearest training shape.

A test score means little if the test shape has a near copy among the training shapes (a
retrieval baseline would then look like a perfect model). For every record of the held-out
splits this finds the training shape with the highest volumetric IoU and writes
``near_duplicates_<split>.csv`` (one row per held-out shape) and ``near_duplicates.md`` (min /
median / max, a histogram, the closest pairs, the timing).

How: each record's normalised mesh is labelled on one grid of ``resolution^3`` cell centres in the
unit cube by the project's containment routine (``geometry.query.contains``, the one the metrics
use); with the labels as 0/1 rows, all intersections come from one matrix product per block of
training shapes (exact in float32: counts stay below 2^24), the unions from the row sums. A grid
of 32^3 screens every pair cheaply, but thin shapes (panels, fins: a few cells thick) can look
identical on it: on parts_medium, pairs at IoU 1.0 on 32^3 measured 0.33 on 64^3. So the shapes
whose coarse nearest IoU reaches ``--refine-above`` are scored again on a ``--refine`` grid against
their ``--candidates`` best coarse matches, and that finer IoU is the one reported for them.

    python scripts/near_duplicates.py data/parts_medium [--splits test val] [--resolution 32] [--refine 64] [--out DIR]

Without a manifest (a build still running) the records on disk are used, and the report says so.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

from data_modules.manifest import read_manifest
from data_modules.records import read_record, record_path
from radar2shape.errors import UserInputError
from radar2shape.geometry.query import contains

BLOCK = 256  # training shapes per matrix product: bounds the float32 copy at BLOCK x resolution^3
HISTOGRAM = np.linspace(0.0, 1.0, 11)


def grid_points(resolution: int) -> np.ndarray:
    """Cell centres ``[resolution^3, 3]`` of a regular grid over the unit cube ``[-0.5, 0.5]^3``."""
    axis = -0.5 + (np.arange(resolution) + 0.5) / resolution
    return np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3).astype(np.float32)


def record_ids(root: Path, split: str) -> tuple[list[str], bool]:
    """The split's record ids (manifest order) and whether they came from a manifest."""
    try:
        return list(read_manifest(root)["splits"].get(split, [])), True
    except UserInputError:
        folder = root / "records" / split
        if not folder.is_dir():
            raise
        return sorted(p.stem for p in folder.glob("*.npz")), False


def occupancy(root: Path, split: str, ids: list[str], points: np.ndarray) -> np.ndarray:
    """Bool ``[len(ids), len(points)]``: which grid points each record's mesh contains."""
    out = np.zeros((len(ids), len(points)), dtype=bool)
    for row, record_id in enumerate(ids):
        path = record_path(root, split, record_id)
        try:
            data = read_record(path, ["vertices", "faces"])
        except (OSError, ValueError) as err:
            raise UserInputError(f"{path}: not a readable record ({type(err).__name__}: {err})") from err
        if "vertices" not in data or "faces" not in data:
            raise UserInputError(f"{path}: record has no mesh (expected keys 'vertices' and 'faces')")
        mesh = trimesh.Trimesh(data["vertices"], data["faces"], process=False)
        if len(mesh.faces):
            out[row] = contains(mesh, points)
    return out


def iou_matrix(a: np.ndarray, b: np.ndarray, block: int = BLOCK) -> np.ndarray:
    """IoU ``[len(a), len(b)]`` of every pair of bool occupancy rows (1 where both are empty)."""
    a32 = a.astype(np.float32)
    size_a = a.sum(1).astype(np.float64)
    out = np.empty((len(a), len(b)), dtype=np.float64)
    for start in range(0, len(b), block):
        part = b[start:start + block]
        inter = (a32 @ part.astype(np.float32).T).astype(np.float64)
        union = size_a[:, None] + part.sum(1)[None, :] - inter
        out[:, start:start + block] = np.where(union > 0, inter / np.maximum(union, 1), 1.0)
    return out


def summary(iou: np.ndarray) -> dict[str, float]:
    """Distribution of nearest-training IoUs: min, median, mean, max and the counts at >= 0.9 / 0.95 / 1."""
    return {"n": len(iou), "min": float(iou.min()), "median": float(np.median(iou)), "mean": float(iou.mean()),
            "max": float(iou.max()), "at_least_0.9": int((iou >= 0.9).sum()), "at_least_0.95": int((iou >= 0.95).sum()),
            "equal_1": int((iou >= 1.0).sum())}


def markdown(root: Path, resolution: int, results: dict, seconds: dict, from_manifest: bool, top: int = 10) -> str:
    lines = [f"# Near-duplicate check of `{root}`", "",
             f"For each held-out shape, the volumetric IoU of its nearest training shape on a {resolution}^3 grid of "
             "cell centres in the unit cube (containment by `geometry.query.contains`, as the metrics). "
             "IoU 1 on this grid: a probable copy; >= 0.9: inspect.", ""]
    if not from_manifest:
        lines += ["No manifest (the build has not finished): the records present on disk were used.", ""]
    lines += ["| split | shapes | training shapes | min | median | mean | max | >= 0.9 | >= 0.95 | = 1 |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for split, r in results.items():
        s = r["summary"]
        lines.append(f"| {split} | {s['n']} | {r['n_train']} | {s['min']:.3f} | {s['median']:.3f} | {s['mean']:.3f} | "
                     f"{s['max']:.3f} | {s['at_least_0.9']} | {s['at_least_0.95']} | {s['equal_1']} |")
    lines += ["", "Histogram of nearest-training IoU (shapes per bin):", "",
              "| bin | " + " | ".join(results) + " |", "|---" * (len(results) + 1) + "|"]
    counts = {split: np.histogram(r["iou"], HISTOGRAM)[0] for split, r in results.items()}
    for i in range(len(HISTOGRAM) - 1):
        lo, hi = HISTOGRAM[i], HISTOGRAM[i + 1]
        lines.append(f"| [{lo:.1f}, {hi:.1f}{']' if i == len(HISTOGRAM) - 2 else ')'} | "
                     + " | ".join(str(counts[s][i]) for s in results) + " |")
    for split, r in results.items():
        order = np.argsort(-r["iou"])[:top]
        lines += ["", f"Closest pairs ({split}):", "", f"| {split} record | nearest train record | IoU |", "|---|---|---|"]
        lines += [f"| {r['ids'][i]} | {r['train_ids'][r['nearest'][i]]} | {r['iou'][i]:.3f} |" for i in order]
    lines += ["", "Time: " + ", ".join(f"{k} {v:.1f} s" for k, v in seconds.items()) + ".", ""]
    return "\n".join(lines)


def refine(root: Path, split: str, ids: list[str], train_ids: list[str], matrix: np.ndarray, rows: np.ndarray,
           resolution: int, candidates: int) -> tuple[np.ndarray, np.ndarray]:
    """Nearest training index and IoU on a ``resolution^3`` grid for held-out ``rows``, among each row's
    ``candidates`` best coarse matches (occupancy computed once per shape involved)."""
    points = grid_points(resolution)
    best = np.argsort(-matrix[rows], axis=1)[:, :candidates]
    needed = sorted(set(best.ravel().tolist()))
    fine_train = dict(zip(needed, occupancy(root, "train", [train_ids[j] for j in needed], points)))
    fine_held = occupancy(root, split, [ids[i] for i in rows], points)
    nearest, iou = np.empty(len(rows), dtype=int), np.empty(len(rows))
    for k, (held, cand) in enumerate(zip(fine_held, best)):
        values = iou_matrix(held[None], np.stack([fine_train[j] for j in cand]))[0]
        nearest[k], iou[k] = cand[values.argmax()], values.max()
    return nearest, iou


def run(root: Path, splits: list[str], resolution: int, out: Path, refine_resolution: int = 64,
        refine_above: float = 0.8, candidates: int = 5) -> dict:
    """Compute, write the CSVs and the Markdown; returns ``{split: {...}}`` with the nearest IoUs."""
    if not root.is_dir():
        raise UserInputError(f"dataset folder {root} not found (build it with `radar2shape build-data`)")
    if resolution < 2:
        raise UserInputError(f"--resolution {resolution}: expected an integer >= 2 (e.g. 32)")
    if refine_resolution and refine_resolution < resolution:
        raise UserInputError(f"--refine {refine_resolution}: expected 0 (off) or a grid >= --resolution {resolution}")
    points = grid_points(resolution)
    seconds, started = {}, time.perf_counter()
    train_ids, from_manifest = record_ids(root, "train")
    if not train_ids:
        raise UserInputError(f"{root}: no training records to compare with")
    train = occupancy(root, "train", train_ids, points)
    seconds["occupancy of train"] = time.perf_counter() - started
    results = {}
    for split in splits:
        ids, _ = record_ids(root, split)
        if not ids:
            raise UserInputError(f"{root}: split {split!r} has no records")
        started = time.perf_counter()
        held = occupancy(root, split, ids, points)
        seconds[f"occupancy of {split}"] = time.perf_counter() - started
        started = time.perf_counter()
        matrix = iou_matrix(held, train)
        seconds[f"IoU matrix {split} x train ({len(ids)} x {len(train_ids)})"] = time.perf_counter() - started
        nearest = matrix.argmax(1)
        coarse = matrix[np.arange(len(ids)), nearest]
        iou, refined = coarse.copy(), np.flatnonzero(coarse >= refine_above) if refine_resolution else np.zeros(0, int)
        if len(refined):
            started = time.perf_counter()
            nearest[refined], iou[refined] = refine(root, split, ids, train_ids, matrix, refined, refine_resolution,
                                                    candidates)
            seconds[f"refinement of {len(refined)} {split} shapes at {refine_resolution}^3"] = time.perf_counter() - started
        results[split] = {"ids": ids, "train_ids": train_ids, "n_train": len(train_ids), "nearest": nearest,
                          "iou": iou, "coarse": coarse, "refined": set(refined.tolist()), "summary": summary(iou)}
    out.mkdir(parents=True, exist_ok=True)
    for split, r in results.items():
        with (out / f"near_duplicates_{split}.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["split", "index", "record_id", "nearest_train_index", "nearest_train_id", "iou",
                             "grid", f"iou_{resolution}"])
            for i, (record_id, j, value) in enumerate(zip(r["ids"], r["nearest"], r["iou"])):
                grid = refine_resolution if i in r["refined"] else resolution
                writer.writerow([split, i, record_id, int(j), train_ids[j], f"{value:.6f}", grid, f"{r['coarse'][i]:.6f}"])
    text = markdown(root, resolution, results, seconds, from_manifest)
    if refine_resolution:
        text = text.replace("\n\n| split |", f"\n\nShapes whose nearest IoU on {resolution}^3 reached {refine_above:g} were "
                            f"scored again on {refine_resolution}^3 against their {candidates} best {resolution}^3 "
                            f"matches; their IoU below is the {refine_resolution}^3 one (column `grid` of the CSV): "
                            + ", ".join(f"{len(r['refined'])} of {len(r['ids'])} {s}" for s, r in results.items())
                            + ".\n\n| split |", 1)
    (out / "near_duplicates.md").write_text(text)
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", type=Path, help="built dataset folder (radar2shape build-data --out)")
    parser.add_argument("--splits", nargs="+", default=["test"], help="held-out splits to check (default: test)")
    parser.add_argument("--resolution", type=int, default=32, help="occupancy grid per axis (default 32)")
    parser.add_argument("--refine", type=int, default=64,
                        help="finer grid for the shapes that look like copies on the coarse one (default 64; 0: off)")
    parser.add_argument("--refine-above", type=float, default=0.8, help="coarse IoU from which to refine (default 0.8)")
    parser.add_argument("--candidates", type=int, default=5, help="best coarse matches refined per shape (default 5)")
    parser.add_argument("--out", type=Path, help="output folder (default reports/near_duplicates/<dataset name>)")
    args = parser.parse_args(argv)
    out = args.out or Path("reports") / "near_duplicates" / args.root.name
    try:
        results = run(args.root, args.splits, args.resolution, out, args.refine, args.refine_above, args.candidates)
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for split, r in results.items():
        s = r["summary"]
        print(f"{split}: {s['n']} shapes, nearest-training IoU min {s['min']:.3f} median {s['median']:.3f} "
              f"max {s['max']:.3f}; {s['equal_1']} at 1.0, {s['at_least_0.9']} >= 0.9")
    print(f"wrote {out / 'near_duplicates.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
