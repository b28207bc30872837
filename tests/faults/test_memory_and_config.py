"""Out-of-range build options and meshes too large for memory are refused before any work: one
``error:`` line naming the key (or the GiB needed and the limit), exit code 2, no output folder."""

from __future__ import annotations

import time

import numpy as np
import pytest

from fault_helpers import TINY_YAML
from radar2shape.cli import main

OPTIONS = {  # case -> (replacement of the tiny config's text, words the error line must hold)
    "sbr-bounces-negative": ("seed: 0", "seed: 0\nsimulator: {method: sbr, max_bounces: -1}", "simulator.max_bounces"),
    "po-bounces-negative": ("seed: 0", "seed: 0\nsimulator: {max_bounces: -3}", "simulator.max_bounces"),
    "rays-zero": ("seed: 0", "seed: 0\nsimulator: {method: sbr, rays_per_wavelength: 0}", "simulator.rays_per_wavelength"),
    "edge-threshold": ("seed: 0", "seed: 0\nsimulator: {method: po+ec, edge_threshold_deg: 200}",
                       "simulator.edge_threshold_deg"),
    "polarization": ("seed: 0", "seed: 0\nsimulator: {polarization: XX}", "simulator.polarization"),
    "freq-negative": ("start: 8.0", "start: -8.0", "freq_hz"),
    "freq-count-zero": ("count: 16", "count: 0", "freq_ghz.count"),
    "aspect-range": ("stop: 180.0", "stop: 270.0", "aspect_rad"),
    "size-zero": ("size_m: 1.0", "size_m: 0.0", "size_m"),
    "face-budget": ("face_budget: 1000", "face_budget: 0", "mesh.face_budget"),
    "occ-negative": ("occ: 1024", "occ: -1", "sampling.occ"),
    "floor-nan": ("seed: 0", "seed: 0\nfloor_db: .nan", "floor_db"),
}


@pytest.mark.parametrize("old, new, words", list(OPTIONS.values()), ids=list(OPTIONS))
def test_out_of_range_options_are_refused_before_anything_is_written(old, new, words, tmp_path, capsys):
    config = tmp_path / "bad.yaml"
    text = TINY_YAML.replace(old, new, 1)
    assert text != TINY_YAML
    config.write_text(text)
    assert main(["build-data", "--config", str(config), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.splitlines()) == 1
    assert captured.err.startswith("error: ") and words in captured.err, captured.err
    assert not (tmp_path / "out").exists()


def test_build_memory_over_the_limit_is_refused_naming_the_workers(tmp_path, capsys):
    config = tmp_path / "tiny.yaml"
    config.write_text(TINY_YAML.replace("face_budget: 1000", "face_budget: 2000000"))
    argv = ["build-data", "--config", str(config), "--out", str(tmp_path / "out"), "--workers", "4",
            "--memory-limit-gb", "8"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    # 4 x (2e6 faces x 2048 B + 1024 cells x 48 B + 3072 points x 256 B + 32^3 voxels x 32 B) = 15.3 GiB
    assert err == ("error: build-data with 4 worker(s) (each: a 2000000-face mesh from mesh.face_budget, a 8 x 8 x 16 "
                   "radar grid, 3072 sample points, a 32^3 remesh grid) needs about 15.3 GiB of memory, over the limit "
                   "of 8.0 GiB (--memory-limit-gb); reduce the size or raise --memory-limit-gb\n")
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def big_mesh(tmp_path_factory):
    """A real 2,097,152-face binary STL (a folded strip of triangles), written without trimesh."""
    path = tmp_path_factory.mktemp("big") / "big.stl"
    n = 2**21
    records = np.zeros(n, dtype=[("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    i = np.arange(n, dtype=np.float32)
    records["v"][:, 0] = np.stack([i, np.zeros(n), np.zeros(n)], 1) / n
    records["v"][:, 1] = np.stack([i + 1, np.zeros(n), np.ones(n)], 1) / n
    records["v"][:, 2] = np.stack([i, np.ones(n), np.zeros(n)], 1) / n
    records["normal"] = (0.0, 0.0, 1.0)
    with open(path, "wb") as handle:
        handle.write(b"radar2shape test mesh".ljust(80, b" ") + np.uint32(n).tobytes())
        records.tofile(handle)
    return path


def test_simulate_refuses_a_two_million_face_mesh_at_once(big_mesh, tmp_path, capsys):
    out = tmp_path / "r.npz"
    start = time.perf_counter()
    code = main(["simulate", str(big_mesh), "--out", str(out), "--aspect-deg", "0:180:4", "--roll-deg", "0:90:2",
                 "--freq-ghz", "8:12:4", "--memory-limit-gb", "2"])
    seconds = time.perf_counter() - start
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1
    assert err.startswith(f"error: {big_mesh}: a mesh of 2097152 faces with a response of 4 x 2 x 4 ")
    assert "needs about 4.0 GiB of memory, over the limit of 2.0 GiB (--memory-limit-gb)" in err, err
    assert seconds < 5 and not out.exists()  # from the header: the 100 MB file is never parsed


def test_evaluate_refuses_a_two_million_face_ground_truth_at_once(big_mesh, tmp_path, capsys):
    import trimesh

    pred = tmp_path / "pred.ply"
    trimesh.creation.icosphere(2, 0.4).export(pred)
    start = time.perf_counter()
    code = main(["evaluate", str(pred), str(big_mesh), "--memory-limit-gb", "2"])
    seconds = time.perf_counter() - start
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1
    assert f"{big_mesh} (2097152 faces)" in err and "over the limit of 2.0 GiB" in err, err
    assert seconds < 5
