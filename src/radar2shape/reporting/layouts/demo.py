"""``demo``: ``make demo``: ``<model>-<section>`` test runs. Section ``unseen`` is the product (the
shipped model and the lookup on shapes neither has seen); ``full`` and ``partial`` are the platform
check (tiny models trained in minutes). The report opens with what each table shows, so a reader
does not take the platform check's numbers for the method's.
"""

from __future__ import annotations

from pathlib import Path

from radar2shape.reporting.cells import collect_cells, runs_table, sampling_line
from radar2shape.reporting.figures import radar_shapes_figure
from radar2shape.reporting.layouts.columns import CEILING_IOU, DEPENDENCE_IOU, SHAPE_COLUMNS, SHAPES_IOU
from radar2shape.reporting.tables import Layout, markdown_table, write_csv

UNSEEN = "unseen"

INTRO = """\
This report has two parts.

**1. The shipped model on shapes it has never seen.** `radar2shape reconstruct` uses a Radar2Shape
model shipped in the package (docs/model_card.md), trained on 1,000 shapes of the procedural `parts`
family (seed 1). Here it reconstructs 20 shapes of the same family built from another seed
(conf/data/parts_unseen.yaml), on the paper's metric sampling. Beside it, the nearest-neighbour
lookup returns the training shape whose radar is closest, searching 1,000 shapes of that other seed:
as many shapes of the family as the model learnt from. The radar dependence says how much worse each
row gets when every shape is reconstructed from another shape's radar (near zero: a shape prior).
The lookup does well on this family because its shapes come in close variants (on parts_medium, 30 of
100 test shapes have a training shape at IoU >= 0.9; reports/parts_medium/near_duplicates.md);
real objects have no such copies.

**2. The platform check.** The demo also trains both stages of Radar2Shape from scratch on a tiny
dataset (36 training shapes, a 16^3 radar grid, a few minutes of CPU) and tests them with the two
references, under full and partial observability, to show that the whole pipeline runs on your
machine. With 36 training shapes of 10 classes the tiny model has seen about four shapes per
class: it learns the coarse outline its radar implies, while the lookup returns a whole training
shape, and an exact shape of the right class beats a blurred one on IoU. Expect the lookup to win
this part; the numbers of the method at scale are in docs/results.md.
"""


def write_demo(grid, out: Path, layout: Layout, shapes: int, archive: Path | None = None) -> Path:
    """``README.md``, ``table_<section>.csv`` and one reconstruction figure per section shown."""
    cells, _ = collect_cells(grid)
    lines = ["# radar2shape demo", "", INTRO]
    diagnostics = {section: rows for section, rows, _ in layout.tables(cells, layout.diagnostics)}
    for section, rows, columns in layout.tables(cells):
        in_section = [c for c in cells if (layout.split(c.name) or {}).get("section") == section]
        lines += [f"## {layout.section_title(section)}", "",
                  "Mean ± std over the test shapes; best per column in bold (docs/metrics.md).", "",
                  markdown_table(rows, columns), "", sampling_line(in_section), ""]
        write_csv(rows, columns, out / f"table_{section}.csv")
        if diagnostics.get(section):
            lines += ["Diagnostics (radar dependence: own radar minus another shape's, ± standard error):", "",
                      markdown_table(diagnostics[section], list(layout.diagnostics)), ""]
        shown = [c for c in in_section if c.state == "done" and section in (UNSEEN, "full")]
        figure = f"reconstructions_{section}.png"
        if shown and radar_shapes_figure(shown, layout, out / figure, shapes):
            lines += [f"![{section} reconstructions]({figure})", ""]
    lines += ["## Runs", "", runs_table(cells), ""]
    (out / "README.md").write_text("\n".join(lines))
    return out / "README.md"


SECTION_TITLES = {
    UNSEEN: "1. The shipped model on 20 unseen parts shapes (full observability)",
    "full": "2. Platform check: tiny models, full observability",
    "partial": "2. Platform check: tiny models, partial observability",
}

LAYOUT = Layout("demo", SHAPE_COLUMNS, write_demo, ("row", "section"),
                {"shipped": "Radar2Shape, shipped model", "radar2shape": "Radar2Shape, tiny (trained here)",
                 "nearest": "nearest-neighbour lookup", "mean_shape": "mean-shape"}, {},
                lambda section: SECTION_TITLES.get(section, section),
                diagnostics=(DEPENDENCE_IOU, CEILING_IOU, SHAPES_IOU))
