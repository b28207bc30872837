"""Every config file is a test: each experiment trains one step through ``radar2shape fit`` with the
layers its header documents and leaves a checkpoint that loads with ``weights_only=True``; every
model, data, DataModule and radar file is loaded and checked.

Experiments run on tiny generated datasets (5 shapes); paper-size ones keep their models and get
inputs of the size those models read (64 frequencies, 32 aspects for profile models) and few points.
GPU experiments run with conf/trainer/cpu.yaml in place of gpu.yaml; their real layers are parsed
by ``--print_config``.
"""

from __future__ import annotations

import importlib
import inspect
import re
from dataclasses import dataclass, replace
from pathlib import Path

import pytest
import torch
import yaml

from data_modules.build import build_dataset
from data_modules.config import load_build_config
from radar2shape.cli import main
from radar2shape.errors import UserInputError

REPO = Path(__file__).resolve().parents[1]
CONF = REPO / "conf"
TINY_POINTS = ("{train: {surface: 512, sdf: 1024}, val: {surface: 512, sdf: 1024, eval: 2048, occ: 4096}, "
               "test: {surface: 512, sdf: 1024, eval: 2048, occ: 4096}}")

# name -> (data config, radar grid overriding its own or None)
DATASETS = {
    "parts16": ("parts_tiny.yaml", None),
    "frusta16": ("frusta_tiny.yaml", None),
    "parts64": ("parts_tiny.yaml", {"aspect_deg": {"start": 0.0, "stop": 180.0, "count": 4},
                                     "roll_deg": {"start": 0.0, "stop": 360.0, "count": 4, "endpoint": False},
                                     "freq_ghz": {"start": 8.0, "stop": 12.0, "count": 64}}),
    "frusta32x64": ("frusta_tiny.yaml", {"aspect_deg": {"start": 0.0, "stop": 180.0, "count": 32},
                                         "roll_deg": {"start": 0.0, "stop": 360.0, "count": 2, "endpoint": False},
                                         "freq_ghz": {"start": 8.0, "stop": 12.0, "count": 64}}),
}


@dataclass(frozen=True)
class Setup:
    """How the test runs one experiment: its layers, data, and the runs it depends on."""

    trainer: str  # the trainer layer the header documents (cpu or gpu)
    callbacks: str | None  # conf/callbacks/NAME.yaml, or None
    data: str | None = None  # a DATASETS name (None: the experiment makes its own data)
    before: tuple[str, ...] = ()  # experiment files layered before this one
    model: str | None = None  # conf/model file for experiments without a model
    stage1: str | None = None  # experiment whose checkpoint is model.init_args.stage1_ckpt
    base: str | None = None  # experiment whose checkpoint is model.init_args.base_ckpt
    tiny_points: bool = False  # paper-size point counts replaced by TINY_POINTS


SETUPS = {
    "toy_sphere": Setup("cpu", None),
    "sdf_vae_parts_cpu": Setup("cpu", "shape_metrics", "parts16"),
    "sdf_vae_frusta_cpu": Setup("cpu", "shape_metrics", "frusta16"),
    "radar_diffusion_parts_cpu": Setup("cpu", "shape_metrics", "parts16", stage1="sdf_vae_parts_cpu"),
    "lora_finetune_cpu": Setup("cpu", "shape_metrics", "parts16", base="radar_diffusion_parts_cpu"),
    "table1_tiny": Setup("cpu", "shape_metrics", "parts16", model="tmnet_tiny.yaml"),
    "table1_lora": Setup("cpu", "shape_metrics", "parts16", before=("table1_tiny",), base="radar_diffusion_parts_cpu"),
    "rollsym_tiny": Setup("cpu", "profile_metrics", "frusta16", model="profile_unet_tiny.yaml"),
    "table1_medium": Setup("cpu", "shape_metrics", "parts64", model="sdf_vae_medium.yaml", tiny_points=True),
    "table1_real": Setup("cpu", "shape_metrics", "parts64", model="sdf_vae_medium.yaml", tiny_points=True),
    "rollsym_medium": Setup("cpu", "profile_metrics", "frusta32x64", model="profile_unet_medium.yaml"),
    "sdf_vae_parts": Setup("gpu", "shape_metrics", "parts16", tiny_points=True),  # Stage 1 reads no radar
    "sdf_vae_frusta": Setup("gpu", "shape_metrics", "frusta16", tiny_points=True),
    "radar_diffusion_parts": Setup("gpu", "shape_metrics", "parts64", stage1="sdf_vae_parts", tiny_points=True),
    "table1_paper": Setup("gpu", "shape_metrics", "parts64", model="tmnet.yaml", tiny_points=True),
    "rollsym_paper": Setup("gpu", "profile_metrics", "frusta32x64", model="profile_unet.yaml"),
}
EXPERIMENTS = sorted(p.stem for p in (CONF / "experiment").glob("*.yaml"))
# One step of these takes 40-80 s on 2 CPU cores (ResNet-152 encoders, ~700 MB checkpoints with the
# optimiser state); their model files are built in the default suite by test_model_file_builds_...
SLOW_FITS = {"radar_diffusion_parts", "table1_paper"}


def layers(name: str, trainer: str | None = None) -> list[str]:
    """The --config files of experiment ``name``, in order (``trainer`` replaces its trainer layer)."""
    setup = SETUPS[name]
    files = [CONF / "trainer" / f"{trainer or setup.trainer}.yaml"]
    if setup.callbacks:
        files.append(CONF / "callbacks" / f"{setup.callbacks}.yaml")
    files += [CONF / "experiment" / f"{n}.yaml" for n in (*setup.before, name)]
    return [str(f) for f in files]


class Runs:
    """Datasets and one-step fits made once per session (two-stage runs reuse their Stage 1)."""

    def __init__(self, root: Path):
        self.root = root
        self.datasets: dict[str, Path] = {}
        self.fits: dict[str, Path] = {}

    def dataset(self, name: str) -> Path:
        if name not in self.datasets:
            config_name, radar = DATASETS[name]
            config = load_build_config(CONF / "data" / config_name, num=5)
            if radar is not None:
                config = replace(config, radar=radar)
            build_dataset(config, self.root / "data" / name, progress=False)
            self.datasets[name] = self.root / "data" / name
        return self.datasets[name]

    def fit(self, name: str) -> Path:
        """The checkpoint of one training step of experiment ``name`` (run on CPU)."""
        if name in self.fits:
            return self.fits[name]
        setup = SETUPS[name]
        run_dir = self.root / "runs" / name
        args = ["fit", *(f"--config={c}" for c in layers(name, trainer="cpu")),
                "--trainer.max_steps=1", "--trainer.max_epochs=1", "--trainer.limit_val_batches=0",
                "--trainer.num_sanity_val_steps=0", f"--trainer.default_root_dir={run_dir}"]
        if setup.model:
            args.append(f"--model={CONF / 'model' / setup.model}")
        if setup.stage1:
            args.append(f"--model.init_args.stage1_ckpt={self.fit(setup.stage1)}")
        if setup.base:
            args.append(f"--model.init_args.base_ckpt={self.fit(setup.base)}")
        if setup.data:
            args += [f"--data.init_args.root={self.dataset(setup.data)}", "--data.init_args.batch_size=2",
                     "--data.init_args.num_workers=0"]
        if setup.tiny_points:
            args.append(f"--data.init_args.points={TINY_POINTS}")
        assert main(args) == 0, args
        checkpoints = sorted(run_dir.rglob("*.ckpt"))
        assert checkpoints, f"{name}: no checkpoint under {run_dir}"
        self.fits[name] = checkpoints[-1]
        return checkpoints[-1]


@pytest.fixture(scope="session")
def runs(tmp_path_factory) -> Runs:
    return Runs(tmp_path_factory.mktemp("configs"))


def model_file(name: str) -> Path | None:
    """The conf/model file experiment ``name`` trains (its own ``model:`` or the test's choice)."""
    setup = SETUPS[name]
    if setup.model:
        return CONF / "model" / setup.model
    for experiment in (name, *setup.before[::-1]):
        value = yaml.safe_load((CONF / "experiment" / f"{experiment}.yaml").read_text()).get("model")
        if isinstance(value, str):
            return (CONF / "experiment" / value).resolve()
    return None


def test_every_experiment_has_a_setup():
    assert set(SETUPS) == set(EXPERIMENTS)


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_experiment_header_documents_its_layers(name):
    header = "".join(line for line in (CONF / "experiment" / f"{name}.yaml").read_text().splitlines(True)
                     if line.startswith("#"))
    setup = SETUPS[name]
    assert f"--config conf/trainer/{setup.trainer}.yaml" in header
    if setup.callbacks:
        assert f"--config conf/callbacks/{setup.callbacks}.yaml" in header
    assert "docs/configs.md" in header


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_experiment_layers_parse_with_their_own_trainer(name, capsys):
    """The documented command (GPU trainer for paper-size runs) parses; trainer keys come from the layers."""
    with pytest.raises(SystemExit) as exit_info:
        main(["fit", *(f"--config={c}" for c in layers(name)), "--print_config"])
    assert exit_info.value.code in (0, None)
    printed = yaml.safe_load(capsys.readouterr().out)
    trainer = yaml.safe_load((CONF / "trainer" / f"{SETUPS[name].trainer}.yaml").read_text())["trainer"]
    experiment = yaml.safe_load((CONF / "experiment" / f"{name}.yaml").read_text()).get("trainer") or {}
    for key, value in trainer.items():
        assert printed["trainer"][key] == experiment.get(key, value), key
    if "max_epochs" in experiment:
        assert printed["trainer"]["max_epochs"] == experiment["max_epochs"]
    if SETUPS[name].callbacks:
        classes = [c["class_path"] for c in printed["trainer"]["callbacks"]]
        assert classes[:2] == ["lightning.pytorch.callbacks.ModelCheckpoint",
                               "radar2shape.metrics.ReconstructionEvaluator"]


def test_cpu_bf16_layer_turns_on_autocast_over_the_cpu_trainer(capsys):
    """conf/trainer/cpu_bf16.yaml after cpu.yaml: Lightning's bf16-mixed on the CPU, the rest of cpu.yaml kept."""
    files = layers("sdf_vae_parts_cpu")
    assert files[0].endswith("conf/trainer/cpu.yaml")
    with pytest.raises(SystemExit) as exit_info:
        main(["fit", f"--config={files[0]}", f"--config={CONF / 'trainer' / 'cpu_bf16.yaml'}",
              *(f"--config={c}" for c in files[1:]), "--print_config"])
    assert exit_info.value.code in (0, None)
    printed = yaml.safe_load(capsys.readouterr().out)["trainer"]
    assert (printed["precision"], printed["accelerator"], printed["log_every_n_steps"]) == ("bf16-mixed", "cpu", 5)


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_FITS else n
                                  for n in EXPERIMENTS])
def test_experiment_fits_one_step_and_saves_a_loadable_checkpoint(name, runs):
    checkpoint = torch.load(runs.fit(name), map_location="cpu", weights_only=True)
    assert checkpoint["global_step"] == 1
    path = model_file(name)
    if path is not None:  # the checkpoint holds the model file's hyperparameters
        expected = yaml.safe_load(path.read_text())["init_args"]
        hparams = checkpoint["hyper_parameters"]
        for key, value in expected.items():
            if key.endswith("_ckpt"):
                continue
            assert hparams[key] == (list(value) if isinstance(value, tuple) else value), (name, key)


# ---- model files ---------------------------------------------------------------------------------

MODELS = sorted(p.name for p in (CONF / "model").glob("*.yaml"))
NEEDS_CHECKPOINT = {"lora_radar_diffusion.yaml"}  # built by the experiment tests from a trained Stage 2
STAGE1 = {"radar_diffusion.yaml": "sdf_vae.yaml", "radar_diffusion_cpu.yaml": "sdf_vae_cpu.yaml",
          "diffusion_sdf.yaml": "diffusion_sdf_vae.yaml", "diffusion_sdf_tiny.yaml": "diffusion_sdf_vae_tiny.yaml",
          "radar_diffusion_medium.yaml": "sdf_vae_medium.yaml", "diffusion_sdf_medium.yaml": "diffusion_sdf_vae_medium.yaml"}


def model_class(spec: dict):
    module, _, name = spec["class_path"].rpartition(".")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize("name", MODELS)
def test_model_file_builds_the_class_it_names(name):
    spec = yaml.safe_load((CONF / "model" / name).read_text())
    cls = model_class(spec)
    assert set(spec) == {"class_path", "init_args"}
    parameters = inspect.signature(cls).parameters
    forwards = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values())
    unknown = set() if forwards else set(spec["init_args"]) - set(parameters)
    assert not unknown, f"{name}: {cls.__name__} has no parameter(s) {sorted(unknown)}"
    if name in NEEDS_CHECKPOINT:
        return
    extra = {}
    if name in STAGE1:  # a Stage 2 rebuilds its Stage 1 from hyperparameters, as when a checkpoint loads
        stage1 = yaml.safe_load((CONF / "model" / STAGE1[name]).read_text())
        extra["stage1_hparams"] = dict(model_class(stage1)(**stage1["init_args"]).hparams)
    model = cls(**spec["init_args"], **extra)
    assert type(model) is cls
    for key, value in spec["init_args"].items():
        if not key.endswith("_ckpt"):
            assert model.hparams[key] == value, (name, key)


@pytest.mark.parametrize("cpu, paper", [("sdf_vae_cpu.yaml", "sdf_vae.yaml"),
                                        ("radar_diffusion_cpu.yaml", "radar_diffusion.yaml")])
def test_cpu_model_files_are_differences_from_the_paper_file(cpu, paper):
    """A _cpu file lists only what differs; the rest comes from the class defaults, which the paper file
    spells out in full, so the CPU model is the paper file with the _cpu keys changed."""
    cpu_spec, paper_spec = (yaml.safe_load((CONF / "model" / n).read_text()) for n in (cpu, paper))
    assert cpu_spec["class_path"] == paper_spec["class_path"]
    defaults = {k: p.default for k, p in inspect.signature(model_class(paper_spec)).parameters.items()}
    for key, value in paper_spec["init_args"].items():
        assert defaults[key] == value, f"{paper}: {key} = {value!r} but the class default is {defaults[key]!r}"
    changed = {k: v for k, v in cpu_spec["init_args"].items() if paper_spec["init_args"].get(k) != v}
    assert set(changed) == set(cpu_spec["init_args"]) - {"stage1_ckpt"}, "a _cpu file repeats a paper value"


# ---- data build configs, DataModule sections, radar grids ------------------------------------------

DATA_CONFIGS = sorted(p.name for p in (CONF / "data").glob("*.yaml"))


def _with_real_roots(path, text, root, out):
    """A copy of a real-target config whose every source root is ``root``."""
    raw = yaml.safe_load(text)
    for source in raw["family_options"]["sources"]:
        source["root"] = str(root)
    raw["radar"] = str(CONF.parent / raw["radar"]) if not Path(raw["radar"]).is_absolute() else raw["radar"]
    out.write_text(yaml.safe_dump(raw))
    return out


@pytest.mark.parametrize("name", DATA_CONFIGS)
def test_data_config_loads_and_checks(name, tmp_path):
    import trimesh

    path = CONF / "data" / name
    text = path.read_text()
    if "PATH/TO/MESHES" in text:  # folder configs: a real folder in place of the placeholder
        (tmp_path / "meshes").mkdir()
        trimesh.creation.box().export(tmp_path / "meshes" / "box.off")
        with pytest.raises(UserInputError, match="folder.root: .*PATH/TO/MESHES is not a directory"):
            load_build_config(path)
        path = tmp_path / name
        path.write_text(text.replace("PATH/TO/MESHES", str(tmp_path / "meshes")))
    if yaml.safe_load(text)["family"] == "real":  # sources fetched by `make data-real`: empty stand-ins
        missing = tmp_path / "not-fetched"
        with pytest.raises(UserInputError, match=r"real.sources\[0\].root: .*not-fetched is not a directory .*make data-real"):
            load_build_config(_with_real_roots(path, text, missing, tmp_path / "missing.yaml"))
        (tmp_path / "src").mkdir()
        path = _with_real_roots(path, text, tmp_path / "src", tmp_path / name)
    raw = yaml.safe_load(text)
    config = load_build_config(path)
    assert config.family == raw["family"] and config.num == raw.get("num") and config.seed == raw.get("seed", 0)
    assert config.simulator == (raw.get("simulator") or {})
    counts = {k: v for k, v in (raw.get("sampling") or {}).items() if isinstance(v, int)}
    assert {k: getattr(config.sampling, k) for k in counts} == counts
    assert config.radar["freq_ghz"]["count"] == (64 if "conf/radar/default.yaml" in str(raw.get("radar")) else 16)


def test_sbr_twins_differ_from_their_po_config_only_in_the_simulator():
    for po, sbr in (("parts.yaml", "parts_sbr.yaml"), ("parts_tiny.yaml", "parts_tiny_sbr.yaml")):
        po_dict, sbr_dict = (load_build_config(CONF / "data" / n).to_dict() for n in (po, sbr))
        assert sbr_dict["simulator"]["method"] == "sbr" and po_dict["simulator"] == {}
        assert {**sbr_dict, "simulator": {}} == po_dict


def test_real_variants_config_is_real_plus_variants():
    real, variants = (yaml.safe_load((CONF / "data" / n).read_text()) for n in ("real.yaml", "real_variants.yaml"))
    assert variants["family_options"].pop("variants") == {"per_object": 1, "scale": [0.8, 1.25]}
    assert variants == real  # so data/real's records are its originals' (Makefile: data-real-variants)


MODULES = sorted(p.name for p in (CONF / "data" / "module").glob("*.yaml"))


@pytest.mark.parametrize("name", MODULES)
def test_datamodule_file_builds_on_tiny_data(name, runs):
    spec = yaml.safe_load((CONF / "data" / "module" / name).read_text())
    cls = model_class(spec)
    data = runs.dataset("frusta16" if cls.__name__ == "ProfileDataModule" else "parts16")
    module = cls(**{**spec["init_args"], "root": str(data), "num_workers": 0})
    module.setup("fit")
    batch = next(iter(module.train_dataloader()))
    assert batch["radar"].shape[0] == min(spec["init_args"]["batch_size"], 3)  # 3 train shapes of 5
    for key, value in spec["init_args"].items():
        if key not in ("root", "num_workers"):
            stored = module.hparams[key]
            assert (list(stored) if isinstance(stored, tuple) else stored) == value, (name, key)


@pytest.mark.parametrize("name, shape", [("default.yaml", (32, 32, 64)), ("tiny.yaml", (16, 16, 16))])
def test_radar_grid_files(name, shape):
    from radar2shape.radar import RadarGrid

    grid = RadarGrid.from_yaml(CONF / "radar" / name)
    assert grid.shape == shape and grid.size_m == 1.0
    assert grid.freq_hz[0] == pytest.approx(8e9) and grid.freq_hz[-1] == pytest.approx(12e9)
    assert re.search(r"roll_deg: \{.*endpoint: false\}", (CONF / "radar" / name).read_text())


def test_every_radar_file_is_tested():
    assert sorted(p.name for p in (CONF / "radar").glob("*.yaml")) == ["default.yaml", "tiny.yaml"]
