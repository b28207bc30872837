"""Export a trained RadarDiffusion checkpoint as the model shipped inside the package.

    python scripts/export_default_model.py --ckpt RUN/checkpoints/last.ckpt \
        [--out src/radar2shape/weights/radar2shape_parts_medium.ckpt] [--dtype float16] [--max-mb 25] [--surface-level 0.002] [--mesh-resolution 128]

Writes the inference-only copy (``radar2shape.pretrained.export_checkpoint``: weights,
hyperparameters, radar spec; no optimizer, loop or callback state), refuses a result over
``--max-mb`` before writing it, then loads the written file the way ``radar2shape reconstruct``
does, so a file that would not load is caught here rather than by a user. Bad input is one
``error:`` line and exit code 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from radar2shape.atomic import atomic_path, check_output_path
from radar2shape.errors import UserInputError
from radar2shape.pretrained import DEFAULT_MODEL, DTYPES, export_checkpoint

MAX_MB = 25.0  # the size a package can carry comfortably (wheel indexes and repositories)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", required=True, type=Path, help="RadarDiffusion checkpoint written by 'radar2shape fit'")
    parser.add_argument("--out", type=Path, default=DEFAULT_MODEL, help=f"exported file (default {DEFAULT_MODEL})")
    parser.add_argument("--dtype", choices=DTYPES, help="store the weights in this precision (default: as trained)")
    parser.add_argument("--surface-level", type=float,
                        help="SDF level Stage 1 meshes as the surface (default: the checkpoint's; chosen on validation)")
    parser.add_argument("--mesh-resolution", type=int,
                        help="marching-cubes grid of its reconstructions (default: the checkpoint's; chosen on validation)")
    parser.add_argument("--max-mb", type=float, default=MAX_MB, help=f"refuse a larger export (default {MAX_MB:g} MB)")
    return parser.parse_args(argv)


def describe(path: Path) -> str:
    """One line on what the exported file loads as: the check that it works with ``reconstruct``."""
    from radar2shape.commands.reconstruct import load_model

    model = load_model(path)
    grid = model.radar_spec.grid
    n_params = sum(p.numel() for p in model.parameters())
    return (f"loads as {type(model).__name__} ({n_params / 1e6:.2f} M parameters), radar grid "
            f"{len(grid.aspect_rad)} aspects x {len(grid.roll_rad)} rolls x {len(grid.freq_hz)} frequencies "
            f"{grid.freq_hz[0] / 1e9:g}-{grid.freq_hz[-1] / 1e9:g} GHz")


def export_and_check(args: argparse.Namespace) -> tuple[float, str]:
    """Export into a temporary file, load it, and only then rename it onto ``--out``.

    A file that does not load never replaces what ``--out`` held (e.g. the shipped model).
    """
    check_output_path(args.out, "--out", (".ckpt",))
    if args.out.resolve() == args.ckpt.resolve():
        raise UserInputError(f"--out: {args.out} is the source checkpoint (--ckpt); expected a separate file")
    with atomic_path(args.out) as temp:
        size = export_checkpoint(args.ckpt, temp, args.dtype, args.max_mb, args.surface_level,
                                 args.mesh_resolution)
        return size, describe(temp)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        size, loaded = export_and_check(args)
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: {size:.2f} MB (source {args.ckpt.stat().st_size / 1e6:.2f} MB); {loaded}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
