"""``radar2shape reconstruct``: a mesh from a radar response, simulated or measured.

``--radar FILE.npz`` reads what ``radar2shape simulate`` writes; ``--measured FILE
[--format austin|csv|npz]`` reads measured data (``radar.measured``: Austin RCS text, generic
CSV / NPZ). Both are put on the checkpoint's radar grid by ``radar.measured.resample``: linear
interpolation of the dB image (not of the complex field, whose phase turns too fast), cells the
file does not cover masked (the models' mask channel), a partly overlapping frequency band
accepted down to ``--min-overlap``, optional ``--calibration-db`` and ``--size-m`` scaling.
``--roll-symmetric`` repeats an aspect-only response along roll for the full 3D model, as the
paper does with measured data. The checkpoint may be a :class:`RadarDiffusion` (3D) or a
roll-symmetric profile model (``ProfileUNetDiffusion``, ``InvRT``), which takes the aspect-only
response directly. Everything about the radar (grid, dB floor and train statistics) comes from
the :class:`~radar2shape.radar.spec.RadarSpec` stored in the checkpoint: no dataset is needed.
Without ``--ckpt`` a model shipped in the package is used (``--model``, default
``radar2shape.pretrained.DEFAULT_NAME``), and its path is printed.

Every option, output path and input file is checked before the model runs (the marching-cubes
grid against a memory limit too); a response with no measurement (every cell at the model's dB
floor, e.g. all zeros) is refused unless ``--allow-empty``. All outputs (mesh, ``--save-input``,
``--spread``, ``--png``) are written together at the end, atomically: a failed run leaves none.
torch and Lightning are imported only once the arguments are parsed.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from radar2shape.atomic import atomic_path, atomic_paths, check_output_path
from radar2shape.errors import UserInputError
from radar2shape.preflight import add_memory_option, check_input_file, check_memory, memory_limit_bytes
from radar2shape.pretrained import DEFAULT_NAME, SHIPPED_MODELS, load_model

KEEP = 3  # = models.verifier.KEEP (not imported: it needs torch before the arguments are parsed)

if TYPE_CHECKING:
    import torch

    from radar2shape.radar.measured import GridInput
    from radar2shape.radar.spec import RadarSpec

FORMATS = ("austin", "csv", "npz")  # = radar.measured.FORMATS
MIN_OVERLAP = 0.5  # = radar.measured.MIN_OVERLAP
MESH_OUT_SUFFIXES = (".obj", ".off", ".ply", ".stl", ".glb")  # = geometry.mesh_io.WRITE_SUFFIXES
IMAGE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")
# Peak bytes per marching-cubes cell: float32 query points [N^3, 3], SDF values and their copy.
BYTES_PER_GRID_CELL = 24


class AboutAction(argparse.Action):
    """``--about [MODEL]``: print a shipped model's card and exit, like ``--help`` (no other option needed)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs="?", const=DEFAULT_NAME, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        from radar2shape.pretrained import model_card

        try:
            text = model_card(values)
        except UserInputError as err:
            parser.exit(2, f"error: {err}\n")
        sys.stdout.write(text)
        parser.exit(0)


def configure_parser(parser: argparse.ArgumentParser) -> None:
    names = ", ".join(SHIPPED_MODELS)
    parser.add_argument("--about", action=AboutAction, metavar="MODEL",
                        help=f"print a shipped model's card (training data, scores, limits) and exit; MODEL is "
                        f"one of {names} (default {DEFAULT_NAME})")
    model = parser.add_mutually_exclusive_group()
    model.add_argument("--model", choices=tuple(SHIPPED_MODELS),
                       help=f"a model shipped with radar2shape: parts (procedural parts family) or real (real "
                       f"aircraft, ships, vehicles, buildings); default {DEFAULT_NAME}")
    model.add_argument("--ckpt", type=Path,
                       help="RadarDiffusion or roll-symmetric profile model checkpoint (.ckpt) instead of a "
                       "shipped model")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--radar", type=Path, help="response .npz as written by 'radar2shape simulate'")
    source.add_argument("--measured", type=Path, nargs="+", metavar="FILE",
                        help="measured response file (several Austin .txt files combine, e.g. one per frequency)")
    parser.add_argument("--format", choices=FORMATS, help="format of --measured (default: from the suffix: "
                        ".txt austin, .csv csv, .npz npz)")
    parser.add_argument("--out", required=True, type=Path, help="output mesh (.obj, .off, .ply, .stl or .glb)")
    parser.add_argument("--roll-symmetric", action="store_true", help="repeat an aspect-only response along roll")
    parser.add_argument("--calibration-db", type=float, default=0.0, help="added to every dB value (default 0)")
    parser.add_argument("--size-m", type=float, help="the measured object's longest side in metres: scales "
                        "frequency and level to the model's object size (default: no scaling)")
    parser.add_argument("--min-overlap", type=float, default=MIN_OVERLAP,
                        help=f"least fraction of the model's band the file must cover (default {MIN_OVERLAP})")
    parser.add_argument("--save-input", type=Path, help="also write the model-grid input (.npz: db, mask, ...)")
    parser.add_argument("--samples", type=int, help="K sampled shapes; the mesh is their mean (default: model's)")
    parser.add_argument("--candidates", type=int, help="draw K shapes and return the mean of the ones the model's "
                        "verifier scores best (--keep), with their predicted IoU (3D models with a verifier file; "
                        "not with --samples)")
    parser.add_argument("--keep", type=int, help="with --candidates: how many of the best-scored candidates are "
                        f"averaged (mean SDF; default {KEEP}, at most K; 1 returns the single best)")
    parser.add_argument("--verifier", type=Path, help="verifier file for --candidates (default: the checkpoint's "
                        "<name>.verifier.pt beside it)")
    parser.add_argument("--steps", type=int, help="DDIM steps, RadarDiffusion only (default: the model's)")
    parser.add_argument("--resolution", type=int, help="marching-cubes grid size, RadarDiffusion only")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    parser.add_argument("--png", type=Path, help="also write a PNG: input dB image and the reconstruction")
    parser.add_argument("--spread", type=Path, help="also write the per-vertex SDF std over the K samples (.npy)")
    parser.add_argument("--allow-empty", action="store_true", help="reconstruct even when every cell of the "
                        "response is at the model's dB floor (no measurement, e.g. an all-zero file)")
    add_memory_option(parser)
    parser.epilog = ("Bad input is one 'error:' line (exit code 2) and nothing is written; outputs appear "
                     "complete or not at all.")


def is_profile_model(model) -> bool:
    from radar2shape.models.profile_diffusion import ProfileModel

    return isinstance(model, ProfileModel)


def measured_input(paths: list[Path], fmt: str | None, spec: RadarSpec, roll_symmetric: bool = False,
                   calibration_db: float = 0.0, size_m: float | None = None,
                   min_overlap: float = MIN_OVERLAP) -> GridInput:
    """A file on the spec's grid; a roll-symmetric spec takes an aspect-only response at its one roll."""
    from radar2shape.radar.measured import read_measured, resample

    measurement = read_measured(paths, fmt)
    if spec.roll_symmetric and not measurement.aspect_only:
        raise UserInputError(f"{measurement.source}: a profile model needs an aspect-only response (one roll angle), "
                             f"got {len(measurement.roll_rad)} roll angles")
    grid = spec.grid
    return resample(measurement, grid.aspect_rad, grid.roll_rad, grid.freq_hz, floor_db=spec.floor_db,
                    calibration_db=calibration_db, size_m=size_m, model_size_m=grid.size_m,
                    min_overlap=min_overlap, roll_symmetric=roll_symmetric or spec.roll_symmetric)


def model_batch(spec: RadarSpec, grid: GridInput) -> dict[str, torch.Tensor]:
    """The one-sample batch the model sees: ``spec.normalise``d radar and its mask (roll dropped when roll-symmetric)."""
    import torch

    radar = torch.from_numpy(spec.normalise(grid.db, grid.mask))[None]
    mask = torch.from_numpy(grid.mask)[None]
    if spec.roll_symmetric:
        return {"radar": radar[:, :, 0], "radar_mask": mask[:, :, 0]}
    return {"radar": radar, "radar_mask": mask}


def reconstruct_input(model, grid: GridInput, samples: int | None = None, steps: int | None = None,
                      resolution: int | None = None, seed: int = 0):
    """``(Reconstruction, per-vertex SDF spread or None)`` of a model-grid input, 3D or profile model."""
    batch = model_batch(model.radar_spec, grid)
    if is_profile_model(model):
        if samples is not None:
            model.hparams.num_samples = samples
        if "sample_seed" in model.hparams:
            model.hparams.sample_seed = seed
        return model.reconstruct(batch)[0], None
    (recon, spread), = model.reconstruct_with_uncertainty(batch, num_samples=samples, steps=steps,
                                                          resolution=resolution, sample_seed=seed)
    return recon, spread


def reconstruct_best_candidate(model, verifier, grid: GridInput, candidates: int, keep: int = KEEP,
                               steps: int | None = None, resolution: int | None = None, seed: int = 0):
    """``(Reconstruction, SDF spread over the K candidates at its vertices, kept indices best first, predicted
    IoUs [K])``: the mesh is the mean SDF of the ``keep`` best-scored candidates, ``predicted_iou`` their mean."""
    import torch

    from radar2shape.models.verifier import verified_latents
    from radar2shape.reconstruction import Reconstruction

    batch = model_batch(model.radar_spec, grid)
    latents, predicted, kept = verified_latents(model, verifier, batch, candidates, keep, steps, seed)
    mesh, _ = model.mean_mesh(latents[kept], resolution)
    spread = np.zeros(0, dtype=np.float32)
    if len(mesh.vertices):
        with torch.no_grad():
            vertices = torch.as_tensor(mesh.vertices, dtype=torch.float32, device=model.device)
            spread = model.sdf_function(latents)(vertices).std(0, unbiased=False).cpu().numpy()
    recon = Reconstruction(mesh=model.place_in_heading(mesh, batch, 0), predicted_iou=float(predicted[kept].mean()))
    return recon, spread, kept.cpu().numpy(), predicted.cpu().numpy()


def save_png(path: Path, db: np.ndarray, spec: RadarSpec, mesh, title: str) -> None:
    """Input dB image (mean power over frequency, aspect x roll; masked cells blank) beside two views of the mesh."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from radar2shape.geometry.query import sample_surface
    from radar2shape.metrics.render import VIEWS, depth_image

    points = sample_surface(mesh, 20_000, 0)[0] if len(mesh.faces) else np.zeros((0, 3))
    power = np.where(np.isfinite(db), 10 ** (db / 10), 0.0)
    count = np.isfinite(db).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):  # masked cells (no value) stay blank
        power_db = np.where(count > 0, 10 * np.log10(power.sum(axis=-1) / count), np.nan)
    aspect, roll_deg = np.degrees(spec.grid.aspect_rad), np.degrees(spec.grid.roll_rad)
    roll_extent = (roll_deg[0], roll_deg[-1]) if len(roll_deg) > 1 else (roll_deg[0] - 0.5, roll_deg[0] + 0.5)
    fig = Figure(figsize=(3.4 * (1 + len(VIEWS)), 3.4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 1 + len(VIEWS))
    image = axes[0].imshow(power_db, aspect="auto", cmap="viridis", extent=(*roll_extent, aspect[-1], aspect[0]))
    axes[0].set(title="input (mean over frequency)", xlabel="roll (deg)", ylabel="aspect (deg)")
    fig.colorbar(image, ax=axes[0], label="dBsm")
    for ax, (azimuth, elevation) in zip(axes[1:], VIEWS):
        ax.imshow(depth_image(points, azimuth, elevation), cmap="viridis", vmin=-0.6, vmax=0.6)
        ax.set(title=f"reconstruction ({azimuth:g}, {elevation:g} deg)", xticks=[], yticks=[])
    fig.suptitle(title, fontsize=9)
    with atomic_path(path) as temp:
        fig.savefig(temp, dpi=100)


def _check_arguments(args: argparse.Namespace) -> list[Path]:
    """Everything checkable without the model; returns the output paths (the mesh first)."""
    for name in ("samples", "steps", "resolution", "candidates", "keep"):
        value = getattr(args, name)
        if value is not None and value < (2 if name in ("resolution", "candidates") else 1):
            least = "an integer >= 2" if name in ("resolution", "candidates") else "a positive integer"
            raise UserInputError(f"--{name}: expected {least}, got {value}")
    if args.candidates is not None and args.samples is not None:
        raise UserInputError("--candidates returns what the verifier scores best of K, --samples the mean of all K: "
                             "use one of them")
    for name in ("verifier", "keep"):
        if getattr(args, name) is not None and args.candidates is None:
            raise UserInputError(f"--{name} is read with --candidates K; add --candidates")
    if args.keep is not None and args.keep > args.candidates:
        raise UserInputError(f"--keep: at most the {args.candidates} candidates, got {args.keep}")
    if args.seed < 0:
        raise UserInputError(f"--seed: expected a non-negative integer, got {args.seed}")
    if args.format is not None and args.measured is None:
        raise UserInputError("--format applies to --measured files (--radar is always the simulate .npz)")
    if not 0.0 < args.min_overlap <= 1.0:
        raise UserInputError(f"--min-overlap: expected a fraction in (0, 1], got {args.min_overlap}")
    if not math.isfinite(args.calibration_db):
        raise UserInputError(f"--calibration-db: expected a finite number of dB, got {args.calibration_db}")
    if args.size_m is not None and not (math.isfinite(args.size_m) and args.size_m > 0):
        raise UserInputError(f"--size-m: expected a positive number of metres, got {args.size_m}")
    outputs = {"--out": check_output_path(args.out, "--out", MESH_OUT_SUFFIXES)}
    for name, suffixes in (("save_input", (".npz",)), ("spread", (".npy",)), ("png", IMAGE_SUFFIXES)):
        if getattr(args, name) is not None:
            label = f"--{name.replace('_', '-')}"
            outputs[label] = check_output_path(getattr(args, name), label, suffixes)
    responses = [args.radar] if args.radar is not None else list(args.measured)
    inputs = responses + ([args.ckpt] if args.ckpt is not None else [])  # the default model is no user path
    seen: dict[Path, str] = {Path(p).resolve(): "an input" for p in inputs}
    for label, path in outputs.items():
        other = seen.setdefault(path.resolve(), label)
        if other != label:
            raise UserInputError(f"{label}: {path} is also {other}; expected a separate output file")
    for path in responses:
        check_input_file(path, "--radar" if args.radar is not None else "--measured", "a radar response file")
    return list(outputs.values())


def _check_options(args: argparse.Namespace, model, profile: bool) -> None:
    """The options against the loaded model, and the memory its meshing needs."""
    if profile:
        unused = [f"--{n}" for n in ("steps", "resolution", "spread", "candidates") if getattr(args, n) is not None]
        if args.samples is not None and "num_samples" not in model.hparams:
            unused.append("--samples")
        if unused:
            raise UserInputError(f"{', '.join(unused)}: not used by {type(model).__name__} (a profile model)")
        return
    if args.steps is not None and args.steps > model.hparams.num_steps:
        raise UserInputError(f"--steps: at most the model's {model.hparams.num_steps} steps, got {args.steps}")
    resolution = int(args.resolution or model.hparams.get("mesh_resolution", 128))
    check_memory(resolution**3 * BYTES_PER_GRID_CELL, f"--resolution {resolution} (a {resolution}^3 marching-cubes "
                 "grid)", args.memory_limit_gb)


def check_not_empty(grid: GridInput, spec: RadarSpec, name: str) -> None:
    """Refuse a response whose every observed cell is at the dB floor: the model would see no measurement."""
    values = grid.db[np.isfinite(grid.db)]
    if values.size and np.all(values <= spec.floor_db):
        raise UserInputError(f"{name}: every cell is at or below the model's dB floor ({spec.floor_db:g} dBsm): "
                             "no measurement (an all-zero response?); pass --allow-empty to reconstruct anyway")


def load_candidate_verifier(args: argparse.Namespace, checkpoint: Path, model):
    """The verifier for ``--candidates``: ``--verifier``, else the one beside the checkpoint."""
    from radar2shape.models.verifier import default_verifier_path, load_verifier

    path = args.verifier or default_verifier_path(checkpoint)
    if not path.is_file():
        where = "--verifier" if args.verifier else f"no verifier beside {checkpoint.name}: expected"
        raise UserInputError(f"{where} {path} (scripts/train_verifier.py trains one for a model); "
                             "leave out --candidates to reconstruct without one")
    return load_verifier(path, model.n_levels, args.candidates)


def _checkpoint_path(ckpt: Path | None, name: str | None) -> Path:
    """``--ckpt`` when given; else shipped model ``name`` (default :data:`DEFAULT_NAME`), named on stdout."""
    if ckpt is not None:
        return ckpt
    from radar2shape.pretrained import shipped_checkpoint

    name = name or DEFAULT_NAME
    path = shipped_checkpoint(name)
    print(f"model: {name} ({path}, shipped with radar2shape; --about {name} describes it, --ckpt uses another)")
    return path


def main(args: argparse.Namespace) -> int:
    outputs = _check_arguments(args)
    memory_limit_bytes(args.memory_limit_gb)  # a bad limit is refused before the model loads
    checkpoint = _checkpoint_path(args.ckpt, args.model)
    model = load_model(checkpoint)
    spec = model.radar_spec
    profile = is_profile_model(model)
    _check_options(args, model, profile)
    verifier = load_candidate_verifier(args, checkpoint, model) if args.candidates else None
    paths, fmt = ([args.radar], "npz") if args.radar is not None else (args.measured, args.format)
    grid = measured_input(paths, fmt, spec, args.roll_symmetric, args.calibration_db, args.size_m, args.min_overlap)
    name = paths[0].name
    if not args.allow_empty:
        check_not_empty(grid, spec, str(paths[0]))
    print(f"input {name}: {int(grid.mask.sum())} of {grid.mask.size} aspect x roll cells observed, "
          f"{int(grid.freq_mask.sum())} of {len(grid.freq_mask)} frequencies in band ({100 * grid.overlap:.0f} % overlap)")

    start = time.perf_counter()
    if verifier is not None:
        keep = args.keep or min(KEEP, args.candidates)
        recon, spread, kept, predicted = reconstruct_best_candidate(model, verifier, grid, args.candidates, keep,
                                                                    args.steps, args.resolution, args.seed)
    else:
        recon, spread = reconstruct_input(model, grid, args.samples, args.steps, args.resolution, args.seed)
    seconds = time.perf_counter() - start
    mesh = recon.mesh
    if mesh is None or len(mesh.faces) == 0:
        print(f"error: the reconstruction of {name} is empty (no surface); nothing written", file=sys.stderr)
        return 1
    written = [args.out]
    with atomic_paths(*outputs) as temps:  # every output, or none
        temp = dict(zip(outputs, temps))
        mesh.export(temp[outputs[0]], file_type=args.out.suffix.lower().lstrip("."))
        if args.save_input:
            np.savez(temp[outputs[1]], db=grid.db, mask=grid.mask, freq_mask=grid.freq_mask,
                     radar=spec.normalise(grid.db, grid.mask), aspect_rad=spec.grid.aspect_rad,
                     roll_rad=spec.grid.roll_rad, freq_hz=spec.grid.freq_hz)
            written.append(args.save_input)
        if args.spread:
            np.save(temp[outputs[len(written)]], spread)
            written.append(args.spread)
        if args.png:
            save_png(temp[outputs[len(written)]], grid.db, spec, mesh, f"{name} -> {args.out.name}")
            written.append(args.png)
    detail = f"{len(mesh.vertices)} vertices, {len(mesh.faces)} faces, {seconds:.2f} s"
    if spread is not None:
        count = args.candidates or args.samples or model.hparams.num_samples
        detail += (f", {count} {'candidate' if verifier is not None else 'sample'}(s); SDF spread over them mean "
                   f"{spread.mean():.4f}, max {spread.max():.4f}")
    print(f"wrote {args.out}: {detail}")
    if verifier is not None:
        which = (f"candidate {kept[0] + 1}" if len(kept) == 1 else
                 f"the mean of candidates {', '.join(str(i + 1) for i in kept)} (its best {len(kept)})")
        print(f"verifier: returned {which} of {args.candidates}, predicted IoU {recon.predicted_iou:.2f} "
              f"(candidates {predicted.min():.2f} to {predicted.max():.2f}; docs/metrics.md)")
    if not profile:
        from radar2shape.metrics.consistency import radar_consistency

        residual = radar_consistency(mesh, grid.db, grid.mask, spec)
        print(f"radar consistency: {residual:.3f} (the reconstruction's PO radar against the input over the observed "
              "cells, relative residual in power after one gain: 0 = explains it, 1 = not at all; docs/metrics.md)")
    print("frame: the body frame of the radar (z up: aspect from +z, roll about z from +x), normalised to the "
          "unit cube (longest side 1, centred); scale by the object's size to compare with a mesh in metres")
    for path in written[1:]:
        print(f"wrote {path}")
    return 0
