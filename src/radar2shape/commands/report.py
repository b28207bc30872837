"""``radar2shape report --grid NAME [--out DIR]``: a grid's run folders -> tables and figures.

Reads the runs of ``conf/grid/NAME.yaml`` (or a grid file path) from their folders, as
``radar2shape sweep`` left them, and writes the grid's report layout (its ``report:`` key, default
``table1``; see :mod:`radar2shape.report_layouts`) to ``reports/NAME/`` (or ``--out``).

In the ``table1`` layout run names say where a run goes: ``<model>-<group>`` is the cell of row
``model`` in column group ``group`` (``radar2shape-full``, ``tmnet-partial``, ``radar2shape-full-sbr``
for PO-SBR test data); a name without ``-`` is an auxiliary run (e.g. a Stage-1 VAE) listed with
its wall time only. Folders of ``out_dir`` named like a cell but not in the grid (a model scored by
hand with ``radar2shape test --trainer.default_root_dir <out_dir>/<model>-<group>/test``, or written
by another experiment) are read from their logged test metrics and shown in a separate table under
the grid's: another protocol, never mixed into the grid's table, bold or CSV. A run folder may hold
a ``note`` file (one line, e.g. where a result was carried over from): it is printed under the
table, so no cell's origin is hidden.
"""

from __future__ import annotations

import argparse

FIGURE_SHAPES = 6


def configure_parser(parser: argparse.ArgumentParser) -> None:
    from radar2shape.report_layouts import LAYOUTS

    parser.add_argument("--grid", required=True, help="grid name (conf/grid/NAME.yaml) or a grid YAML file")
    parser.add_argument("--out", help="output folder (default reports/NAME)")
    parser.add_argument("--layout", choices=sorted(LAYOUTS), help="report layout (default: the grid's 'report', else table1)")
    parser.add_argument("--shapes", type=int, default=FIGURE_SHAPES, help="test shapes per figure")


def main(args: argparse.Namespace) -> int:
    from radar2shape.reporting import write_report
    from radar2shape.sweep import load_grid

    path = write_report(load_grid(args.grid), args.out, args.layout, args.shapes)
    print(f"wrote {path}")
    return 0
