"""Benchmark: training shapes/s per model, reference kernels against the current (fast) path, in one run.

    python bench/train_throughput.py [--models stage1 stage2 tmnet list] [--threads 2] [--bf16] [--device cuda]

One step = the model's training losses, backward, the model's own optimizer (``configure_optimizers``)
on a synthetic batch at the medium configs (batch 16, 2,048 surface + 4,096 SDF points per shape,
radar 32 x 32 x 64): timing needs no dataset, and data loading is measured in bench/profile_steps.py.
Both paths start from the same weights and batch; the reference path is
``radar2shape.nn.kernels.reference_path()`` (the ops before the fast forms, the per-parameter
optimizer). ``--bf16`` adds the opt-in bfloat16 autocast path (on a GPU: ``torch.autocast`` in bfloat16, what the
trainer's ``precision: bf16-mixed`` runs). ``--device cuda`` times on the GPU (synchronised; the
CPU-second column is then the host's time). The paths take turns for
``--rounds`` rounds and each keeps its best round: on a shared, oversubscribed machine a round's
time depends on what else ran then far more than on the path. Prints shapes/s by wall clock and
per CPU-second (process time) and the ratios; docs/throughput.md.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

import radar2shape  # noqa: E402,F401  (before torch: the package's OpenMP settings apply, as in a fit)
import torch  # noqa: E402
import yaml  # noqa: E402

from radar2shape.nn import kernels  # noqa: E402

CONF = REPO / "conf/model"
BATCH = 16
STEPS = {"stage1": 1, "stage2": 2, "tmnet": 1, "list": 1, "profile_unet": 5, "invrt": 5}


def _config(name: str) -> dict:
    return yaml.safe_load((CONF / name).read_text())


def _radar_batch(batch: int, gen: torch.Generator, num_freq: int = 64, surface: int = 2048, sdf: int = 4096) -> dict:
    radar = {"radar": torch.randn(batch, 32, 32, num_freq, generator=gen),
             "radar_mask": torch.ones(batch, 32, 32, dtype=torch.bool)}
    radius = 0.15 + 0.3 * torch.rand(batch, 1, 1, generator=gen)
    surface = torch.nn.functional.normalize(torch.randn(batch, surface, 3, generator=gen), dim=-1)
    queries = torch.rand(batch, sdf, 3, generator=gen) * 1.1 - 0.55
    return {**radar, "surface_points": surface * radius, "surface_normals": surface,
            "sdf_points": queries, "sdf_values": queries.norm(dim=-1) - radius[..., 0], "index": torch.arange(batch)}


def build(name: str, batch: int = BATCH, model_args: dict | None = None, points: dict | None = None
          ) -> tuple[torch.nn.Module, dict]:
    """A freshly initialised (seed 0) training-mode model at its medium config and a synthetic batch.

    ``model_args`` override the model file's ``init_args``; ``points`` (``surface``, ``sdf``) the
    batch's points per shape (default: the medium DataModule's 2,048 / 4,096)."""
    from lightning.pytorch.cli import instantiate_class

    torch.manual_seed(0)
    gen = torch.Generator().manual_seed(1)
    model_args, sizes = model_args or {}, {"surface": 2048, "sdf": 4096, **(points or {})}
    if name == "stage1":
        from radar2shape.models.sdf_vae import SDFVAE

        hparams = {**_config("sdf_vae_medium.yaml")["init_args"], **model_args}
        return SDFVAE(**hparams).train(), _radar_batch(batch, gen, **sizes)
    if name == "stage2":
        from radar2shape.models.radar_diffusion import RadarDiffusion

        stage2 = {k: v for k, v in _config("radar_diffusion_medium.yaml")["init_args"].items() if k != "stage1_ckpt"}
        model = RadarDiffusion(stage1_hparams=_config("sdf_vae_medium.yaml")["init_args"], **{**stage2, **model_args}).train()
        data = _radar_batch(batch, gen, **sizes)
        with torch.no_grad():  # training reads the latents cached at fit start
            model._train_latents = dict(enumerate(model.stage1.encode(data["surface_points"])[0]))
            model.standardiser.fit(torch.stack(list(model._train_latents.values())))
        return model, data
    if name in ("tmnet", "list"):
        return instantiate_class((), _config(f"{name}_medium.yaml")).train(), _radar_batch(batch, gen)
    if name in ("profile_unet", "invrt"):  # roll-symmetric: radar [B, A, F] and (r, z) profiles
        model = instantiate_class((), _config(f"{name}_medium.yaml")).train()
        z = torch.linspace(-0.5, 0.5, int(model.hparams.profile_points))
        r = 0.1 + 0.3 * torch.rand(batch, 1, generator=gen) * (1 - z.square() * 3)
        profile = torch.stack([r.clamp(min=0.02), z.expand(batch, -1)], dim=-1)
        profile[:, 0, 0] = profile[:, -1, 0] = 0.0
        radar = torch.randn(batch, int(model.hparams.num_aspect), int(model.hparams.num_freq), generator=gen)
        return model, {"radar": radar, "radar_mask": torch.ones(radar.shape[:2], dtype=torch.bool), "profile": profile}
    raise ValueError(f"unknown model {name!r}")


def optimizer_of(model: torch.nn.Module) -> torch.optim.Optimizer:
    """The model's own optimizer (what ``configure_optimizers`` gives under the current kernel switch)."""
    configured = model.configure_optimizers()
    return configured["optimizer"] if isinstance(configured, dict) else configured


def autocast(device: torch.device) -> contextlib.AbstractContextManager:
    """The model's CPU autocast switch; on a GPU, Lightning's bf16-mixed autocast when the bf16 path is on."""
    if device.type == "cpu":
        return kernels.training_autocast("cpu")
    return torch.autocast(device.type, dtype=torch.bfloat16, enabled=kernels.bf16_training())


def training_step(model: torch.nn.Module, optimizer: torch.optim.Optimizer, batch: dict) -> float:
    """One step as ``ReconstructionModel.training_step`` runs it, less Lightning's logging."""
    with autocast(model.device):
        loss = model.losses(batch)["loss"]
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    optimizer.step()
    return float(loss.detach())


class Runner:
    """A copy of ``model`` with its own optimizer under one path, warmed up by one step."""

    def __init__(self, model: torch.nn.Module, batch: dict, name: str) -> None:
        self.model, self.batch, self.name = copy.deepcopy(model), batch, name
        with path(name):
            self.optimizer = optimizer_of(self.model)
            training_step(self.model, self.optimizer, batch)

    def time(self, steps: int) -> tuple[float, float]:
        """(wall, CPU) seconds per step over ``steps`` steps."""
        with path(self.name):
            synchronise(self.model.device)
            wall, cpu = time.perf_counter(), time.process_time()
            for _ in range(steps):
                training_step(self.model, self.optimizer, self.batch)
            synchronise(self.model.device)
            return (time.perf_counter() - wall) / steps, (time.process_time() - cpu) / steps


def synchronise(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def to_device(model: torch.nn.Module, batch: dict, device: torch.device) -> tuple[torch.nn.Module, dict]:
    """Model and batch on ``device`` (Stage 2's cached latents too, as Lightning's fit moves them)."""
    model = model.to(device)
    if hasattr(model, "_train_latents"):
        model._train_latents = {k: v.to(device) for k, v in model._train_latents.items()}
    return model, {k: v.to(device) for k, v in batch.items()}


@contextlib.contextmanager
def path(name: str):
    """``reference``, ``fast`` or ``bf16`` (fast + bfloat16 autocast) for the enclosed code."""
    with kernels.reference_path(name == "reference"):
        kernels.set_bf16_training(name == "bf16")
        try:
            yield
        finally:
            kernels.set_bf16_training(False)


GRID_RUNS = {"stage1": "radar2shape_stage1", "stage2": "radar2shape-full-seed0"}  # the run each stage repeats


def grid_settings(grid: str, name: str) -> dict:
    """What ``grid``'s run of stage ``name`` trains with: ``model_args`` (its ``model.init_args``
    overrides), ``points`` (its training points per shape), ``bf16`` (the cpu_bf16 layer) and ``batch``."""
    from radar2shape.sweep import load_grid

    run = next(r for r in load_grid(grid).runs if r.name == GRID_RUNS[name])
    prefix = "model.init_args."
    model_args = {k.removeprefix(prefix): v for k, v in run.overrides.items()
                  if k.startswith(prefix) and k != prefix + "stage1_ckpt"}
    bf16 = "conf/trainer/cpu_bf16.yaml" in run.configs or run.overrides.get("trainer.precision") == "bf16-mixed"
    return {"model_args": model_args, "points": run.overrides.get("data.init_args.points.train"), "bf16": bf16,
            "batch": int(run.overrides.get("data.init_args.batch_size", BATCH))}


def compare_grids(names: list[str], grids: list[str], device: torch.device, rounds: int, steps: int) -> None:
    """Shapes/s of each stage as ``grids[0]`` trains it (reference kernels: the committed rows) against
    ``grids[1]`` (current kernels, its points, model options, precision and batch), in one run."""
    print(f"grid settings: {grids[0]} (reference kernels) against {grids[1]} (shapes/s: wall | per CPU-second)")
    for name in [n for n in names if n in GRID_RUNS]:
        runners, batches = [], []
        for grid, kernel_path in zip(grids, ("reference", "fast")):
            settings = grid_settings(grid, name)
            model, batch = to_device(*build(name, batch=settings["batch"], model_args=settings["model_args"],
                                            points=settings["points"]), device)
            runners.append(Runner(model, batch, "bf16" if settings["bf16"] else kernel_path))
            batches.append(settings["batch"])
        timed = [[r.time(steps or STEPS[name]) for r in runners] for _ in range(rounds)]
        (ref_wall, ref_cpu), (new_wall, new_cpu) = (tuple(min(rnd[i][k] for rnd in timed) for k in (0, 1)) for i in (0, 1))
        ref_wall, ref_cpu, new_wall, new_cpu = (ref_wall / batches[0], ref_cpu / batches[0],
                                                new_wall / batches[1], new_cpu / batches[1])  # seconds per shape
        print(f"  {name:8s} {grids[0]} {1 / ref_wall:6.1f} | {1 / ref_cpu:6.1f}   {grids[1]} "
              f"{1 / new_wall:6.1f} | {1 / new_cpu:6.1f}   x{ref_wall / new_wall:.2f} wall, x{ref_cpu / new_cpu:.2f} CPU",
              flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=["stage1", "stage2", "tmnet", "list"], choices=sorted(STEPS))
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--steps", type=int, default=0, help="timed steps per path (0: a per-model default)")
    parser.add_argument("--rounds", type=int, default=2, help="rounds in which the paths take turns")
    parser.add_argument("--bf16", action="store_true", help="also time the opt-in bfloat16 autocast path")
    parser.add_argument("--device", default="cpu", help="cpu (default) or cuda")
    parser.add_argument("--grids", nargs=2, default=["table1-medium", "table1-medium-faster"], metavar=("REF", "NEW"),
                        help="also time Stage 1 and 2 as these two grids train them ('' '': skip)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    device = torch.device(args.device)
    bf16 = args.bf16 and (device.type != "cpu" or kernels.cpu_has_bf16())
    paths = ["reference", "fast"] + (["bf16"] if bf16 else [])
    where = torch.cuda.get_device_name(device) if device.type == "cuda" else f"{torch.get_num_threads()} threads"
    print(f"training throughput, batch {BATCH}, medium configs, {where}, best of "
          f"{args.rounds} rounds (shapes/s: wall | per CPU-second; ratio = path / reference)")
    for name in args.models:
        model, batch = to_device(*build(name), device)
        steps = args.steps or STEPS[name] * (10 if device.type == "cuda" else 1)
        runners = [Runner(model, batch, p) for p in paths]
        rounds = [[r.time(steps) for r in runners] for _ in range(args.rounds)]
        times = {p: tuple(min(rnd[i][k] for rnd in rounds) for k in (0, 1)) for i, p in enumerate(paths)}
        cells = []
        for p in paths:
            wall, cpu = times[p]
            cells.append(f"{p} {BATCH / wall:6.1f} | {BATCH / cpu:6.1f}")
        ratios = [f"{p} x{times['reference'][0] / times[p][0]:.2f} wall, x{times['reference'][1] / times[p][1]:.2f} CPU"
                  for p in paths[1:]]
        print(f"  {name:8s} " + "   ".join(cells) + "   " + "; ".join(ratios), flush=True)
    if all(args.grids):
        compare_grids(args.models, args.grids, device, args.rounds, args.steps)


if __name__ == "__main__":
    main()
