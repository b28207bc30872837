"""The models shipped inside the package, and the export that makes a training checkpoint shippable.

Two RadarDiffusion models (Stage 2, each holding its Stage-1 weights) on the default radar grid
(conf/radar/default.yaml) ship in ``weights/``, named in :data:`SHIPPED_MODELS`: ``parts``, trained
on the procedural parts family, and ``real``, trained on real aircraft, ships, vehicles and
buildings (``make data-real``). ``radar2shape reconstruct`` without ``--ckpt`` uses ``--model``
(default :data:`DEFAULT_NAME`, whose file is :data:`DEFAULT_MODEL`). A training checkpoint also carries optimizer moments, loop and callback
states and the DataModule's settings, which inference never reads and which roughly triple its
size; :func:`export_checkpoint` keeps only what ``LightningModule.load_from_checkpoint`` and
:func:`load_model` reads, so the shipped file stays small and loads exactly like
the original. torch is imported only inside the functions: the reconstruct parser names
:data:`DEFAULT_MODEL` in its help before any heavy import.
"""

from __future__ import annotations

import io
from pathlib import Path

from radar2shape.atomic import check_output_path, write_bytes_atomic
from radar2shape.errors import UserInputError

__all__ = ["DEFAULT_MODEL", "DEFAULT_NAME", "SHIPPED_MODELS", "EXPORT_KEYS", "DTYPES", "export_checkpoint",
           "default_checkpoint", "shipped_checkpoint", "card_path", "load_model", "model_card", "size_mb"]

# Plain files next to this module (not importlib.resources): torch.load needs a real path, and
# setuptools installs packages unzipped, so the path is a file for editable and regular installs.
WEIGHTS = Path(__file__).resolve().parent / "weights"
SHIPPED_MODELS = {"parts": WEIGHTS / "radar2shape_parts_medium.ckpt", "real": WEIGHTS / "radar2shape_real.ckpt"}
DEFAULT_NAME = "parts"
DEFAULT_MODEL = SHIPPED_MODELS[DEFAULT_NAME]
# Each model's card, written by `make results` (radar2shape.reporting.results).
MODEL_CARDS = {"parts": WEIGHTS / "MODEL_CARD.md", "real": WEIGHTS / "MODEL_CARD_real.md"}
MODEL_CARD = MODEL_CARDS[DEFAULT_NAME]

RADAR_DIFFUSION = "radar2shape.models.radar_diffusion.RadarDiffusion"
RADAR_SPEC_KEY = "radar_spec"  # = models.base.RADAR_SPEC_KEY (not imported: it needs Lightning)

# What loading reads: the weights, the constructor arguments (and how Lightning stored them), the
# radar spec, and the version Lightning's checkpoint migration keys on. epoch and global_step are
# two integers kept as provenance (how long the shipped model trained).
EXPORT_KEYS = ("state_dict", "hyper_parameters", "hparams_name", "hparams_type", RADAR_SPEC_KEY,
               "pytorch-lightning_version", "epoch", "global_step")

# Storage precisions for the exported weights; the model is rebuilt in float32 on load either way.
DTYPES = ("float32", "float16", "bfloat16")

BYTES_PER_MB = 1_000_000


def size_mb(n_bytes: int) -> float:
    """Megabytes (10^6 bytes), the unit of the shipped-size limit."""
    return n_bytes / BYTES_PER_MB


def _check_radar_diffusion(path: Path, hparams: dict, label: str) -> None:
    """Refuse anything but a RadarDiffusion (or subclass): only Stage 2 reconstructs a mesh alone.

    A checkpoint written by ``radar2shape fit`` names its class (``_class_path``); one saved
    without the Lightning CLI does not, and is recognised by ``stage1_hparams``, which every
    RadarDiffusion stores (a Stage-1 SDFVAE or a profile model has none).
    """
    import importlib

    from radar2shape.models.radar_diffusion import RadarDiffusion

    class_path = hparams.get("_class_path")
    if class_path is None:
        if "stage1_hparams" not in hparams:
            raise UserInputError(f"{label}: {path} holds a model without Stage-1 hyperparameters (a Stage-1 SDFVAE "
                                 "or another model); expected a RadarDiffusion (Stage 2) checkpoint")
        return
    module, _, name = str(class_path).rpartition(".")
    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError) as err:
        raise UserInputError(f"{label}: {path} names model class {class_path!r}, which cannot be imported "
                             f"({err}); expected a RadarDiffusion (Stage 2) checkpoint") from err
    if not (isinstance(cls, type) and issubclass(cls, RadarDiffusion)):
        raise UserInputError(f"{label}: {path} holds a {class_path}; expected a RadarDiffusion (Stage 2) checkpoint")


def _read_source(src: Path, label: str) -> dict:
    """The source checkpoint, checked: a RadarDiffusion that stores its radar spec."""
    from radar2shape.checkpoints import load_checkpoint
    from radar2shape.radar.spec import RadarSpec

    checkpoint = load_checkpoint(src, "a RadarDiffusion checkpoint", label=label)
    hparams = checkpoint["hyper_parameters"]
    if not isinstance(hparams, dict):
        raise UserInputError(f"{label}: {src}: 'hyper_parameters' is a {type(hparams).__name__}, expected a dict "
                             "(not a RadarDiffusion checkpoint)")
    _check_radar_diffusion(src, hparams, label)
    if checkpoint.get(RADAR_SPEC_KEY) is None:
        raise UserInputError(f"{label}: {src} stores no radar spec (not fitted on a radar DataModule, or saved "
                             "before checkpoints stored one); export a checkpoint written by 'radar2shape fit'")
    RadarSpec.from_dict(checkpoint[RADAR_SPEC_KEY], f"{label}: {src}: {RADAR_SPEC_KEY}")  # a broken spec: one line
    return checkpoint


def _cast_weights(state_dict: dict, dtype: str | None) -> dict:
    """Floating-point tensors stored in ``dtype`` (None: unchanged); integer and bool buffers kept.

    Every tensor is cloned, so a view of a larger storage is not saved with its whole base.
    """
    import torch

    target = None if dtype is None else getattr(torch, dtype)
    out = {}
    for key, value in state_dict.items():
        if isinstance(value, torch.Tensor):
            value = value.detach().clone()
            if target is not None and value.is_floating_point():
                value = value.to(target)
        out[key] = value
    return out


def minimal_checkpoint(checkpoint: dict, dtype: str | None = None) -> dict:
    """The keys of ``checkpoint`` that loading reads (:data:`EXPORT_KEYS`), weights cast to ``dtype``."""
    import copy

    out = {key: copy.deepcopy(checkpoint[key]) for key in EXPORT_KEYS if key in checkpoint and key != "state_dict"}
    out["state_dict"] = _cast_weights(checkpoint["state_dict"], dtype)
    return out


def _serialise(checkpoint: dict) -> bytes:
    """The bytes ``torch.save`` writes, in memory, so the size is known before anything is written."""
    import torch

    buffer = io.BytesIO()
    torch.save(checkpoint, buffer)
    return buffer.getvalue()


def export_checkpoint(src: str | Path, dst: str | Path, dtype: str | None = None, max_mb: float | None = None,
                      surface_level: float | None = None, mesh_resolution: int | None = None,
                      *, src_label: str = "--ckpt", dst_label: str = "--out") -> float:
    """Write the inference-only copy of RadarDiffusion checkpoint ``src`` to ``dst``; returns its size in MB.

    Kept: :data:`EXPORT_KEYS` (weights, hyperparameters, radar spec, Lightning version); dropped:
    optimizer and scheduler states, loops, callbacks, DataModule settings. ``dtype`` (one of
    :data:`DTYPES`, None = as trained) stores floating-point weights in a smaller precision.
    ``max_mb`` refuses a result larger than that, before anything is written. ``surface_level``
    (None: the source's) sets the level its Stage 1 meshes (``SDFVAE.surface_level``), chosen on the
    validation split; ``mesh_resolution`` (None: the source's) its marching-cubes grid. The file is
    written atomically; a bad source, destination, option or size is one ``UserInputError`` line.
    """
    src, dst = Path(src), Path(dst)
    if dtype is not None and dtype not in DTYPES:
        raise UserInputError(f"--dtype: expected one of {', '.join(DTYPES)}, got {dtype!r}")
    if max_mb is not None and not max_mb > 0:
        raise UserInputError(f"--max-mb: expected a positive number of MB, got {max_mb}")
    if mesh_resolution is not None and mesh_resolution < 2:
        raise UserInputError(f"--mesh-resolution: expected an integer >= 2, got {mesh_resolution}")
    check_output_path(dst, dst_label, (".ckpt",))
    if dst.resolve() == src.resolve():
        raise UserInputError(f"{dst_label}: {dst} is the source checkpoint ({src_label}); expected a separate file")
    checkpoint = minimal_checkpoint(_read_source(src, src_label), dtype)
    if surface_level is not None:  # a RadarDiffusion (_read_source checks) always holds its Stage 1's hyperparameters
        checkpoint["hyper_parameters"]["stage1_hparams"]["surface_level"] = float(surface_level)
    if mesh_resolution is not None:
        checkpoint["hyper_parameters"]["mesh_resolution"] = int(mesh_resolution)
    data = _serialise(checkpoint)
    if max_mb is not None and size_mb(len(data)) > max_mb:
        raise UserInputError(f"{dst_label}: the exported model is {size_mb(len(data)):.1f} MB, over the "
                             f"{max_mb:g} MB limit (try --dtype float16 or a smaller model); nothing written")
    write_bytes_atomic(dst, data)
    return size_mb(len(data))


def _check_name(name: str, label: str) -> None:
    if name not in SHIPPED_MODELS:
        raise UserInputError(f"{label}: no shipped model named {name!r}; expected one of {', '.join(SHIPPED_MODELS)}")


def card_path(name: str = DEFAULT_NAME) -> Path:
    """Where shipped model ``name``'s card is installed."""
    _check_name(name, "--about")
    return MODEL_CARDS[name]


def model_card(name: str = DEFAULT_NAME) -> str:
    """Shipped model ``name``'s card: what it was trained on, its measured scores, what it does not know."""
    path = card_path(name)
    if not path.is_file():
        raise UserInputError(f"--about: no model card is installed for the {name} model (expected {path})")
    return path.read_text(encoding="utf-8")


def shipped_checkpoint(name: str = DEFAULT_NAME) -> Path:
    """Shipped model ``name``'s file when it is installed; otherwise one line telling the user to pass ``--ckpt``."""
    _check_name(name, "--model")
    path = Path(SHIPPED_MODELS[name])
    if not path.is_file():
        what = "--ckpt: no default model" if name == DEFAULT_NAME else f"--model {name}: no such model"
        raise UserInputError(f"{what} is installed (expected {path}); "
                             "pass --ckpt CKPT (a RadarDiffusion or profile model checkpoint)")
    return path


def default_checkpoint() -> Path:
    """The default shipped model's file, or one line telling the user to pass ``--ckpt``."""
    return shipped_checkpoint(DEFAULT_NAME)


def _model_class(path: Path, hparams: dict, label: str):
    """The checkpoint's LightningModule class: its ``_class_path`` (LightningCLI), else RadarDiffusion."""
    import importlib

    from radar2shape.models.profile_diffusion import ProfileModel
    from radar2shape.models.radar_diffusion import RadarDiffusion

    class_path = hparams.get("_class_path", RADAR_DIFFUSION)
    module, _, name = class_path.rpartition(".")
    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as err:
        raise UserInputError(f"{label}: {path} names model class {class_path!r}, which cannot be imported ({err})") from err
    if not (isinstance(cls, type) and issubclass(cls, (RadarDiffusion, ProfileModel))):
        raise UserInputError(f"{label}: {path} holds a {class_path}; expected a RadarDiffusion or a profile model")
    return cls


def load_model(path: str | Path, label: str = "--ckpt"):
    """The checkpoint's model on the CPU in eval mode, its ``radar_spec`` read from the checkpoint.

    A checkpoint without a radar spec (saved before checkpoints stored one) is refused: its
    normalisation cannot be recovered without the training data, so the model must be retrained.
    """
    from radar2shape.checkpoints import load_checkpoint
    from radar2shape.radar.spec import RadarSpec

    path = Path(path)
    checkpoint = load_checkpoint(path, "a reconstruction model checkpoint", label=label)
    hparams = checkpoint.get("hyper_parameters")
    if not isinstance(hparams, dict):
        raise UserInputError(f"{label}: {path}: 'hyper_parameters' is a {type(hparams).__name__}, expected a dict "
                             "(not a reconstruction model checkpoint)")
    cls = _model_class(path, dict(hparams), label)
    if checkpoint.get(RADAR_SPEC_KEY) is None:
        raise UserInputError(f"{label}: {path} stores no radar spec (it was saved before checkpoints stored one, "
                             "or not fitted on a radar DataModule); retrain the model")
    spec = RadarSpec.from_dict(checkpoint[RADAR_SPEC_KEY], f"{label}: {path}: {RADAR_SPEC_KEY}")
    try:
        model = cls.load_from_checkpoint(path, map_location="cpu", weights_only=True)
    except (KeyError, TypeError, ValueError, RuntimeError, AttributeError, EOFError) as err:
        raise UserInputError(f"{label}: {path} is not a reconstruction model checkpoint ({type(err).__name__}: {err})") from err
    model.set_radar_spec(spec)  # checked against the network: a spec that does not fit is refused
    return model.eval()
