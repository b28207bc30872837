"""The roll-symmetric sections of docs/results.md: Table 2 at medium scale, its best diffusion
configuration per setting against InvRT, and the zero-shot monocone, each read from its reports' tables."""

from __future__ import annotations

from pathlib import Path

from radar2shape.reporting.pages import OBSERVABILITY, link
from radar2shape.reporting.tables import columns, markdown_table, read_table


def table2_medium(root: Path) -> str:
    rows = read_table(root / "reports/rollsym-medium/table.csv")
    noises = sorted({t.split("/", 1)[0] for t, _ in rows}, key=["low", "medium", "high"].index)
    lines = [f"## Table 2 at medium scale ([report]({link(Path('reports/rollsym-medium/table.md'))}))", "",
             "2,000 roll-symmetric frusta (32 aspects x 64 frequencies), 200 test shapes, three noise levels "
             "relative to each response's peak (the report gives the dB); IoU-S, mean ± std over shapes:", ""]
    for noise in noises:
        picked = [(t.split("/", 1)[1], m) for t, m in rows if t.startswith(f"{noise}/")]
        lines += [f"Noise level `{noise}`:", "", markdown_table(picked, columns(OBSERVABILITY, [("iou_s", "IoU-S ↑", True, 3, "std")])), ""]
    return "\n".join(lines)


TABLE2_BEST = (  # (report table, row title) of the best diffusion configuration measured in each setting
    (Path("reports/rollsym-medium-longer-median/table.csv"), "Profile U-Net diffusion, 500 epochs, median of 32 draws"),
    (Path("reports/rollsym-medium-reduce/table.csv"), "Profile U-Net diffusion, 200 epochs, median of 32 draws"),
)


def table2_best(root: Path) -> str:
    """Per Table-2 setting, the best-trained diffusion configuration measured there beside InvRT (3 seeds)."""
    if not all((root / path).is_file() for path, _ in TABLE2_BEST):
        return ""
    invrt = {t.split("/", 1)[0]: m for t, m in read_table(root / "reports/rollsym-medium/table.csv") if t.endswith("/InvRT")}
    best: dict[tuple[str, str], tuple[str, float]] = {}
    for path, title in TABLE2_BEST:  # the first listed that holds a setting is the one reported
        for row, metrics in read_table(root / path):
            noise, name = row.split("/", 1)
            for obs in OBSERVABILITY:
                if name == title and f"{obs}/iou_s_mean" in metrics and (obs, noise) not in best:
                    best[(obs, noise)] = (f"[{title}]({link(path.with_suffix('.md'))})", metrics[f"{obs}/iou_s_mean"])
    lines = ["## Table 2: the diffusion's best configuration against InvRT", "",
             "IoU-S per setting of the best-trained profile U-Net measured there, beside InvRT (60 epochs, mean of "
             "3 seeds); paired differences and caveats: docs/rollsym.md, \"Combining the draws\".", "",
             "| observability | noise | diffusion configuration | IoU-S ↑ | InvRT IoU-S | difference |", "|---|---|---|---|---|---|"]
    for obs in OBSERVABILITY:
        for noise in ("low", "medium", "high"):
            if (obs, noise) in best and noise in invrt:
                config, iou = best[(obs, noise)]
                other = invrt[noise][f"{obs}/iou_s_mean"]
                lines.append(f"| {obs} | {noise} | {config} | {iou:.3f} | {other:.3f} | {iou - other:+.3f} |")
    return "\n".join(lines) + "\n"


def monocone(root: Path) -> str:
    path = root / "reports/monocone/monocone.csv"
    if not path.is_file():
        return ""
    rows = read_table(path)
    groups = {g: g for g in OBSERVABILITY if any(f"{g}/iou_s_mean" in m for _, m in rows)}
    return "\n".join([f"## Zero-shot monocone ([report]({link(Path('reports/monocone/monocone.md'))}))", "",
                      "Models trained on simulated shapes, scored on simulated cone measurements with noise (IoU-S):", "",
                      markdown_table(rows, columns(groups, [("iou_s", "IoU-S ↑", True, 3, "std")])), ""])
