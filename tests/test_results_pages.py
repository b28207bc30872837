"""docs/results.md, the model cards and README's table are generated from the committed reports: no drift."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest

from radar2shape.reporting import model_cards, results

ROOT = Path(__file__).resolve().parents[1]


def test_committed_pages_match_the_reports():
    stale = results.write_pages(ROOT, check=True)
    assert not stale, f"regenerate with `make results`: {[str(p.relative_to(ROOT)) for p in stale]}"


def test_model_card_quotes_the_shipped_runs_per_shape_scores():
    with (ROOT / model_cards.TABLE1_MEDIUM_STAGE2 / "scores" / f"{model_cards.SHIPPED_RUN}.csv").open() as handle:
        iou = np.mean([float(row["iou"]) for row in csv.DictReader(handle)])
    card = (ROOT / results.MODEL_CARD).read_text()
    assert f"| full | {iou:.3f} |" in card
    assert card == (ROOT / results.PACKAGED_CARD).read_text()  # what `reconstruct --about` prints


def test_real_model_card_quotes_its_runs_and_the_lookup():
    card = (ROOT / results.REAL_CARD).read_text()
    scores = ROOT / model_cards.REAL_REPORT / "scores"
    for obs in ("full", "partial"):
        for title, name in (("this model", f"{model_cards.REAL_TEST}-{obs}-seed0"), ("radar lookup", f"nearest-{obs}")):
            with (scores / f"{name}.csv").open() as handle:
                iou = np.mean([float(row["iou"]) for row in csv.DictReader(handle)])
            assert f"| {obs} | {title} | {iou:.3f} |" in card
    assert card == (ROOT / results.PACKAGED_REAL_CARD).read_text()  # what `reconstruct --about real` prints


def test_a_hand_edit_is_caught(tmp_path):
    shutil.copytree(ROOT / "reports", tmp_path / "reports", ignore=shutil.ignore_patterns("demo", "*.png"))
    for page in (results.RESULTS_PAGE, results.MODEL_CARD, results.PACKAGED_CARD, results.REAL_CARD,
                 results.PACKAGED_REAL_CARD, results.README):
        (tmp_path / page).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / page, tmp_path / page)
    assert results.write_pages(tmp_path, check=True) == []
    page = tmp_path / results.RESULTS_PAGE
    page.write_text(page.read_text().replace("0.553 ± 0.214", "0.653 ± 0.214", 1))
    readme = tmp_path / results.README
    readme.write_text(readme.read_text().replace("| Radar2Shape | 0.553", "| Radar2Shape | 0.563", 1))
    assert set(results.write_pages(tmp_path, check=True)) == {page, readme}
    assert set(results.write_pages(tmp_path)) == {page, readme}  # rewritten from the reports
    assert results.write_pages(tmp_path, check=True) == []


def test_about_prints_the_card(capsys):
    from radar2shape.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["reconstruct", "--about"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == (ROOT / results.PACKAGED_CARD).read_text()
    with pytest.raises(SystemExit) as exit_:
        main(["reconstruct", "--about", "real"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == (ROOT / results.PACKAGED_REAL_CARD).read_text()
    with pytest.raises(SystemExit) as exit_:
        main(["reconstruct", "--about", "boat"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err == "error: --about: no shipped model named 'boat'; expected one of parts, real\n"


def test_table2_best_quotes_the_per_shape_scores_of_the_runs_it_names():
    """Each setting's IoU-S on the results page is the mean of that run's per-shape scores; the 500-epoch
    grid wins where it ran, the 200-epoch one fills the two partial settings it did not."""
    page = (ROOT / results.RESULTS_PAGE).read_text()

    def mean_iou_s(grid: str, run: str) -> float:
        with (ROOT / "reports" / grid / "scores" / f"{run}.csv").open() as handle:
            return np.mean([float(row["iou_s"]) for row in csv.DictReader(handle)])

    for obs, noise in (("full", "low"), ("full", "high"), ("partial", "low")):
        iou = mean_iou_s("rollsym-medium-longer-median", f"unet_500_median32-{obs}-{noise}")
        assert f"| {obs} | {noise} | [Profile U-Net diffusion, 500 epochs, median of 32 draws]" in page
        assert f"| {iou:.3f} |" in page.split(f"| {obs} | {noise} | ", 1)[1].splitlines()[0]
    iou = mean_iou_s("rollsym-medium-reduce", "unet_median32-partial-high")
    row = page.split("| partial | high | ", 1)[1].splitlines()[0]
    assert row.startswith("[Profile U-Net diffusion, 200 epochs, median of 32 draws]") and f"| {iou:.3f} |" in row
