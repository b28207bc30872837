"""The shipped default model: export of a training checkpoint, and ``reconstruct`` without ``--ckpt``.

A tiny RadarDiffusion (the sphere Stage 1 of tests/models/test_radar_diffusion.py) is fitted for
two steps through a Trainer, so its checkpoint has everything a ``radar2shape fit`` checkpoint has
(optimizer state, loops, LightningCLI's class path and instantiator); the export must drop the
training state and still reconstruct exactly the same mesh.
"""

from __future__ import annotations

import fnmatch
import importlib.util
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
import trimesh
import yaml

import radar2shape.pretrained as pretrained
REPO_ROOT = Path(__file__).resolve().parents[1]
from models.test_radar_diffusion import (  # noqa: F401  (single_thread: the module's fixture)
    GRID,
    RadarStub,
    fit,
    radar_batch,
    single_thread,
    sphere_batch,
    sphere_stage1,
    tiny_model,
)
from radar2shape.cli import main
from radar2shape.commands.reconstruct import load_model, measured_input, reconstruct_input
from radar2shape.errors import UserInputError
from radar2shape.pretrained import DEFAULT_MODEL, SHIPPED_MODELS, export_checkpoint
from radar2shape.radar import save_response

RADAR_DIFFUSION = "radar2shape.models.radar_diffusion.RadarDiffusion"
CLI_HPARAMS = {"_class_path": RADAR_DIFFUSION, "_instantiator": "lightning.pytorch.cli.instantiate_module"}
SHIPPED = DEFAULT_MODEL  # the real path, before any test monkeypatches it
SHIPPED_FILES = dict(SHIPPED_MODELS)
MAX_SHIPPED_MB = 25.0
FLOAT16_REL_ERROR = 2.0**-11  # round-to-nearest with an 11-bit significand
FLOAT16_SUBNORMAL_STEP = 2.0**-24  # spacing below 2^-14, where the relative bound does not hold


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, single_thread) -> SimpleNamespace:
    """A Trainer-saved tiny RadarDiffusion (``source``), its export (``exported``) and a response file."""
    folder = tmp_path_factory.mktemp("pretrained")
    model = tiny_model(sphere_stage1(folder / "stage1.ckpt"), sample_steps=4)
    model.hparams.update(CLI_HPARAMS)  # what `radar2shape fit` stores: load_from_checkpoint goes through it
    batch = {**radar_batch(4), "surface_points": sphere_batch()["surface_points"][:1].expand(4, -1, -1)}
    trainer = fit(model, RadarStub(batch, GRID), 2, folder)
    source = folder / "source.ckpt"
    trainer.save_checkpoint(source)
    exported = folder / "exported.ckpt"
    size = export_checkpoint(source, exported)
    rng = np.random.default_rng(0)
    shape = tuple(len(GRID[k]) for k in ("aspect_rad", "roll_rad", "freq_hz"))
    response = (0.1 * (rng.normal(size=shape) + 1j * rng.normal(size=shape))).astype(np.complex64)
    radar = save_response(folder / "radar.npz", response, GRID["aspect_rad"], GRID["roll_rad"], GRID["freq_hz"])
    return SimpleNamespace(folder=folder, source=source, exported=exported, size=size, radar=radar,
                           stage1=folder / "stage1.ckpt")


def reconstruct_file(ckpt, radar, seed: int) -> trimesh.Trimesh:
    """What ``radar2shape reconstruct --ckpt ckpt --radar radar --seed seed`` meshes, in memory."""
    model = load_model(ckpt)
    grid = measured_input([radar], "npz", model.radar_spec)
    recon, _ = reconstruct_input(model, grid, seed=seed)
    return recon.mesh


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "\n" not in err, err
    return err


def test_export_drops_training_state_and_keeps_weights(tiny):
    source = torch.load(tiny.source, map_location="cpu", weights_only=True)
    exported = torch.load(tiny.exported, map_location="cpu", weights_only=True)
    assert "optimizer_states" in source and "loops" in source  # a real training checkpoint
    assert set(exported) <= set(pretrained.EXPORT_KEYS) and "optimizer_states" not in exported
    assert {"state_dict", "hyper_parameters", "radar_spec", "pytorch-lightning_version"} <= set(exported)
    assert tiny.exported.stat().st_size < tiny.source.stat().st_size
    assert tiny.size == pytest.approx(tiny.exported.stat().st_size / 1e6, abs=1e-9)
    assert exported["hyper_parameters"] == source["hyper_parameters"]
    assert exported["radar_spec"] == source["radar_spec"]
    assert exported["state_dict"].keys() == source["state_dict"].keys()
    for key, value in source["state_dict"].items():
        assert torch.equal(exported["state_dict"][key], value), key


def test_exported_model_reconstructs_the_same_mesh(tiny):
    original = reconstruct_file(tiny.source, tiny.radar, seed=3)
    shipped = reconstruct_file(tiny.exported, tiny.radar, seed=3)
    assert len(original.faces) > 0
    np.testing.assert_array_equal(shipped.faces, original.faces)
    np.testing.assert_allclose(shipped.vertices, original.vertices, rtol=0, atol=1e-6)


def test_float16_export_rounds_each_weight_to_half_precision(tiny, tmp_path):
    half = tmp_path / "half.ckpt"
    size = export_checkpoint(tiny.source, half, dtype="float16")
    assert size < 0.75 * tiny.size  # weights dominate the file; halving them shrinks it
    stored = torch.load(half, map_location="cpu", weights_only=True)["state_dict"]
    source = torch.load(tiny.source, map_location="cpu", weights_only=True)["state_dict"]
    for key, value in source.items():
        if not value.is_floating_point():
            assert torch.equal(stored[key], value), key
            continue
        assert stored[key].dtype == torch.float16, key
        error = (stored[key].double() - value.double()).abs()
        bound = FLOAT16_REL_ERROR * value.double().abs() + FLOAT16_SUBNORMAL_STEP
        assert bool((error <= bound).all()), key
    model = load_model(half)  # rebuilt in float32
    assert all(p.dtype == torch.float32 for p in model.parameters())


def test_export_with_a_surface_level_and_grid_meshes_them(tiny, tmp_path):
    """``--surface-level`` / ``--mesh-resolution``: the exported model's SDF is the source's minus the
    level, meshed on that grid; weights unchanged."""
    leveled = tmp_path / "leveled.ckpt"
    export_checkpoint(tiny.source, leveled, surface_level=0.004, mesh_resolution=40)
    source, shifted = load_model(tiny.source), load_model(leveled)
    assert shifted.stage1.hparams.surface_level == 0.004 and source.stage1.hparams.surface_level == 0.0
    assert shifted.hparams.mesh_resolution == 40 != source.hparams.mesh_resolution
    h = torch.randn(2, source.n_levels, source.latent_dim)
    points = torch.rand(9, 3) - 0.5
    torch.testing.assert_close(shifted.sdf_function(h)(points), source.sdf_function(h)(points) - 0.004)


def test_reconstruct_without_ckpt_uses_the_default_model(tiny, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(pretrained.SHIPPED_MODELS, "parts", tiny.exported)
    explicit, default = tmp_path / "explicit.obj", tmp_path / "default.obj"
    common = ["--radar", str(tiny.radar), "--seed", "5"]
    assert main(["reconstruct", "--ckpt", str(tiny.exported), *common, "--out", str(explicit)]) == 0
    assert "model:" not in capsys.readouterr().out
    assert main(["reconstruct", *common, "--out", str(default)]) == 0
    out = capsys.readouterr().out
    assert f"model: parts ({tiny.exported}, shipped with radar2shape" in out
    first, second = (trimesh.load(p, force="mesh", process=False) for p in (explicit, default))
    assert len(first.faces) > 0
    np.testing.assert_array_equal(second.faces, first.faces)
    np.testing.assert_allclose(second.vertices, first.vertices, rtol=0, atol=1e-6)


def test_reconstruct_without_ckpt_and_no_default_model(tiny, tmp_path, monkeypatch, capsys):
    missing = tmp_path / "weights" / "radar2shape_parts_medium.ckpt"
    monkeypatch.setitem(pretrained.SHIPPED_MODELS, "parts", missing)
    outputs = tmp_path / "out"
    code = main(["reconstruct", "--radar", str(tiny.radar), "--out", str(outputs / "m.obj"),
                 "--png", str(outputs / "m.png")])
    assert code == 2
    err = one_line_error(capsys)
    assert f"no default model is installed (expected {missing})" in err and "pass --ckpt" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no output, no folder created


def test_model_real_reconstructs_with_its_own_file(tiny, tmp_path, monkeypatch, capsys):
    """--model real reads SHIPPED_MODELS['real'], not the default: a missing default does not matter."""
    monkeypatch.setitem(pretrained.SHIPPED_MODELS, "real", tiny.exported)
    monkeypatch.setitem(pretrained.SHIPPED_MODELS, "parts", tmp_path / "absent.ckpt")
    explicit, named = tmp_path / "explicit.obj", tmp_path / "named.obj"
    common = ["--radar", str(tiny.radar), "--seed", "2"]
    assert main(["reconstruct", "--ckpt", str(tiny.exported), *common, "--out", str(explicit)]) == 0
    capsys.readouterr()
    assert main(["reconstruct", "--model", "real", *common, "--out", str(named)]) == 0
    assert f"model: real ({tiny.exported}, shipped with radar2shape; --about real" in capsys.readouterr().out
    first, second = (trimesh.load(p, force="mesh", process=False) for p in (explicit, named))
    assert len(first.faces) > 0
    np.testing.assert_array_equal(second.faces, first.faces)


def test_model_names_a_missing_file_or_is_refused_with_ckpt(tiny, tmp_path, monkeypatch, capsys):
    missing = tmp_path / "weights" / "radar2shape_real.ckpt"
    monkeypatch.setitem(pretrained.SHIPPED_MODELS, "real", missing)
    out = tmp_path / "out" / "m.obj"
    assert main(["reconstruct", "--model", "real", "--radar", str(tiny.radar), "--out", str(out)]) == 2
    err = one_line_error(capsys)
    assert f"--model real: no such model is installed (expected {missing})" in err and "pass --ckpt" in err
    assert main(["reconstruct", "--model", "real", "--ckpt", str(tiny.exported), "--radar", str(tiny.radar),
                 "--out", str(out)]) == 2
    assert "argument --ckpt: not allowed with argument --model" in one_line_error(capsys)
    assert main(["reconstruct", "--model", "boat", "--radar", str(tiny.radar), "--out", str(out)]) == 2
    assert "argument --model: invalid choice: 'boat'" in one_line_error(capsys)
    assert not out.parent.exists()


def test_checkpoint_model_resolves_shipped_names(tiny, monkeypatch):
    from radar2shape.models.checkpoint_model import CheckpointModel

    monkeypatch.setitem(pretrained.SHIPPED_MODELS, "real", tiny.exported)
    assert CheckpointModel("real").ckpt_path == str(tiny.exported)
    with pytest.raises(UserInputError, match="no such model is installed"):
        monkeypatch.setitem(pretrained.SHIPPED_MODELS, "real", tiny.folder / "absent.ckpt")
        CheckpointModel("real")


def test_output_colliding_with_ckpt_is_still_refused(tiny, tmp_path, capsys):
    """--ckpt stays an input of the collision check (a copy named .obj would be overwritten)."""
    named_obj = tmp_path / "model.obj"
    named_obj.write_bytes(tiny.exported.read_bytes())
    assert main(["reconstruct", "--ckpt", str(named_obj), "--radar", str(tiny.radar), "--out", str(named_obj)]) == 2
    assert f"--out: {named_obj} is also an input" in one_line_error(capsys)
    assert named_obj.read_bytes() == tiny.exported.read_bytes()


def with_cli_class(path, out, class_path: str, radar_spec: dict | None) -> str:
    """A copy of checkpoint ``path`` as `radar2shape fit` would have saved a model of ``class_path``."""
    checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    checkpoint["hyper_parameters"] = {**checkpoint["hyper_parameters"], **CLI_HPARAMS, "_class_path": class_path}
    checkpoint.pop("radar_spec", None)
    if radar_spec is not None:
        checkpoint["radar_spec"] = radar_spec
    torch.save(checkpoint, out)
    return str(out)


def test_export_refuses_what_is_not_a_radar_diffusion_with_a_spec(tiny, tmp_path):
    spec = torch.load(tiny.exported, map_location="cpu", weights_only=True)["radar_spec"]
    cases = {
        "bare Stage 1": (str(tiny.stage1), "without Stage-1 hyperparameters"),
        "CLI Stage 1": (with_cli_class(tiny.stage1, tmp_path / "s1.ckpt", "radar2shape.models.sdf_vae.SDFVAE", spec),
                        "holds a radar2shape.models.sdf_vae.SDFVAE; expected a RadarDiffusion (Stage 2)"),
        "no spec": (with_cli_class(tiny.source, tmp_path / "nospec.ckpt", RADAR_DIFFUSION, None), "stores no radar spec"),
    }
    for name, (src, message) in cases.items():
        with pytest.raises(UserInputError) as info:
            export_checkpoint(src, tmp_path / "out.ckpt")
        assert message in str(info.value) and "\n" not in str(info.value), name
        assert str(info.value).startswith(f"--ckpt: {src}"), name
    assert not (tmp_path / "out.ckpt").exists()


def test_export_refuses_bad_options(tiny, tmp_path):
    with pytest.raises(UserInputError, match=r"^--dtype: expected one of float32, float16, bfloat16, got 'int8'$"):
        export_checkpoint(tiny.source, tmp_path / "a.ckpt", dtype="int8")
    with pytest.raises(UserInputError, match=r"^--out: .*a\.pt has suffix '\.pt'; expected one of \.ckpt$"):
        export_checkpoint(tiny.source, tmp_path / "a.pt")
    with pytest.raises(UserInputError, match="is the source checkpoint"):
        export_checkpoint(tiny.source, tiny.source)
    with pytest.raises(UserInputError, match=r"^--mesh-resolution: expected an integer >= 2, got 1$"):
        export_checkpoint(tiny.source, tmp_path / "a.ckpt", mesh_resolution=1)
    assert list(tmp_path.iterdir()) == []


def load_script():
    spec = importlib.util.spec_from_file_location("export_default_model", REPO_ROOT / "scripts" / "export_default_model.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_export_script_checks_size_and_loads_the_result(tiny, tmp_path, capsys):
    script = load_script()
    out = tmp_path / "weights" / "model.ckpt"
    assert script.main(["--ckpt", str(tiny.source), "--out", str(out), "--max-mb", f"{tiny.size / 2:.6f}"]) == 2
    err = one_line_error(capsys)
    assert f"the exported model is {tiny.size:.1f} MB, over the" in err and "nothing written" in err
    assert not out.exists() and not out.parent.exists()
    assert script.main(["--ckpt", str(tiny.source), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out}: {out.stat().st_size / 1e6:.2f} MB" in printed
    assert "loads as RadarDiffusion" in printed and "4 aspects x 8 rolls x 8 frequencies 8-12 GHz" in printed
    assert out.read_bytes() == tiny.exported.read_bytes()  # the same export as the API's
    assert [p.name for p in out.parent.iterdir()] == [out.name]  # no temporary file left


@pytest.mark.parametrize("name", sorted(SHIPPED_FILES))
def test_package_data_lists_each_shipped_model_and_card(name):
    """A regular (non-editable) install must carry the weights and cards: pyproject's package data matches them."""
    config = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["radar2shape"]
    for path in (SHIPPED_FILES[name], pretrained.MODEL_CARDS[name]):
        relative = path.relative_to(REPO_ROOT / "src" / "radar2shape").as_posix()
        assert any(fnmatch.fnmatch(relative, pattern) for pattern in patterns), (relative, patterns)


@pytest.mark.parametrize("name, data", [("parts", "data/parts_unseen"), ("real", "data/real")])
def test_shipped_verifier_fits_the_shipped_model_and_is_package_data(name, data):
    from radar2shape.geometry.families.folder import sha256_of
    from radar2shape.models.verifier import default_verifier_path, load_verifier

    shipped = SHIPPED_FILES[name]
    path = default_verifier_path(shipped)
    if not path.is_file():
        pytest.skip(f"no shipped verifier at {path} (scripts/train_verifier.py writes one)")
    patterns = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["radar2shape"]
    relative = path.relative_to(REPO_ROOT / "src" / "radar2shape").as_posix()
    assert any(fnmatch.fnmatch(relative, pattern) for pattern in patterns), patterns
    model = load_model(shipped)
    verifier = load_verifier(path, model.n_levels)  # its features are this model's (else one clear error)
    about = torch.load(path, map_location="cpu", weights_only=True)["about"]
    assert about["checkpoint"] == shipped.name and about["data"] == data
    assert about["checkpoint_sha256"] == sha256_of(shipped)  # trained on this model's samples
    assert (REPO_ROOT / about["report"]).is_file()  # the report that scores it is committed
    assert path.stat().st_size < 100_000 and not verifier.training


def default_grid() -> dict[str, np.ndarray]:
    """conf/radar/default.yaml's axes in radians and hertz."""
    conf = yaml.safe_load((REPO_ROOT / "conf" / "radar" / "default.yaml").read_text())
    axis = {name: conf[name] for name in ("aspect_deg", "roll_deg", "freq_ghz")}
    values = {name: np.linspace(a["start"], a["stop"], a["count"], endpoint=a.get("endpoint", True))
              for name, a in axis.items()}
    return {"aspect_rad": np.radians(values["aspect_deg"]), "roll_rad": np.radians(values["roll_deg"]),
            "freq_hz": values["freq_ghz"] * 1e9}


@pytest.mark.parametrize("name", sorted(SHIPPED_FILES))
def test_shipped_model_is_on_the_default_grid_and_small(name):
    path = SHIPPED_FILES[name]
    if not path.is_file():
        pytest.skip(f"no shipped model at {path} (export one with scripts/export_default_model.py)")
    assert path.stat().st_size / 1e6 <= MAX_SHIPPED_MB
    assert "optimizer_states" not in torch.load(path, map_location="cpu", weights_only=True)
    model = load_model(path)
    assert type(model).__name__ == "RadarDiffusion" and not model.radar_spec.roll_symmetric
    expected = default_grid()
    assert [len(v) for v in expected.values()] == [32, 32, 64]
    for name, values in expected.items():
        np.testing.assert_allclose(getattr(model.radar_spec.grid, name), values, rtol=1e-9, err_msg=name)


def test_mirrored_constants_match_their_sources():
    """pretrained.py repeats two names so that importing it needs no torch or Lightning."""
    from radar2shape.models.base import RADAR_SPEC_KEY
    from radar2shape.models.radar_diffusion import RadarDiffusion

    assert pretrained.RADAR_SPEC_KEY == RADAR_SPEC_KEY
    assert pretrained.RADAR_DIFFUSION == f"{RadarDiffusion.__module__}.{RadarDiffusion.__qualname__}" == RADAR_DIFFUSION
