"""The shipped models' cards: what each was trained on, its measured scores and its limits.

Written by ``make results`` (:mod:`radar2shape.reporting.results`) from the committed reports and
the shipped files themselves (radar grid, size, training steps), to docs/ and beside the weights,
where ``radar2shape reconstruct --about [MODEL]`` prints them.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from radar2shape.reporting.cells import pooled, read_scores
from radar2shape.reporting.pages import (GENERATED, OBSERVABILITY, TABLE1_MEDIUM, TABLE1_MEDIUM_STAGE2, TABLE1_REAL,
                                         TABLE1_REAL_LONG, REAL_VERIFIER, link)

MODEL_CARD = Path("docs/model_card.md")
PACKAGED_CARD = Path("src/radar2shape/weights/MODEL_CARD.md")  # what `reconstruct --about` prints
# The shipped model (make default-model): of the three full-observability seeds of table1-medium-stage2,
# the one with the highest final validation IoU; its Stage 1 is table1-medium's.
SHIPPED_GRID, SHIPPED_RUN, SHIPPED_STAGE1 = "table1-medium-stage2", "radar2shape_long-full-seed2", "radar2shape_stage1"


# ---- the shipped model's card ------------------------------------------------------------------------
def _shipped_scores(root: Path) -> dict[str, float]:
    """Means over the shapes of the shipped run's per-shape scores (one row per test shape)."""
    rows = read_scores(root / TABLE1_MEDIUM_STAGE2 / "scores" / f"{SHIPPED_RUN}.csv")
    means = pooled(rows, ("iou", "chamfer_l2_x1e3", "fscore_1pct", "radar_dependence_iou", "ceiling_iou"))
    return {k[: -len("_mean")]: v for k, v in means.items() if k.endswith("_mean")} | {"shapes": means["num_shapes"]}


CONFIDENCE = Path("reports/shipped-model/confidence_parts_unseen.md")


def _confidence_rows(root: Path, observability: str) -> list[dict]:
    """The per-shape rows (IoU, radar consistency) of the shipped model's confidence report."""
    text = (root / CONFIDENCE).read_text()
    rows = csv.DictReader(io.StringIO(text.split("```csv\n", 1)[1].split("```", 1)[0]))
    return [r for r in rows if r["observability"] == observability]


def _partial_unseen(root: Path) -> str:
    """The shipped model's mean IoU on partly observed unseen shapes."""
    values = [float(r["iou"]) for r in _confidence_rows(root, "partial")]
    return f"{sum(values) / len(values):.3f}"


def _confidence_line(root: Path) -> str:
    from scipy.stats import spearmanr

    rows = _confidence_rows(root, "full")
    rho = spearmanr([float(r["radar_consistency"]) for r in rows], [float(r["iou"]) for r in rows]).statistic
    return (f"`reconstruct` also prints a radar consistency (docs/metrics.md): on {len(rows)} unseen parts shapes its "
            f"Spearman correlation with IoU is {rho:+.2f} ([confidence_parts_unseen.md]({link(CONFIDENCE)})): "
            "a high value flags a poor reconstruction.")


def _samples(k: int) -> str:
    return "one sample" if k == 1 else f"the mean SDF of {k} samples"


def _fit_minutes(root: Path) -> float:
    """Training time of the shipped run and the Stage 1 it reads, from the runs' records in the report."""
    import json

    records = (root / TABLE1_MEDIUM / "scores" / f"{SHIPPED_STAGE1}.json",
               root / TABLE1_MEDIUM_STAGE2 / "scores" / f"{SHIPPED_RUN}.json")
    return sum(json.loads(path.read_text())["record"]["fit_seconds"] for path in records) / 60


REAL_SHIPPED = Path("reports/real-shipped")  # grid real-shipped: the shipped model on the real test split


def _real_targets_line(root: Path) -> str:
    """What the card says of real objects: this model's per-shape scores on the real test split, the
    references' from the real-target report, and its yaw check."""
    path = root / REAL_SHIPPED / "scores" / "shipped-full.csv"
    if not path.is_file():
        return _yaw_line(root)
    rows = read_scores(path)
    means = pooled(rows, ("iou", "radar_dependence_iou", "ceiling_iou"))
    iou, dependence, ceiling = (means[f"{k}_mean"] for k in ("iou", "radar_dependence_iou", "ceiling_iou"))
    nearest = pooled(read_scores(root / TABLE1_REAL / "scores" / "nearest-full.csv"), ("iou",))["iou_mean"]
    return (f" On the {len(rows)} real test objects of `make data-real` (aircraft, ships, vehicles, buildings) "
            f"it scores IoU {iou:.3f}, with a radar dependence of {dependence:+.3f} (it hardly reads their radar) "
            f"and a Stage-1 ceiling of {ceiling:.3f} ([report]({link(REAL_SHIPPED / 'real-shipped.md')}); "
            f"a radar lookup in the real training objects: {nearest:.3f}, "
            f"[table1-real]({link(TABLE1_REAL / 'table1-real.md')}))." + _yaw_line(root) + _real_model_line(root))


def _real_model_line(root: Path) -> str:
    """The pointer from this card to the model trained on real targets, with its full-radar IoU."""
    rows = read_scores(root / REAL_REPORT / "scores" / f"{REAL_TEST}-full-seed0.csv")
    return (f" The `real` model (`--model real`, `--about real`), trained on the real training objects, scores "
            f"IoU {pooled(rows, ('iou',))['iou_mean']:.3f} on the same {len(rows)} test objects.")


YAW_CHECK = Path("reports/shipped-model/yaw_check_real.md")


def _yaw_line(root: Path, report: Path = YAW_CHECK) -> str:
    """A model on the real test aircraft, unturned and turned (the mean row of its yaw check ``report``)."""
    path = root / report
    if not path.is_file():
        return ""
    text = path.read_text()
    rows = [line for line in text.splitlines() if line.startswith("| ") and "__" in line]
    mean = next(line for line in text.splitlines() if line.startswith("| mean |")).split("|")
    yaw = text.split("| IoU at 0 deg | IoU at ", 1)[1].split(" ", 1)[0]
    return (f" This model, on {len(rows)} real test aircraft: IoU {float(mean[3]):.3f}, and {float(mean[4]):.3f} "
            f"with the aircraft turned {yaw} deg about z ([{report.name}]({link(report)})).")


LATENT_REFINEMENT = Path("reports/real/latent_refinement.csv")  # scripts/latent_refinement.py on the shipped real model


def _latent_refinement_line(root: Path, report: Path = LATENT_REFINEMENT) -> str:
    """What the real model's Stage 1 decodes from latents fitted to each test object (its encoder's share of the loss)."""
    path = root / report
    if not path.is_file():
        return ""
    rows = read_scores(path)
    by_class: dict[str, list[float]] = {}
    for row in rows:
        by_class.setdefault(row["label"], []).append(float(row["iou_fitted"]) - float(row["iou_encoded"]))
    lower = sum(1 for gains in by_class.values() if sum(gains) < 0)
    return (f" Part of the loss is its encoder's: latents fitted to each test object with the decoder frozen score "
            f"IoU {pooled(rows, ('iou_fitted',))['iou_fitted_mean']:.3f} against the encoder's "
            f"{pooled(rows, ('iou_encoded',))['iou_encoded_mean']:.3f} ([{report.with_suffix('.md').name}]"
            f"({link(report.with_suffix('.md'))})), though lower on {lower} of {len(by_class)} classes, thin ones, "
            "where a lower SDF error does not mean a higher IoU.")


def _read_shipped(checkpoint: Path):
    """A shipped file's checkpoint dict, radar spec and parameter count."""
    from radar2shape.checkpoints import load_checkpoint
    from radar2shape.pretrained import RADAR_SPEC_KEY
    from radar2shape.radar.spec import RadarSpec

    ckpt = load_checkpoint(checkpoint, "a shipped model", label="model card")
    params = sum(v.numel() for v in ckpt["state_dict"].values() if getattr(v, "is_floating_point", lambda: False)())
    return ckpt, RadarSpec.from_dict(ckpt[RADAR_SPEC_KEY]), params


def _radar_section(spec) -> list[str]:
    """The card section on the radar grid a model reads, from the spec stored in its file."""
    from numpy import degrees as deg

    grid = spec.grid
    return [
        "## The radar it reads",
        f"Monostatic VV physical optics, {len(grid.aspect_rad)} aspects over {deg(grid.aspect_rad[0]):g}-"
        f"{deg(grid.aspect_rad[-1]):g} deg x {len(grid.roll_rad)} rolls over {deg(grid.roll_rad[0]):g}-"
        f"{deg(grid.roll_rad[-1]):g} deg x {len(grid.freq_hz)} frequencies over {grid.freq_hz[0] / 1e9:g}-"
        f"{grid.freq_hz[-1] / 1e9:g} GHz, object size {grid.size_m:g} m; dB floor {spec.floor_db:g} dBsm, "
        f"normalised with its training mean {spec.db_mean:.2f} dB and std {spec.db_std:.2f} dB. Other files are "
        "resampled onto this grid (`reconstruct --measured`); cells a file does not cover are masked.", ""]


def model_card(root: Path, checkpoint: Path) -> str:
    from radar2shape.geometry.families.parts import PART_CLASSES
    from radar2shape.pretrained import size_mb

    ckpt, spec, params = _read_shipped(checkpoint)
    hp = ckpt["hyper_parameters"]
    full = _shipped_scores(root)

    def score_line(title: str, s: dict) -> str:
        return (f"| {title} | {s['iou']:.3f} | {s['chamfer_l2_x1e3']:.2f} | {s['fscore_1pct']:.3f} | "
                f"{s['radar_dependence_iou']:+.3f} | {s['ceiling_iou']:.3f} | {s['shapes']:.0f} |")

    run = link(TABLE1_MEDIUM_STAGE2 / f"{SHIPPED_GRID}.md")
    return "\n".join([
        "# Model card: the shipped Radar2Shape model", "", GENERATED, "",
        f"`{checkpoint.name}` ({size_mb(checkpoint.stat().st_size):.1f} MB, {params / 1e6:.2f} M parameters) is what "
        "`radar2shape reconstruct` uses without `--ckpt` (`--model parts`, the default); `radar2shape reconstruct "
        "--about` prints this card. For real aircraft, ships, vehicles and buildings use `--model real` "
        "(`--about real`).", "",
        "## What it is",
        f"A RadarDiffusion (Stage 2: {_samples(int(hp.get('num_samples', 1)))} of {hp.get('sample_steps', '?')} "
        "DDIM steps per reconstruction) holding its Stage-1 SDF-VAE: radar in, a watertight mesh in the unit cube out "
        "(docs/radar_diffusion.md). It trained for "
        f"{int(ckpt.get('epoch', 0)) + 1} epochs ({int(ckpt.get('global_step', 0)):,} optimizer steps) as run "
        f"`{SHIPPED_RUN}` of grid `{SHIPPED_GRID}`, on fully observed radar, on the Stage 1 of grid "
        "`table1-medium`; of the grid's three seeds it had the highest validation IoU.", "",
        "## What it was trained on",
        "1,000 procedural shapes of `conf/data/parts_medium.yaml` (seed 1), ten classes: "
        f"{', '.join(sorted(PART_CLASSES))}. Each object lies in its family's canonical pose in the body frame: "
        "z up, aspect measured from +z, roll about z from +x, longest side 1 m for the simulation "
        "(docs/design.md, section 4).", "",
        *_radar_section(spec),
        "## Measured scores",
        f"On the 100 test shapes of parts_medium, which it never trained on ([report]({run})); radar dependence: "
        "own radar minus another shape's; ceiling: its Stage 1 decoding the true shapes:", "",
        "| observability | IoU ↑ | CD x10^3 ↓ | F@1% ↑ | radar dependence Δ IoU | Stage-1 ceiling IoU | shapes |",
        "|---|---|---|---|---|---|---|",
        score_line("full", full), "",
        "`make demo` scores it again on 20 shapes of another seed, beside a lookup in 1,000 shapes (reports/demo/). "
        + _confidence_line(root), "",
        "## What it does not know",
        "- Objects outside the ten classes: other objects come back as the nearest thing it knows."
        + _real_targets_line(root),
        "- Other poses: it has only seen objects lined up with the frame; a turned object (a yaw that is not "
        "the family's) or a mesh in another up-axis convention is reconstructed in the wrong place. Put the "
        "object's up axis on +z before simulating.",
        "- Partly observed radar: it trained on every cell observed; with 70 % of the cells masked it falls to "
        f"IoU {_partial_unseen(root)} on unseen parts shapes ([confidence_parts_unseen.md]({link(CONFIDENCE)})); "
        "the table1-medium partial rows are separate models trained on masked radar.",
        "- Other radar: other bands, other polarisations, and multi-bounce (PO-SBR) or measured radar "
        "differ from its PO training data; docs/sbr_lora.md fine-tunes it to PO-SBR.", "",
        "## Retrain it",
        f"`make sweep GRID=table1-medium` trains its Stage 1, `make sweep GRID={SHIPPED_GRID}` this Stage 2 on it "
        "(that grid reads the Stage 1 from the shipped file, which holds it bit for bit; "
        f"{_fit_minutes(root):.0f} min of training on 2 cores together, per the reports' run records), then "
        "`make default-model` exports the run's last checkpoint here and `make results` rewrites this card.", ""])


# ---- the real-target model's card ---------------------------------------------------------------------
REAL_CARD = Path("docs/model_card_real.md")
PACKAGED_REAL_CARD = Path("src/radar2shape/weights/MODEL_CARD_real.md")  # `reconstruct --about real`
# The shipped real model (make real-model): table1-real-long's Stage 2, the real-target run with the
# highest test IoU; its scores, lookup rows, Stage-1 fit and yaw check come from that report.
REAL_GRID, REAL_RUN, REAL_TEST, REAL_STAGE1 = ("table1-real-long", "radar2shape_circ_steps12k_stage2-seed0",
                                               "radar2shape_circ_steps12k", "radar2shape_stage1")
REAL_REPORT = TABLE1_REAL_LONG
PER_CLASS_MODEL = "Radar2Shape (real model, shipped)"  # its column in the report's per_class.md
NEAR_DUPLICATES_REAL = Path("reports/real/near_duplicates.md")
REAL_ON_PARTS = Path("reports/real-model-on-parts")  # grid real-model-on-parts: this model on the parts test split


def _real_split_sizes(root: Path) -> tuple[int, int]:
    """(training objects, test objects) of data/real, from the near-duplicate report's summary row."""
    row = next(line for line in (root / NEAR_DUPLICATES_REAL).read_text().splitlines() if line.startswith("| test |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    return int(cells[2]), int(cells[1])


def _run_fit_seconds(report_md: Path, run: str) -> float:
    """A run's fit seconds from the runs table of its grid report."""
    row = next(line for line in report_md.read_text().splitlines() if line.startswith(f"| {run} | done | fit |"))
    return float(row.split("|")[4])


def _real_rows(root: Path) -> tuple[list[str], dict[str, list[dict]]]:
    """The card's score table rows (model and lookup per observability) and the model's per-shape rows."""
    keys = ("iou", "chamfer_l2_x1e3", "fscore_1pct", "radar_dependence_iou", "ceiling_iou")
    lines, per_shape = [], {}
    for obs in OBSERVABILITY:
        for title, scores in (("this model", REAL_REPORT / "scores" / f"{REAL_TEST}-{obs}-seed0.csv"),
                              ("this model, `--candidates 8`", REAL_VERIFIER / "scores" / f"real_verifier3-{obs}.csv"),
                              ("radar lookup", REAL_REPORT / "scores" / f"nearest-{obs}.csv")):
            rows = read_scores(root / scores)
            m = pooled(rows, keys)
            ceiling = m.get("ceiling_iou_mean", math.nan)
            lines.append(f"| {obs} | {title} | {m['iou_mean']:.3f} | {m['chamfer_l2_x1e3_mean']:.2f} | "
                         f"{m['fscore_1pct_mean']:.3f} | {m['radar_dependence_iou_mean']:+.3f} | "
                         f"{'n/a' if math.isnan(ceiling) else f'{ceiling:.3f}'} | {m['num_shapes']:.0f} |")
            if title == "this model":
                per_shape[obs] = rows
    return lines, per_shape


def _per_class_line(root: Path) -> str:
    """The classes where the lookup beats this model on IoU, from the report's per-class table."""
    path = REAL_REPORT / "per_class.md"
    table = (root / path).read_text().split("### IoU ↑", 1)[1].split("###", 1)[0]
    rows = [[c.strip().strip("*") for c in line.strip().strip("|").split("|")] for line in table.splitlines()
            if line.startswith("| ") and not line.startswith("| class")]
    header = next(line for line in table.splitlines() if line.startswith("| class"))
    names = [c.strip() for c in header.strip().strip("|").split("|")]
    model, lookup = names.index(PER_CLASS_MODEL), names.index("Nearest neighbour")
    behind = [r[0].rsplit(" (", 1)[0] for r in rows if float(r[lookup]) > float(r[model])]
    return (f"- Some classes: the radar lookup scores a higher IoU on {len(behind)} of the {len(rows)} classes "
            f"({', '.join(behind)}; [per_class.md]({link(path)})).")


def real_model_card(root: Path, checkpoint: Path) -> str:
    """The card of the model trained on real targets (``reconstruct --model real``)."""
    import statistics

    from radar2shape.pretrained import size_mb

    ckpt, spec, params = _read_shipped(checkpoint)
    hp = ckpt["hyper_parameters"]
    n_train, n_test = _real_split_sizes(root)
    rows, per_shape = _real_rows(root)
    partial_cd = [float(r["chamfer_l2_x1e3"]) for r in per_shape["partial"]]
    report_md = root / REAL_REPORT / f"{REAL_GRID}.md"
    minutes = (_run_fit_seconds(report_md, REAL_STAGE1) + _run_fit_seconds(report_md, REAL_RUN)) / 60
    full = pooled(per_shape["full"], ("iou", "fscore_1pct", "ceiling_iou"))
    on_parts = read_scores(root / REAL_ON_PARTS / "scores" / "real_model-full.csv")
    lookup_f = pooled(read_scores(root / REAL_REPORT / "scores" / "nearest-full.csv"), ("fscore_1pct",))["fscore_1pct_mean"]
    return "\n".join([
        "# Model card: the shipped real-target model", "", GENERATED, "",
        f"`{checkpoint.name}` ({size_mb(checkpoint.stat().st_size):.1f} MB, {params / 1e6:.2f} M parameters) is what "
        "`radar2shape reconstruct --model real` uses; `radar2shape reconstruct --about real` prints this card.", "",
        "## What it is",
        f"A RadarDiffusion (Stage 2: {_samples(int(hp.get('num_samples', 1)))} of {hp.get('sample_steps', '?')} "
        "DDIM steps per reconstruction) holding its Stage-1 SDF-VAE: radar in, a watertight mesh in the unit cube out "
        f"(docs/radar_diffusion.md). It trained for {int(ckpt.get('epoch', 0)) + 1} epochs "
        f"({int(ckpt.get('global_step', 0)):,} optimizer steps) as run `{REAL_RUN}` of grid `{REAL_GRID}`, with "
        f"{hp.get('roll_padding', '?')} roll padding and random partial-observation masks, on that "
        f"grid's Stage 1 (`{REAL_STAGE1}`).", "",
        "## What it was trained on",
        f"The {n_train} training objects of `make data-real` (conf/data/real.yaml; {n_test} more are held out by "
        "object for the scores below): FlightGear's aircraft (airliners, business jets, light aircraft, fighters, "
        "helicopters), ships, ground vehicles and buildings, and Gazebo models (household objects, street "
        "furniture and others), each made watertight with its up axis on +z and scaled to the unit cube "
        "(docs/data.md). The meshes never ship: they are data under their own licences (FlightGear's GPL-2+, "
        "the Gazebo models' CC BY 3.0, credited to their authors in osrf/gazebo_models), and `make data-real` "
        "rebuilds them from Debian's FlightGear packages and ../shared/real-meshes. This file holds weights "
        "learned from them, not the meshes; keep both credits with it when you pass it on.", "",
        *_radar_section(spec),
        "## Measured scores",
        f"On the {n_test} real test objects ([report]({link(report_md.relative_to(root))}), paired differences in "
        f"[paired.md]({link(REAL_REPORT / 'paired.md')})), beside a radar lookup (the training object whose "
        "radar is nearest); `--candidates 8`: the mean of the 3 of 8 samples its verifier scores best, as "
        f"`reconstruct --candidates 8` returns ([real-verifier]({link(REAL_VERIFIER / 'real-verifier.md')})); "
        "radar dependence: own radar minus another object's; ceiling: its Stage 1 decoding "
        "the true shapes; partial: 70 % of the cells masked:", "",
        "| observability | model | IoU ↑ | CD x10^3 ↓ | F@1% ↑ | radar dependence Δ IoU | Stage-1 ceiling IoU | shapes |",
        "|---|---|---|---|---|---|---|---|",
        *rows, "",
        f"The partial Chamfer mean is dominated by one object ({max(partial_cd):.0f}); the median is "
        f"{statistics.median(partial_cd):.2f}." + _yaw_line(root, REAL_REPORT / "yaw_check.md"), "",
        "## What it does not know",
        _per_class_line(root),
        f"- Surface detail: its F-score at 1 % ({full['fscore_1pct_mean']:.3f}: the share of surface points within "
        f"1 % of the cube of the true surface) is below the lookup's ({lookup_f:.3f}) although its IoU and Chamfer "
        "are better: it gets the volume closer and the fine surface less often. Its Stage 1 reaches IoU "
        f"{full['ceiling_iou_mean']:.3f} on these objects, a bound on this model; meshing its SDF on a finer grid "
        "or at another level does not raise it (docs/radar_diffusion.md, \"Decoding settings\")."
        + _latent_refinement_line(root),
        "- Procedural shapes: it never saw the parts family; on the "
        f"{len(on_parts)} parts_medium test shapes it scores IoU {pooled(on_parts, ('iou',))['iou_mean']:.3f} "
        f"([report]({link(REAL_ON_PARTS / 'real-model-on-parts.md')})), the default `--model parts` "
        f"{_shipped_scores(root)['iou']:.3f}.",
        "- Other up axes: objects are trained with their up axis on +z; turns about z are covered (above), a "
        "mesh lying on its side is not. Put the object's up axis on +z before simulating.",
        "- Other radar: other bands, other polarisations, and multi-bounce (PO-SBR) or measured radar "
        "differ from its PO training data.", "",
        "## Retrain it",
        f"`make data-real` builds the data, `make sweep GRID={REAL_GRID}` trains its Stage 1 and this Stage 2 "
        f"({minutes:.0f} min of training on 2 cores together, per the report's run table), then "
        "`make real-model` exports the run's last checkpoint here and `make results` rewrites this card.", ""])
