"""Bad input to the tool commands (simulate, evaluate, reconstruct, build-data): one line, exit 2, no files.

Every corpus case runs the console script in-process (``radar2shape.cli.main``) inside a folder
of prepared inputs and asserts: exit code 2, exactly one stderr line that starts with
``error:`` and names the problem, and the folder (names, sizes, modification times) unchanged.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from radar2shape.atomic import atomic_paths, check_output_path, write_text_atomic
from radar2shape.cli import main
from radar2shape.errors import UserInputError
from radar2shape.preflight import GIB, MEMORY_ENV
from radar2shape.radar import save_response
from test_reconstruct_cli import ASPECT, FREQ, ROLL, checkpoint, single_thread  # noqa: F401  (fixtures)

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--aspect-deg", "0:180:3", "--roll-deg", "0:90:2", "--freq-ghz", "8:12:2"]
FAST_EVAL = ["--points", "500", "--occ-points", "2000"]
TINY_CONFIG = (REPO / "conf/data/parts_tiny.yaml").read_text().replace(
    "radar: conf/radar/tiny.yaml", f"radar: {REPO / 'conf/radar/tiny.yaml'}")


def snapshot(root: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``root`` with its size and modification time, and every folder."""
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) if p.is_file() else "folder"
            for p in sorted(root.rglob("*"))}


@pytest.fixture
def world(tmp_path, checkpoint):  # noqa: F811  (the imported module fixture)
    """A folder of good and bad inputs; returns the placeholders the cases use."""
    t = tmp_path
    (t / "out").mkdir()
    (t / "folder.obj").mkdir()
    (t / "afile").write_text("a file, not a folder\n")
    trimesh.creation.box((1.0, 0.5, 0.25)).export(t / "mesh.obj")
    trimesh.creation.icosphere(2, 0.4).export(t / "gt.obj")
    trimesh.creation.icosphere(2, 0.35).export(t / "pred.ply")
    (t / "text.obj").write_text("this is not a mesh\nat all\n")
    (t / "empty.obj").write_text("")
    (t / "notes.txt").write_text("1 2 3\n")
    (t / "garbage.ply").write_bytes(bytes(range(256)) * 4)
    (t / "nan.obj").write_text("v nan 0 0\nv 1 nan 0\nv 0 1 nan\nf 1 2 3\n")
    np.save(t / "flat.npy", np.zeros((10, 2)))
    np.save(t / "objects.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    # checkpoints that are not one
    (t / "text.ckpt").write_text("model weights, honest\n")
    (t / "empty.ckpt").write_bytes(b"")
    (t / "pickle.ckpt").write_bytes(pickle.dumps(argparse.Namespace(weights=[1, 2, 3])))
    torch.save({"weights": torch.zeros(3)}, t / "nokeys.ckpt")
    torch.save([torch.zeros(3)], t / "list.ckpt")
    # radar files on the checkpoint's grid
    rng = np.random.default_rng(0)
    shape = (len(ASPECT), len(ROLL), len(FREQ))
    save_response(t / "radar.npz", (rng.normal(size=shape) + 1j * rng.normal(size=shape)).astype(np.complex64),
                  ASPECT, ROLL, FREQ)
    save_response(t / "zeros.npz", np.zeros(shape, np.complex64), ASPECT, ROLL, FREQ)
    np.savez(t / "noaspect.npz", response=np.zeros((0, len(ROLL), len(FREQ)), np.complex64),
             aspect_rad=np.zeros(0), roll_rad=ROLL, freq_hz=FREQ)
    (t / "bad.csv").write_text("aspect_deg,freq_ghz,rcs_dbsm\nzero,ten,-5\n")
    # data configs
    (t / "ok.yaml").write_text(TINY_CONFIG)
    (t / "family.yaml").write_text(TINY_CONFIG.replace("family: parts", "family: nope"))
    (t / "option.yaml").write_text(TINY_CONFIG.replace("segments: 16", "bogus: 1"))
    (t / "sampling.yaml").write_text(TINY_CONFIG.replace("surface: 2048", "surface: -5"))
    (t / "seed.yaml").write_text(TINY_CONFIG.replace("seed: 0", "seed: zero"))
    (t / "syntax.yaml").write_text(TINY_CONFIG.replace("family: parts", "family: [parts"))
    (t / "noradar.yaml").write_text(TINY_CONFIG.replace(str(REPO / "conf/radar/tiny.yaml"), str(t / "none.yaml")))
    return {"t": t, "ckpt": checkpoint}


# (id, argv with {t} = the folder and {ckpt} = a good checkpoint, words the error line must hold, env)
SIMULATE = [
    ("sim-missing-mesh", ["simulate", "{t}/none.obj", "--out", "{t}/out/r.npz"], ["none.obj", "no such file"]),
    ("sim-mesh-folder", ["simulate", "{t}/folder.obj", "--out", "{t}/out/r.npz"], ["folder.obj", "is a folder"]),
    ("sim-text-mesh", ["simulate", "{t}/text.obj", "--out", "{t}/out/r.npz"], ["text.obj"]),
    ("sim-empty-mesh", ["simulate", "{t}/empty.obj", "--out", "{t}/out/r.npz"], ["empty.obj"]),
    ("sim-nan-mesh", ["simulate", "{t}/nan.obj", "--out", "{t}/out/r.npz"], ["nan.obj", "NaN"]),
    ("sim-mesh-suffix", ["simulate", "{t}/notes.txt", "--out", "{t}/out/r.npz"], ["notes.txt", "suffix"]),
    ("sim-out-folder", ["simulate", "{t}/mesh.obj", "--out", "{t}/out"], ["--out", "existing folder"]),
    ("sim-out-under-file", ["simulate", "{t}/mesh.obj", "--out", "{t}/afile/r.npz"], ["--out", "afile", "not a folder"]),
    ("sim-out-suffix", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.txt"], ["--out", ".npz"]),
    ("sim-plot-suffix", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--plot", "{t}/out/r.npz"],
     ["--plot", ".png"]),
    ("sim-plot-under-file", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--plot", "{t}/afile/r.png"],
     ["--plot", "afile"]),
    ("sim-plot-folder", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--plot", "{t}/folder.obj"],
     ["--plot", "existing folder"]),
    ("sim-memory", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--aspect-deg", "0:180:1000",
                    "--roll-deg", "0:360:1000", "--freq-ghz", "8:12:100", "--memory-limit-gb", "4"],
     ["1000 x 1000 x 100", "4.5 GiB", "limit of 4.0 GiB"]),
    ("sim-memory-env", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--aspect-deg", "0:180:1000",
                        "--roll-deg", "0:360:100", "--freq-ghz", "8:12:100"], ["0.4 GiB", "limit of 0.2 GiB", MEMORY_ENV],
     {MEMORY_ENV: "0.2"}),
    ("sim-memory-env-bad", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", *SMALL], [MEMORY_ENV, "'lots'"],
     {MEMORY_ENV: "lots"}),
    ("sim-memory-option-bad", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", *SMALL, "--memory-limit-gb", "-1"],
     ["--memory-limit-gb", "-1"]),
    ("sim-aspect-range", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--aspect-deg", "0:190:3"], ["aspect"]),
    ("sim-count-zero", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--freq-ghz", "8:12:0"], ["--freq-ghz", "COUNT"]),
    ("sim-range-syntax", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--roll-deg", "0:90"],
     ["--roll-deg", "START:STOP:COUNT"]),
    ("sim-size", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--size-m", "-2"], ["--size-m", "-2"]),
    ("sim-sbr-bounces", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", *SMALL, "--method", "sbr",
                         "--bounces", "0"], ["max_bounces"]),
    ("sim-grid-missing", ["simulate", "{t}/mesh.obj", "--out", "{t}/out/r.npz", "--grid", "{t}/none.yaml"], ["none.yaml"]),
]
EVALUATE = [
    ("eval-missing-pred", ["evaluate", "{t}/none.obj", "{t}/gt.obj"], ["none.obj", "no such file"]),
    ("eval-missing-gt", ["evaluate", "{t}/pred.ply", "{t}/none.obj"], ["none.obj", "no such file"]),
    ("eval-pred-folder", ["evaluate", "{t}/folder.obj", "{t}/gt.obj"], ["folder.obj", "is a folder"]),
    ("eval-gt-folder", ["evaluate", "{t}/pred.ply", "{t}/folder.obj"], ["folder.obj", "is a folder"]),
    ("eval-text-pred", ["evaluate", "{t}/text.obj", "{t}/gt.obj"], ["text.obj", "not a .obj mesh"]),
    ("eval-text-gt", ["evaluate", "{t}/pred.ply", "{t}/text.obj"], ["text.obj"]),
    ("eval-empty-gt", ["evaluate", "{t}/pred.ply", "{t}/empty.obj"], ["empty.obj", "no triangles"]),
    ("eval-pred-suffix", ["evaluate", "{t}/notes.txt", "{t}/gt.obj"], ["notes.txt", "unsupported suffix"]),
    ("eval-gt-points", ["evaluate", "{t}/pred.ply", "{t}/flat.npy"], ["flat.npy", "unsupported suffix"]),
    ("eval-npy-shape", ["evaluate", "{t}/flat.npy", "{t}/gt.obj"], ["flat.npy", "[N, 3]"]),
    ("eval-npy-pickle", ["evaluate", "{t}/objects.npy", "{t}/gt.obj"], ["objects.npy", "cannot be read"]),
    ("eval-garbage-pred", ["evaluate", "{t}/garbage.ply", "{t}/gt.obj"], ["garbage.ply"]),
    ("eval-garbage-gt", ["evaluate", "{t}/pred.ply", "{t}/garbage.ply"], ["garbage.ply"]),
    ("eval-points", ["evaluate", "{t}/pred.ply", "{t}/gt.obj", "--points", "0"], ["--points", "positive"]),
    ("eval-occ-points", ["evaluate", "{t}/pred.ply", "{t}/gt.obj", "--occ-points", "-3"], ["--occ-points", "-3"]),
    ("eval-tau", ["evaluate", "{t}/pred.ply", "{t}/gt.obj", "--tau", "-0.1"], ["--tau"]),
    ("eval-tau-nan", ["evaluate", "{t}/pred.ply", "{t}/gt.obj", "--tau", "nan"], ["--tau", "nan"]),
    ("eval-seed", ["evaluate", "{t}/pred.ply", "{t}/gt.obj", "--seed", "-1"], ["--seed", "-1"]),
    ("eval-memory", ["evaluate", "{t}/pred.ply", "{t}/gt.obj", "--occ-points", "1000000000", "--memory-limit-gb", "8"],
     ["--occ-points 1000000000", "59.6 GiB", "limit of 8.0 GiB"]),
]
def rec(ckpt: str = "{ckpt}", radar: str = "{t}/radar.npz") -> list[str]:
    """A valid reconstruct call (or one with another checkpoint or radar file): each case spoils one argument."""
    return ["reconstruct", "--ckpt", ckpt, "--radar", radar, "--out", "{t}/out/m.obj"]


REC = rec()
RECONSTRUCT = [
    ("rec-ckpt-missing", rec(ckpt="{t}/none.ckpt"),
     ["--ckpt", "none.ckpt", "not found"]),
    ("rec-ckpt-folder", rec(ckpt="{t}/out"),
     ["--ckpt", "is a folder"]),
    ("rec-ckpt-empty", rec(ckpt="{t}/empty.ckpt"),
     ["empty.ckpt", "empty file"]),
    ("rec-ckpt-text", rec(ckpt="{t}/text.ckpt"),
     ["text.ckpt", "a text file", "radar2shape fit"]),
    ("rec-ckpt-pickle", rec(ckpt="{t}/pickle.ckpt"),
     ["pickle.ckpt", "pickle"]),
    ("rec-ckpt-nokeys", rec(ckpt="{t}/nokeys.ckpt"),
     ["nokeys.ckpt", "'state_dict'", "keys: weights"]),
    ("rec-ckpt-list", rec(ckpt="{t}/list.ckpt"),
     ["list.ckpt", "holds a list"]),
    ("rec-out-xyz", ["reconstruct", "--ckpt", "{ckpt}", "--radar", "{t}/radar.npz", "--out", "{t}/out/m.xyz"],
     ["--out", "'.xyz'", ".obj"]),
    ("rec-out-gltf", ["reconstruct", "--ckpt", "{ckpt}", "--radar", "{t}/radar.npz", "--out", "{t}/out/m.gltf"],
     ["--out", "'.gltf'"]),
    ("rec-out-folder", ["reconstruct", "--ckpt", "{ckpt}", "--radar", "{t}/radar.npz", "--out", "{t}/out"],
     ["--out", "existing folder"]),
    ("rec-out-under-file", ["reconstruct", "--ckpt", "{ckpt}", "--radar", "{t}/radar.npz", "--out", "{t}/afile/m.obj"],
     ["--out", "afile"]),
    ("rec-spread-suffix", [*REC,
                           "--spread", "{t}/out/s.txt"], ["--spread", ".npy"]),
    ("rec-spread-under-file", [*REC,
                               "--spread", "{t}/afile/s.npy"], ["--spread", "afile"]),
    ("rec-png-under-file", [*REC,
                            "--png", "{t}/afile/v.png"], ["--png", "afile"]),
    ("rec-save-input-is-radar", [*REC,
                                 "--save-input", "{t}/radar.npz"], ["--save-input", "also an input"]),
    ("rec-two-outputs-one-file", [*REC,
                                  "--png", "{t}/out/v.png", "--save-input", "{t}/out/i.npz", "--spread", "{t}/out/i.npz"],
     ["--spread", ".npy"]),
    ("rec-radar-missing", rec(radar="{t}/none.npz"),
     ["--radar", "none.npz", "no such file"]),
    ("rec-radar-folder", rec(radar="{t}/out"),
     ["--radar", "is a folder"]),
    ("rec-radar-empty-axis", rec(radar="{t}/noaspect.npz"),
     ["noaspect.npz", "empty axis"]),
    ("rec-radar-all-zero", rec(radar="{t}/zeros.npz"),
     ["zeros.npz", "dB floor", "--allow-empty"]),
    ("rec-radar-not-npz", rec(radar="{t}/text.ckpt"),
     ["text.ckpt", ".npz"]),
    ("rec-measured-bad", ["reconstruct", "--ckpt", "{ckpt}", "--measured", "{t}/bad.csv", "--out", "{t}/out/m.obj"],
     ["bad.csv"]),
    ("rec-resolution-memory", [*REC,
                               "--resolution", "4000"], ["--resolution 4000", "1430.5 GiB"]),
    ("rec-resolution-small", [*REC,
                              "--resolution", "1"], ["--resolution", "1"]),
    ("rec-steps", [*REC,
                   "--steps", "1000"], ["--steps", "1000"]),
    ("rec-samples", [*REC,
                     "--samples", "0"], ["--samples", "0"]),
    ("rec-seed", [*REC,
                  "--seed", "-4"], ["--seed", "-4"]),
    ("rec-min-overlap", [*REC,
                         "--min-overlap", "0"], ["--min-overlap", "0"]),
    ("rec-format-radar", [*REC,
                          "--format", "csv"], ["--format", "--measured"]),
    ("rec-size", [*REC,
                  "--size-m", "0"], ["--size-m", "0"]),
    ("rec-calibration", [*REC,
                         "--calibration-db", "inf"], ["--calibration-db", "inf"]),
    ("rec-memory-option", [*REC,
                           "--memory-limit-gb", "0"], ["--memory-limit-gb", "0"]),
]
BUILD = [
    ("build-num", ["build-data", "--config", "{t}/ok.yaml", "--out", "{t}/out/data", "--num", "0"], ["--num", "0"]),
    ("build-workers", ["build-data", "--config", "{t}/ok.yaml", "--out", "{t}/out/data", "--workers", "0"],
     ["--workers", "0"]),
    ("build-shard", ["build-data", "--config", "{t}/ok.yaml", "--out", "{t}/out/data", "--shard", "2/2"], ["--shard", "2/2"]),
    ("build-out-file", ["build-data", "--config", "{t}/ok.yaml", "--out", "{t}/afile"], ["--out", "afile", "existing file"]),
    ("build-out-under-file", ["build-data", "--config", "{t}/ok.yaml", "--out", "{t}/afile/data"],
     ["--out", "afile", "not a folder"]),
    ("build-finalize-nothing", ["build-data", "--config", "{t}/ok.yaml", "--out", "{t}/out/data", "--finalize"],
     ["--out", "build_config.json"]),
    ("build-config-missing", ["build-data", "--config", "{t}/none.yaml", "--out", "{t}/out/data"],
     ["--config", "none.yaml", "no such file"]),
    ("build-config-folder", ["build-data", "--config", "{t}/out", "--out", "{t}/out/data"], ["--config", "is a folder"]),
    ("build-family", ["build-data", "--config", "{t}/family.yaml", "--out", "{t}/out/data"], ["family.yaml", "nope"]),
    ("build-option", ["build-data", "--config", "{t}/option.yaml", "--out", "{t}/out/data"], ["option.yaml", "bogus"]),
    ("build-sampling", ["build-data", "--config", "{t}/sampling.yaml", "--out", "{t}/out/data"],
     ["sampling.yaml", "surface", "-5"]),
    ("build-seed", ["build-data", "--config", "{t}/seed.yaml", "--out", "{t}/out/data"], ["seed.yaml", "seed"]),
    ("build-syntax", ["build-data", "--config", "{t}/syntax.yaml", "--out", "{t}/out/data"], ["syntax.yaml"]),
    ("build-radar-missing", ["build-data", "--config", "{t}/noradar.yaml", "--out", "{t}/out/data"],
     ["noradar.yaml", "none.yaml"]),
]
CASES = [case if len(case) == 4 else (*case, None) for case in SIMULATE + EVALUATE + RECONSTRUCT + BUILD]


@pytest.mark.parametrize("argv, words, env", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_no_new_file(world, capsys, monkeypatch, argv, words, env):
    for name, value in (env or {}).items():
        monkeypatch.setenv(name, value)
    monkeypatch.chdir(REPO)
    before = snapshot(world["t"])
    code = main([a.format(**world) for a in argv])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for word in words:
        assert word.format(**world) in lines[0], lines[0]
    assert snapshot(world["t"]) == before


def test_the_corpus_is_large_and_every_command_is_in_it():
    assert len(CASES) >= 40 and len({c[0] for c in CASES}) == len(CASES)
    assert {c[1][0] for c in CASES} == {"simulate", "evaluate", "reconstruct", "build-data"}


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_refused_before_any_work(world, capsys):
    t = world["t"]
    locked = t / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        before = snapshot(t)
        assert main(["simulate", str(t / "mesh.obj"), "--out", str(t / "out/r.npz"), *SMALL,
                     "--plot", str(locked / "r.png")]) == 2
        assert main(["reconstruct", "--ckpt", world["ckpt"], "--radar", str(t / "radar.npz"),
                     "--out", str(t / "out/m.obj"), "--spread", str(locked / "s.npy")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 2 and all("read-only" in line for line in err)
        assert snapshot(t) == before
    finally:
        locked.chmod(0o755)


# ---- the atomic writer --------------------------------------------------------------------------
def test_atomic_paths_write_all_or_nothing(tmp_path):
    first, second = tmp_path / "new/deeper/a.npz", tmp_path / "new/b.txt"
    with pytest.raises(RuntimeError), atomic_paths(first, second) as (a, b):
        np.savez(a, x=np.ones(3))
        raise RuntimeError("the second file fails")
    assert list(tmp_path.iterdir()) == []  # no temp file, and the folders it created are gone
    with atomic_paths(first, second) as (a, b):
        assert a.parent == first.parent and a.suffix == ".npz" and a.name.startswith(".a.")
        np.savez(a, x=np.arange(3))
        b.write_text("ok")
    assert np.load(first)["x"].tolist() == [0, 1, 2] and second.read_text() == "ok"
    assert sorted(p.name for p in first.parent.iterdir()) == ["a.npz"]
    with pytest.raises(FileNotFoundError, match="produced no file"), atomic_paths(tmp_path / "c.txt"):
        pass
    write_text_atomic(second, "replaced")
    assert second.read_text() == "replaced" and sorted(p.name for p in second.parent.iterdir()) == ["b.txt", "deeper"]


def test_check_output_path_names_the_problem(tmp_path):
    (tmp_path / "f").write_text("x")
    assert check_output_path(tmp_path / "a/b/c.npz", "--out", (".npz",)) == tmp_path / "a/b/c.npz"
    assert not (tmp_path / "a").exists()  # checking creates nothing
    for path, message in [(tmp_path, "existing folder"), (tmp_path / "f/x.npz", "is a file, not a folder"),
                          (tmp_path / "c.png", "expected one of .npz")]:
        with pytest.raises(UserInputError, match=message):
            check_output_path(path, "--out", (".npz",))
    with pytest.raises(UserInputError, match="already exists"):
        check_output_path(tmp_path / "f", "--out", overwrite=False)


def test_failed_plot_leaves_no_response(world, monkeypatch):
    import radar2shape.radar.plot as plot

    def broken(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(plot, "plot_response", broken)
    t = world["t"]
    before = snapshot(t)
    assert main(["simulate", str(t / "mesh.obj"), "--out", str(t / "out/new/r.npz"), *SMALL,
                 "--plot", str(t / "out/r.png")]) == 2
    assert snapshot(t) == before


# ---- decisions on inputs that were accepted silently --------------------------------------------
def test_scale_mismatch_warns_on_one_line_and_still_scores(world, capsys):
    t = world["t"]
    trimesh.creation.icosphere(2, 350.0).export(t / "huge.ply")  # 1000 x the 0.35 sphere
    assert main(["evaluate", str(t / "huge.ply"), str(t / "gt.obj"), "--json", *FAST_EVAL]) == 0
    out, err = capsys.readouterr()
    assert len(err.strip().splitlines()) == 1 and err.startswith("warning:") and "--normalise" in err
    assert "875 times" in err  # 700 / 0.8: the longest sides of the two spheres
    assert json.loads(out)["fscore_1pct"] == 0.0
    assert main(["evaluate", str(t / "pred.ply"), str(t / "gt.obj"), "--json", *FAST_EVAL]) == 0
    assert capsys.readouterr().err == ""  # 0.875 x: no warning


def test_all_zero_radar_reconstructs_with_allow_empty(world, capsys):
    t = world["t"]
    argv = ["reconstruct", "--ckpt", world["ckpt"], "--radar", str(t / "zeros.npz"), "--out", str(t / "out/m.obj"),
            "--samples", "1", "--steps", "2", "--resolution", "16"]
    assert main(argv + ["--allow-empty"]) == 0
    assert (t / "out/m.obj").stat().st_size > 0


def test_constants_copied_for_a_fast_start_match_their_sources():
    from radar2shape import pretrained
    from radar2shape.commands import reconstruct
    from radar2shape.geometry.mesh_io import WRITE_SUFFIXES
    from radar2shape.models.base import RADAR_SPEC_KEY
    from radar2shape.models.verifier import KEEP
    from radar2shape.radar.measured import FORMATS, MIN_OVERLAP

    assert reconstruct.FORMATS == FORMATS and reconstruct.MIN_OVERLAP == MIN_OVERLAP and reconstruct.KEEP == KEEP
    assert pretrained.RADAR_SPEC_KEY == RADAR_SPEC_KEY and reconstruct.MESH_OUT_SUFFIXES == WRITE_SUFFIXES


def test_memory_estimate_is_the_documented_closed_form():
    from radar2shape.commands import reconstruct, simulate

    # 1000 x 1000 x 100 cells x 48 B and 4000^3 cells x 24 B, in GiB (the corpus' expected numbers)
    assert f"{1000 * 1000 * 100 * simulate.BYTES_PER_CELL / GIB:.1f}" == "4.5"
    assert f"{4000**3 * reconstruct.BYTES_PER_GRID_CELL / GIB:.1f}" == "1430.5"


# ---- fast start ---------------------------------------------------------------------------------
def test_simulate_and_evaluate_never_import_lightning(world):
    t = world["t"]
    script = (
        "import sys\n"
        "from radar2shape.cli import main\n"
        f"assert main(['evaluate', {str(t / 'pred.ply')!r}, {str(t / 'gt.obj')!r}, '--json', *{FAST_EVAL!r}]) == 0\n"
        f"assert main(['simulate', {str(t / 'mesh.obj')!r}, '--out', {str(t / 'out/r.npz')!r}, *{SMALL!r}]) == 0\n"
        "print(sorted(m for m in ('lightning', 'torch', 'torchmetrics', 'matplotlib') if m in sys.modules))\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "[]"
