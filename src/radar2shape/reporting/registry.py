"""The one place report layouts are registered by name (:data:`LAYOUTS`), and :func:`write_report`,
the one entry point (``radar2shape report`` and the end of ``radar2shape sweep``).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from radar2shape.reporting.layouts import demo, monocone, rollsym, table1
from radar2shape.reporting.tables import Layout

LAYOUTS: dict[str, Layout] = {layout.name: layout for layout in (table1.LAYOUT, rollsym.LAYOUT, demo.LAYOUT, monocone.LAYOUT)}


def get_layout(name: str) -> Layout:
    if name not in LAYOUTS:
        from radar2shape.errors import UserInputError

        raise UserInputError(f"unknown report layout {name!r} (expected one of {sorted(LAYOUTS)})")
    return LAYOUTS[name]


def write_report(grid, out: str | Path | None = None, layout: str | None = None, shapes: int = 4) -> Path:
    """Write ``grid``'s report in ``layout`` (default: the grid's ``report``, else ``table1``) to
    ``out`` (default ``reports/<grid name>``); returns the main Markdown file.

    All or nothing: the layout writes into a hidden staging folder inside ``out`` and its files
    are moved into place only once every one is written, so a failed report changes no file.
    """
    import shutil
    import tempfile

    from radar2shape.atomic import check_output_dir
    from radar2shape.errors import UserInputError

    chosen = get_layout(layout or grid.report or "table1")
    out = Path(out) if out else Path("reports") / grid.name
    check_output_dir(out, "--out")
    archive = out / "scores"  # per-shape scores this report kept last time: they stand in for lost run folders
    ran = grid.out_dir.is_dir() and any(grid.out_dir.iterdir())
    if not ran and not (archive.is_dir() and any(archive.glob("*.csv"))):
        raise UserInputError(f"{grid.path}: no runs to report: out_dir {grid.out_dir} is missing or empty "
                             f"and {archive} holds no per-shape scores (run 'radar2shape sweep {grid.path}' first)")
    created = [folder for folder in (out, *out.parents) if not folder.exists()]
    out.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".report-", dir=out))
    try:
        main = chosen.write(grid, staging, chosen, shapes, archive)
        for path in sorted(p for p in staging.rglob("*") if p.is_file()):
            target = out / path.relative_to(staging)
            target.parent.mkdir(parents=True, exist_ok=True)
            path.replace(target)
        return out / main.relative_to(staging)
    except BaseException as err:
        shutil.rmtree(staging, ignore_errors=True)
        for folder in created:  # deepest first; only the folders this call made, once empty again
            with contextlib.suppress(OSError):
                folder.rmdir()
        from radar2shape.atomic import disk_full, is_disk_full

        if isinstance(err, Exception) and is_disk_full(err):
            raise disk_full(out) from err  # a table or figure write found no space: name the report folder
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
