"""``radar2shape reconstruct --ckpt CKPT --radar FILE.npz --out OUT.obj``: a mesh from a radar response.

FILE.npz is what ``radar2shape simulate`` writes (``response`` complex [A, R, F] and the axes
``aspect_rad``, ``roll_rad``, ``freq_hz``). The checkpoint (a trained :class:`RadarDiffusion`)
stores the radar grid and dB statistics of its training data; a response on another grid is
resampled to it when the file covers it: linear interpolation of the dB image (not of the
complex field, whose phase turns too fast to interpolate) along each axis, roll wrapping
around when the file covers the full circle. ``--roll-symmetric`` repeats a single-roll
(aspect-only) response along roll, as the paper does with measured data.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from radar2shape.errors import UserInputError
from radar2shape.radar import RadarResponse, load_response, to_db

TWO_PI = 2.0 * np.pi


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--ckpt", required=True, type=Path, help="RadarDiffusion checkpoint (.ckpt)")
    parser.add_argument("--radar", required=True, type=Path, help="response .npz as written by 'radar2shape simulate'")
    parser.add_argument("--out", required=True, type=Path, help="output mesh (.obj, or any suffix trimesh writes)")
    parser.add_argument("--samples", type=int, help="K sampled shapes; the mesh is their mean SDF (default: model's)")
    parser.add_argument("--steps", type=int, help="DDIM steps (default: the model's)")
    parser.add_argument("--resolution", type=int, help="marching-cubes grid size (default: the model's)")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    parser.add_argument("--png", type=Path, help="also write a PNG: input dB image and the reconstruction")
    parser.add_argument("--spread", type=Path, help="also write the per-vertex SDF std over the K samples (.npy)")
    parser.add_argument("--roll-symmetric", action="store_true", help="repeat a single-roll response along roll")


def load_model(path: Path):
    """The :class:`RadarDiffusion` in ``path`` on the CPU, in eval mode, with its radar metadata."""
    from radar2shape.models.radar_diffusion import RadarDiffusion

    if not path.is_file():
        raise UserInputError(f"--ckpt: {path} not found")
    try:
        model = RadarDiffusion.load_from_checkpoint(path, map_location="cpu", weights_only=True)
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        message = f"--ckpt: {path} is not a RadarDiffusion checkpoint ({type(err).__name__}: {err})"
        raise UserInputError(message) from err
    if not model.hparams.get("radar_meta"):
        raise UserInputError(f"--ckpt: {path} stores no radar grid (the model was not fitted on a radar DataModule)")
    return model.eval()


def _axis_range(values: np.ndarray, unit: float, name: str) -> str:
    return f"{name} [{values.min() / unit:.6g}, {values.max() / unit:.6g}]"


def resample_axis(values: np.ndarray, source: np.ndarray, target: np.ndarray, axis: int, name: str,
                  unit: float, unit_name: str, periodic: bool = False) -> np.ndarray:
    """Linear interpolation of ``values`` along ``axis`` from ``source`` to ``target`` coordinates.

    ``periodic`` (roll): coordinates are angles and the source covers the full circle, so the
    target may fall anywhere on it. Otherwise every target value must lie within the source range.
    """
    source, target = np.asarray(source, float), np.asarray(target, float)
    tol = 1e-6 * max(float(np.ptp(source)), float(np.abs(source).max()), 1e-9)
    if len(source) == len(target) and np.allclose(source, target, rtol=0, atol=tol):
        return values
    if periodic:  # one period of padding on both sides; 0 and 2 pi count as one sample
        source, first = np.unique(np.mod(source, TWO_PI), return_index=True)
        values = np.take(values, first, axis=axis)
        source = np.concatenate([source[-1:] - TWO_PI, source, source[:1] + TWO_PI])
        values = np.concatenate([np.take(values, [-1], axis), values, np.take(values, [0], axis)], axis=axis)
        target = np.mod(target, TWO_PI)
    else:
        order = np.argsort(source)
        source, values = source[order], np.take(values, order, axis=axis)
        if np.any(np.diff(source) <= tol):
            raise UserInputError(f"--radar: the {name} axis repeats a value; expected distinct samples")
        if target.min() < source[0] - tol or target.max() > source[-1] + tol:
            raise UserInputError(
                f"--radar: {_axis_range(source, unit, name)} {unit_name} does not cover the model's "
                f"{_axis_range(target, unit, name)} {unit_name}"
            )
    if len(source) == 1:
        return np.repeat(values, len(target), axis=axis)
    moved = np.moveaxis(values, axis, -1)
    position = np.clip(np.searchsorted(source, target, side="right") - 1, 0, len(source) - 2)
    weight = np.clip((target - source[position]) / (source[position + 1] - source[position]), 0.0, 1.0)
    out = moved[..., position] * (1 - weight) + moved[..., position + 1] * weight
    return np.moveaxis(out, -1, axis)


def full_circle(roll: np.ndarray) -> bool:
    """True when the roll samples go round the circle: no gap (the seam included) above 1.5x the median gap."""
    angles = np.unique(np.mod(np.asarray(roll, float), TWO_PI))
    if len(angles) < 3:
        return False
    gaps = np.diff(np.append(angles, angles[0] + TWO_PI))
    return bool(gaps.max() <= 1.5 * np.median(gaps))


def radar_on_model_grid(response: RadarResponse, meta: dict, roll_symmetric: bool = False) -> np.ndarray:
    """The response's dB image ``[A, R, F]`` on the model's grid (see the module docstring)."""
    db = to_db(response.response, meta["floor_db"])
    aspect, roll, freq = (np.asarray(meta[k], float) for k in ("aspect_rad", "roll_rad", "freq_hz"))
    source_roll = response.roll_rad
    if roll_symmetric:
        if db.shape[1] != 1:
            raise UserInputError(f"--roll-symmetric: expects a single-roll response, got {db.shape[1]} roll angles")
        db, source_roll = np.repeat(db, len(roll), axis=1), roll
    elif len(source_roll) == 1 and len(roll) > 1:
        raise UserInputError(
            f"--radar: one roll angle but the model needs {len(roll)}; for a roll-symmetric object add --roll-symmetric"
        )
    db = resample_axis(db, response.aspect_rad, aspect, 0, "aspect", np.pi / 180, "deg")
    db = resample_axis(db, source_roll, roll, 1, "roll", np.pi / 180, "deg", periodic=full_circle(source_roll))
    return resample_axis(db, response.freq_hz, freq, 2, "frequency", 1e9, "GHz")


def save_png(path: Path, db: np.ndarray, meta: dict, mesh, title: str) -> None:
    """Input dB image (mean power over frequency, aspect x roll) beside two views of the mesh."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from radar2shape.geometry.query import sample_surface
    from radar2shape.metrics.render import VIEWS, depth_image

    points = sample_surface(mesh, 20_000, 0)[0] if len(mesh.faces) else np.zeros((0, 3))
    power_db = 10 * np.log10(np.mean(10 ** (db / 10), axis=-1))
    roll, aspect = np.degrees(meta["roll_rad"]), np.degrees(meta["aspect_rad"])
    fig = Figure(figsize=(3.4 * (1 + len(VIEWS)), 3.4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 1 + len(VIEWS))
    image = axes[0].imshow(power_db, aspect="auto", cmap="viridis", extent=(roll[0], roll[-1], aspect[-1], aspect[0]))
    axes[0].set(title="input (mean over frequency)", xlabel="roll (deg)", ylabel="aspect (deg)")
    fig.colorbar(image, ax=axes[0], label="dBsm")
    for ax, (azimuth, elevation) in zip(axes[1:], VIEWS):
        ax.imshow(depth_image(points, azimuth, elevation), cmap="viridis", vmin=-0.6, vmax=0.6)
        ax.set(title=f"reconstruction ({azimuth:g}, {elevation:g} deg)", xticks=[], yticks=[])
    fig.suptitle(title, fontsize=9)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)


def main(args: argparse.Namespace) -> int:
    for name in ("samples", "steps", "resolution"):
        value = getattr(args, name)
        if value is not None and value < (2 if name == "resolution" else 1):
            raise UserInputError(f"--{name}: expected a positive integer, got {value}")
    model = load_model(args.ckpt)
    meta = model.hparams.radar_meta
    if args.steps is not None and args.steps > model.hparams.num_steps:
        raise UserInputError(f"--steps: at most the model's {model.hparams.num_steps} steps, got {args.steps}")
    db = radar_on_model_grid(load_response(args.radar), meta, args.roll_symmetric)
    radar = torch.from_numpy(((db - meta["db_mean"]) / meta["db_std"]).astype(np.float32))[None]
    batch = {"radar": radar, "radar_mask": torch.ones(radar.shape[:3], dtype=torch.bool)}

    start = time.perf_counter()
    (recon, spread), = model.reconstruct_with_uncertainty(batch, args.samples, args.steps, args.resolution, args.seed)
    seconds = time.perf_counter() - start
    mesh = recon.mesh
    if len(mesh.faces) == 0:
        print(f"error: the reconstruction of {args.radar} is empty (the decoded SDF has no zero crossing)")
        return 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(args.out)
    samples = args.samples or model.hparams.samples
    print(f"wrote {args.out}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces, {samples} sample(s), "
          f"{seconds:.2f} s; SDF spread over samples mean {spread.mean():.4f}, max {spread.max():.4f}")
    if args.spread:
        np.save(args.spread, spread)
        print(f"wrote {args.spread}")
    if args.png:
        save_png(args.png, db, meta, mesh, f"{args.radar.name} -> {args.out.name}")
        print(f"wrote {args.png}")
    return 0
