"""Columns and column-group titles the layouts share.

Column groups say what was masked ("partial (70 % of cells masked)", "(70 % per axis)"), read
from each run's saved test config, else from hints in the run name (:func:`masking`).
"""

from __future__ import annotations

import re

from radar2shape.reporting.cells import ARCHIVED, Cell, cell_test_config
from radar2shape.reporting.tables import Column


CHAMFER = Column("chamfer_l2_x1e3", "CD x10^3 ↓", higher_is_better=False, digits=2)
IOU = Column("iou", "IoU ↑", higher_is_better=True)
FSCORE = Column("fscore_1pct", "F-score@1% ↑", higher_is_better=True)
IOU_R = Column("iou_r", "IoU-R ↑", higher_is_better=True)
IOU_S = Column("iou_s", "IoU-S ↑", higher_is_better=True)
MATCH_S = Column("match_s", "MATCH-S ↓", higher_is_better=False)
SHAPE_COLUMNS = (CHAMFER, IOU, FSCORE)


# Diagnostics (docs/metrics.md): own-radar minus other-radar score, paired over shapes (± standard
# error); the Stage-1 ceiling of latent models; how many shapes each mean pools.
DEPENDENCE_IOU = Column("radar_dependence_iou", "radar dependence Δ IoU ↑", higher_is_better=True, spread="se")
CEILING_IOU = Column("ceiling_iou", "Stage-1 ceiling IoU ↑", higher_is_better=True)
SHAPES_IOU = Column("iou", "shapes scored (IoU)", higher_is_better=True, total="num_shapes")
DEPENDENCE_IOU_S = Column("radar_dependence_iou_s", "radar dependence Δ IoU-S ↑", higher_is_better=True, spread="se")
SHAPES_IOU_S = Column("iou_s", "shapes scored (IoU-S)", higher_is_better=True, total="num_shapes")


MODEL_TITLES = {
    "radar2shape": "Radar2Shape",
    "radar2shape_paper": "Radar2Shape, as in the paper",
    "radar2shape_s1slow": "Radar2Shape, slow-decay Stage 1",
    "radar2shape_s1wide": "Radar2Shape, wide Stage 1",
    "radar2shape_circ": "Radar2Shape, circular roll padding",
    "radar2shape_k8": "Radar2Shape, mean of 8 samples",
    "radar2shape_long": "Radar2Shape, Stage 2 for 200 epochs",
    "radar2shape_ft": "Radar2Shape, partial: the full 200-epoch model fine-tuned on masked radar",
    "radar2shape_long_k8": "Radar2Shape, Stage 2 for 200 epochs, mean of 8 samples",
    "radar2shape_long_v3of8": "Radar2Shape, Stage 2 for 200 epochs, mean of its verifier's best 3 of 8 samples",
    "radar2shape_circ_steps12k": "Radar2Shape, circular roll padding, Stage 2 for 11,960 steps",
    "radar2shape_circ_steps12k_k8": "Radar2Shape, circular roll padding, Stage 2 for 11,960 steps, mean of 8 samples",
    "radar2shape_third": "Radar2Shape, 3x settings, both stages on schedules of about a third of the committed fits' time",
    "radar2shape_faster": "Radar2Shape, 3x settings, Stage 2 for 1,000 epochs on the shipped real Stage 1",
    "radar2shape_partsenc": "Radar2Shape, radar encoder started from the parts model's, Stage 2 for 600 epochs at batch 32",
    "radar2shape_enc4": "Radar2Shape, radar encoder drawn fresh, Stage 2 for 600 epochs at batch 32 (control)",
    "radar2shape_s1long": "Radar2Shape, Stage 1 for 200 epochs, Stage 2 for 4,160 steps",
    "radar2shape_s1long_steps12k": "Radar2Shape, Stage 1 for 200 epochs, Stage 2 for 11,960 steps",
    "radar2shape_heading": "Radar2Shape, shapes learned in their canonical heading, heading by PO search",
    "radar2shape_front": "Radar2Shape, aircraft and ships learned in their stored heading, heading by PO search",
    "radar2shape_front_s1seed1": "Radar2Shape, aircraft and ships learned in their stored heading, Stage 1 seed 1",
    "radar2shape_front_shippeds1": "Radar2Shape, aircraft and ships learned in their stored heading, on the shipped Stage 1",
    "radar2shape_front_oracle": "Radar2Shape, aircraft and ships learned in their stored heading, true heading given (oracle)",
    "radar2shape_heading_oracle": "Radar2Shape, shapes learned in their canonical heading, true heading given (oracle)",
    "diffusion_sdf": "Diffusion-SDF",
    "tmnet": "TMNet",
    "list": "LIST",
    "nearest": "Nearest neighbour",
    "mean_shape": "Mean shape",
    "shipped": "Radar2Shape, shipped parts-only model (not trained here)",
    "real_model": "Radar2Shape, shipped real-target model (not trained here)",
    "real_verifier3": "Radar2Shape, shipped real-target model, mean of its verifier's best 3 of 8 samples",
    "radar2shape_cfg1": "Radar2Shape, real model fine-tuned with condition dropout, no guidance",
    "radar2shape_cfg2": "Radar2Shape, real model fine-tuned with condition dropout, guidance 2",
    "radar2shape_cfg3": "Radar2Shape, real model fine-tuned with condition dropout, guidance 3",
    "real_verifier1": "Radar2Shape, shipped real-target model, its verifier's best of 8 samples",
    "radar2shape_lora": "Radar2Shape + LoRA (PO-SBR fine-tuned)",
}


GROUP_TITLES = {
    "full": "full",
    "val": "validation split, full",
    "partial": "partial",
    "full-sbr": "PO-SBR test, full",
    "partial-sbr": "PO-SBR test, partial",
}


# ---- what a run masked ------------------------------------------------------------------------
def masking(cell: Cell, group: str) -> str | None:
    """What the run's test mask hid, e.g. "70 % of cells masked", "70 % per axis"; None when full.

    From the saved test config (``observability``, ``mask_rule``: ``cells`` or ``per_axis``,
    ``test_keep``: the kept fraction); without one, from the run's group name (``cells`` / ``axis``
    and a percentage, e.g. ``partial70cells``); "mask not recorded" when neither says.
    """
    config = cell_test_config(cell)
    if config is not None and "observability" in config:
        if config["observability"] != "partial":
            return None
        masked = round(100 * (1 - float(config.get("test_keep", 0.3))))
        if "Profile" in config["class_path"]:  # one angular axis: both rules mask that share of aspects
            return f"{masked} % of aspects masked"
        rule = config.get("mask_rule", "per_axis")
        return f"{masked} % of cells masked" if rule == "cells" else f"{masked} % per axis"
    if "partial" not in group:
        return None
    percent = re.search(r"(\d+)", group)
    amount = f"{percent.group(1)} % " if percent else ""
    if "cell" in group:
        return f"{amount}of cells masked"
    if "axis" in group:
        return f"{amount}per axis"
    return "mask not recorded"


def group_title(titles: dict[str, str]):
    """A ``describe_group`` for a layout: the static title plus what the group's runs masked."""

    def describe(group: str, cells: list[Cell]) -> str:
        base = titles.get(group, group)
        found = {masking(cell, group) for cell in cells if cell.state in ("done", "tested", ARCHIVED)} - {None}  # runs not done say nothing
        if not found:
            return base
        return f"{base} ({found.pop()})" if len(found) == 1 else f"{base} (masks differ: {', '.join(sorted(found))})"

    return describe
