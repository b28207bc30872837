"""scripts/reconstruction_figure.py: a figure of chosen finished runs of a grid, rows in the caller's order."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import yaml

from tests.test_report import finished_run

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("reconstruction_figure", REPO / "scripts" / "reconstruction_figure.py")
reconstruction_figure = importlib.util.module_from_spec(spec)
spec.loader.exec_module(reconstruction_figure)


def make_grid(tmp_path: Path) -> Path:
    runs = tmp_path / "runs"
    names = ["radar2shape-full-seed0", "radar2shape-full-seed1", "tmnet-full", "list-full"]
    for name in names[:3]:
        finished_run(runs / name, 1.0, 0.5, 0.5)
    (runs / "list-full").mkdir(parents=True)  # started, not finished
    path = tmp_path / "t.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(runs), "report": "table1", "runs": [{"name": n} for n in names]}))
    return path


def test_rows_follow_the_callers_order_with_the_reports_titles(tmp_path, capsys):
    grid, out = make_grid(tmp_path), tmp_path / "figs" / "f.png"
    assert reconstruction_figure.main(["--grid", str(grid), "--runs", "tmnet-full", "radar2shape-full-seed1",
                                       "--out", str(out), "--shapes", "2"]) == 0
    assert out.stat().st_size > 0
    assert capsys.readouterr().out.strip() == f"wrote {out}: rows ground truth, TMNet, Radar2Shape"


def test_unfinished_unknown_or_repeated_rows_are_one_error_line_and_no_file(tmp_path, capsys):
    grid, out = make_grid(tmp_path), tmp_path / "f.png"
    for runs, expected in ((["list-full"], "list-full has no saved test reconstructions"),
                           (["nope-full"], "'nope-full' is not a run of grid"),
                           (["radar2shape-full-seed0", "radar2shape-full-seed1"], "one run per table row")):
        assert reconstruction_figure.main(["--grid", str(grid), "--runs", *runs, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: --runs:") and expected in err[0]
    assert not out.exists()
