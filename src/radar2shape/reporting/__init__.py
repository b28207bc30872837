"""Readable reports: the run folders of a grid -> Markdown/CSV tables and figures.

Tables are formatted in :mod:`.tables`, run folders read in :mod:`.cells`, shared figures drawn in
:mod:`.figures`; each layout (:mod:`.layouts`) says which columns its table has and how run names
map onto rows, column groups and sections; :func:`write_report` (:mod:`.registry`) is the one
entry point. The names below are the ones code outside the package imports.
"""

from radar2shape.reporting.cells import (ARCHIVED, Cell, collect_cells, pooled, provenance, read_logged_metrics,
                                         read_scores, run_notes, runs_table, score_keys, scores_file, tested_cell)
from radar2shape.reporting.figures import model_rows_figure, one_replicate_per_row, saved_reconstructions
from radar2shape.reporting.layouts.columns import GROUP_TITLES, MODEL_TITLES, masking
from radar2shape.reporting.layouts.table1 import paper_subset
from radar2shape.reporting.registry import LAYOUTS, get_layout, write_report
from radar2shape.reporting.tables import SEED_SUFFIX, Column, Layout, markdown_table, merge_seeds, write_csv

__all__ = [
    "ARCHIVED", "Cell", "Column", "GROUP_TITLES", "LAYOUTS", "Layout", "MODEL_TITLES", "SEED_SUFFIX", "collect_cells",
    "get_layout", "markdown_table", "masking", "merge_seeds", "model_rows_figure", "one_replicate_per_row",
    "paper_subset", "pooled", "provenance", "read_logged_metrics", "read_scores", "run_notes", "runs_table",
    "saved_reconstructions", "score_keys", "scores_file", "tested_cell", "write_csv", "write_report",
]
