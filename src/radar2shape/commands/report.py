"""``radar2shape report --grid NAME [--out DIR]``: a grid's run folders -> tables and figures.

Reads the runs of ``conf/grid/NAME.yaml`` (or a grid file path) from their folders, as
``radar2shape sweep`` left them, and writes the grid's report layout (its ``report:`` key, default
``table1``; see :mod:`radar2shape.reporting.layouts`) to ``reports/NAME/`` (or ``--out``).

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
    from radar2shape.reporting import LAYOUTS

    parser.add_argument("--grid", required=True, help="grid name (conf/grid/NAME.yaml) or a grid YAML file")
    parser.add_argument("--out", help="output folder (default reports/NAME)")
    parser.add_argument("--layout", choices=sorted(LAYOUTS), help="report layout (default: the grid's 'report', else table1)")
    parser.add_argument("--shapes", type=int, default=FIGURE_SHAPES, help="test shapes per figure")


def main(args: argparse.Namespace) -> int:
    """While a sweep writes the grid (it holds the grid's lock) the report does not wait: it reads
    the runs finished so far, says so, and is consistent because a run counts only with its ``done``
    marker, written last and atomically after its metrics, and a sweep that redoes a run deletes
    that marker before anything else of the run."""
    from radar2shape.locking import holder_of
    from radar2shape.reporting import write_report
    from radar2shape.sweep import LOCK, load_grid

    grid = load_grid(args.grid)
    holder = holder_of(grid.out_dir, LOCK)
    if holder is not None:
        print(f"note: a sweep is writing {grid.out_dir} (pid {holder.get('pid')} on host {holder.get('host')}, "
              f"started {holder.get('started')}); this report holds the runs finished so far")
    path = write_report(grid, args.out, args.layout, args.shapes)
    print(f"wrote {path}")
    return 0
