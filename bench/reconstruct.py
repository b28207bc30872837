"""Benchmark: seconds per reconstruction (radar -> mesh) of Radar2Shape Stage 2 on the CPU.

    python bench/reconstruct.py [--ckpt RUN/checkpoints/last.ckpt] [--steps 50] [--resolution 64]

One radar input, one sample, DDIM with ``--steps`` steps, marching cubes on a ``--resolution``^3
grid: the path ``radar2shape reconstruct`` and the metric callback run. Without ``--ckpt`` the
models are built from conf/model/sdf_vae_cpu.yaml and conf/model/radar_diffusion_cpu.yaml, with
Stage 1 fitted to a sphere for 100 steps so marching cubes meets a real surface (the time of
sampling does not depend on the weights). Target: < 2 s per reconstruction on 2 cores.
``--candidates K`` also times ``reconstruct --candidates K`` (K samples, the verifier's features and
scores, the mesh of the mean SDF of its best three) against one sample in the same run, with the checkpoint's verifier
(``<name>.verifier.pt``) or, without one, an untrained verifier (the time does not depend on it).
Target: < 5 s on 2 cores.
Prints the split between sampling (Transformer steps) and decoding + marching cubes, and the CPU
seconds, which stay meaningful on a shared machine (there, `--threads 1` avoids two threads
thrashing against other jobs).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

import lightning as L  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
import yaml  # noqa: E402

from radar2shape.models.radar_diffusion import RadarDiffusion  # noqa: E402
from radar2shape.models.sdf_vae import SDFVAE  # noqa: E402


def init_args(name: str) -> dict:
    return yaml.safe_load((REPO / "conf/model" / name).read_text())["init_args"]


def cpu_config_model(folder: Path) -> RadarDiffusion:
    """The CPU-config Stage 1 (fitted to a sphere of radius 0.3 for 100 steps) and Stage 2."""
    torch.manual_seed(0)
    stage1 = SDFVAE(**init_args("sdf_vae_cpu.yaml"))
    optimizer = torch.optim.Adam(stage1.parameters(), lr=3e-3)
    surface = torch.randn(1, 1024, 3)
    queries = torch.rand(1, 2048, 3) * 1.1 - 0.55
    batch = {"surface_points": 0.3 * surface / surface.norm(dim=-1, keepdim=True), "sdf_points": queries,
             "sdf_values": queries.norm(dim=-1) - 0.3}
    for _ in range(100):
        optimizer.zero_grad()
        stage1.losses(batch)["loss"].backward()
        optimizer.step()
    path = folder / "stage1.ckpt"
    torch.save({"state_dict": stage1.state_dict(), "hyper_parameters": dict(stage1.hparams),
                "pytorch-lightning_version": L.__version__}, path)
    model = RadarDiffusion(**{**init_args("radar_diffusion_cpu.yaml"), "stage1_ckpt": str(path)})
    model.standardiser.fit(stage1.eval().encode(batch["surface_points"])[0])
    return model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", help="a RadarDiffusion checkpoint (default: the CPU configs, untrained Stage 2)")
    parser.add_argument("--steps", type=int, default=50, help="DDIM steps (default 50)")
    parser.add_argument("--resolution", type=int, default=64, help="marching-cubes grid (default 64)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--candidates", type=int, help="also time the verifier's pick of K samples")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    with tempfile.TemporaryDirectory() as folder:
        if args.ckpt:
            from radar2shape.pretrained import load_model

            model = load_model(args.ckpt)
        else:
            model = cpu_config_model(Path(folder))
    model.eval()
    a, r = 16, 16
    batch = {"radar": torch.randn(1, a, r, model.hparams.num_freq), "radar_mask": torch.ones(1, a, r, dtype=torch.bool)}
    model.reconstruct_with_uncertainty(batch, num_samples=1, steps=args.steps, resolution=16)  # warm-up
    sample_s, total_s, cpu_s, faces = [], [], [], 0
    for _ in range(args.repeats):
        start, cpu_start = time.perf_counter(), time.process_time()
        latents = model.sample_latents(batch, num_samples=1, steps=args.steps)
        sampled = time.perf_counter()
        mesh, _ = model.mean_mesh(latents[0], args.resolution)
        total_s.append(time.perf_counter() - start)
        sample_s.append(sampled - start)
        cpu_s.append(time.process_time() - cpu_start)
        faces = len(mesh.faces)
    best = min(range(args.repeats), key=total_s.__getitem__)
    verdict = "meets" if total_s[best] < 2.0 else "misses"
    print(f"reconstruct (DDIM {args.steps} steps, {args.resolution}^3 grid, {torch.get_num_threads()} threads): "
          f"{total_s[best]:.2f} s per reconstruction (best of {args.repeats}; sampling {sample_s[best]:.2f} s, "
          f"decode + marching cubes {total_s[best] - sample_s[best]:.2f} s; {cpu_s[best]:.2f} CPU s; "
          f"{faces} faces) -- {verdict} the 2 s target")
    print(decode_comparison(model, latents[0], args.resolution, args.repeats))
    if args.candidates:
        print(candidate_timing(model, batch, args, total_s[best]))


def candidate_timing(model: RadarDiffusion, batch: dict, args, one_sample_s: float) -> str:
    """Seconds of ``reconstruct --candidates K``: K samples, verifier features and scores, the kept candidates' mesh."""
    from radar2shape.models.verifier import (
        KEEP, Verifier, default_verifier_path, feature_names, load_verifier, verified_latents,
    )

    path = default_verifier_path(Path(args.ckpt)) if args.ckpt else None
    if path is not None and path.is_file():
        verifier, which = load_verifier(path, model.n_levels), path.name
    else:
        verifier, which = Verifier(len(feature_names(model.n_levels))).eval(), "an untrained verifier"
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        keep = min(KEEP, args.candidates)
        latents, _, kept = verified_latents(model, verifier, batch, args.candidates, keep, args.steps)
        model.mean_mesh(latents[kept], args.resolution)
        times.append(time.perf_counter() - start)
    seconds = min(times)
    verdict = "meets" if seconds < 5.0 else "misses"
    return (f"reconstruct --candidates {args.candidates} ({which}, mean of its best {min(KEEP, args.candidates)}): "
            f"{seconds:.2f} s (best of {args.repeats}), "
            f"{seconds / one_sample_s:.1f}x one sample -- {verdict} the 5 s target")


def decode_comparison(model: RadarDiffusion, latents: torch.Tensor, resolution: int, repeats: int) -> str:
    """Decode + marching cubes with the narrow band (the default) against every grid point, same latents."""
    import radar2shape.geometry.marching_cubes as marching_cubes

    narrow = marching_cubes.extract_mesh
    seconds, meshes = {}, {}
    for name, extract in (("narrow band", narrow), ("every point", partial(narrow, narrow_band=False))):
        marching_cubes.extract_mesh = extract  # mean_mesh imports it at call time
        try:
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                meshes[name] = model.mean_mesh(latents, resolution)[0]
                times.append(time.perf_counter() - start)
        finally:
            marching_cubes.extract_mesh = narrow
        seconds[name] = min(times)
    same = np.array_equal(meshes["narrow band"].faces, meshes["every point"].faces)
    return (f"decode + marching cubes: narrow band {seconds['narrow band']:.2f} s, every grid point "
            f"{seconds['every point']:.2f} s ({seconds['every point'] / seconds['narrow band']:.1f}x); "
            f"same faces: {same}")


if __name__ == "__main__":
    main()
