"""Roll-symmetric metrics: IoU-S, IoU-R and MATCH-S (docs/design.md section 6; docs/rollsym.md).

The paper does not publish exact definitions, so these are ours, fixed here and tested on
hand-computed cases. All work on (r, z) profiles in normalised coordinates (unit cube, so r <= 0.5
and |z| <= 0.5 for the ground truth), closed onto the axis (``geometry.profile.canonical_profile``).

- **IoU-S** (shape): the half cross-section ``{(r, z): 0 <= r <= R(z)}`` of prediction and truth
  rasterised on one fixed grid of square cells of side ``cell`` (default 1/256) covering
  ``r in [0, extent]``, ``z in [-extent, extent]`` (default extent 0.5625: the unit cube plus
  1/16 margin, so a slightly oversized prediction is still scored); a cell belongs to a section
  when its centre lies inside the closed profile polygon. IoU = |P & T| / |P | T|. Higher is better.
- **IoU-R** (radar): both shapes revolved to meshes and simulated with the project's PO simulator
  on the dataset's aspect x frequency grid at the dataset's physical size (roll 0, which is every
  roll for a solid of revolution); each dB image ``[A, F]`` is thresholded at ``level_db``
  (default 20 dB) below its own peak and IoU is taken over the two sets of cells. It scores whether
  the prediction's strong returns (specular flashes, tip and edge returns) appear at the right
  aspects and frequencies, independently of absolute level. Higher is better.
- **MATCH-S** (matching): both profiles resampled to ``k`` points (default 256) equally spaced by
  arc length from the bottom axis point to the top axis point, point ``i`` matched with point
  ``i``; the mean Euclidean distance of the pairs, in normalised units (1 = the object's longest
  side). Lower is better.

A prediction that is missing or not a valid profile (``geometry.profile.validate_profile`` fails)
scores IoU 0; its MATCH-S is undefined, so it is ``nan`` and skipped (the metric's count drops).
"""

from __future__ import annotations

import numpy as np
import torch
from matplotlib.path import Path as PolygonPath

from radar2shape.errors import UserInputError
from radar2shape.geometry.normalise import scaled
from radar2shape.geometry.profile import canonical_profile, mesh_to_profile, profile_to_mesh, validate_profile
from radar2shape.radar import simulate, to_db

DEFAULT_CELL = 1.0 / 256
DEFAULT_EXTENT = 0.5625
DEFAULT_LEVEL_DB = 20.0
DEFAULT_MATCH_POINTS = 256


def half_section_mask(profile, cell: float = DEFAULT_CELL, extent: float = DEFAULT_EXTENT) -> np.ndarray:
    """Bool raster ``[n_z, n_r]`` of the half cross-section: True where a cell centre is inside.

    Rows run over ``z`` from ``-extent`` upwards, columns over ``r`` from 0 outwards.
    """
    polygon = PolygonPath(canonical_profile(profile))  # closed implicitly along the axis
    n_r = int(round(extent / cell))
    r = (np.arange(n_r) + 0.5) * cell
    z = -extent + (np.arange(2 * n_r) + 0.5) * cell
    rr, zz = np.meshgrid(r, z)
    inside = polygon.contains_points(np.column_stack([rr.ravel(), zz.ravel()]))
    return inside.reshape(rr.shape)


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """|a & b| / |a | b| of two bool arrays (1.0 when both are empty: nothing to disagree on)."""
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


def section_iou(pred, target, cell: float = DEFAULT_CELL, extent: float = DEFAULT_EXTENT) -> float:
    """IoU-S of two profiles (see the module docstring)."""
    return mask_iou(half_section_mask(pred, cell, extent), half_section_mask(target, cell, extent))


def arc_length_resample(profile, k: int = DEFAULT_MATCH_POINTS) -> np.ndarray:
    """``k`` points ``[k, 2]`` equally spaced by arc length along the canonical profile, both ends included."""
    points = canonical_profile(profile)
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    targets = np.linspace(0.0, s[-1], k)
    return np.column_stack([np.interp(targets, s, points[:, 0]), np.interp(targets, s, points[:, 1])])


def profile_match_distance(pred, target, k: int = DEFAULT_MATCH_POINTS) -> float:
    """MATCH-S of two profiles: mean distance of index-matched arc-length samples."""
    return float(np.linalg.norm(arc_length_resample(pred, k) - arc_length_resample(target, k), axis=1).mean())


def radar_iou(pred_db: np.ndarray, target_db: np.ndarray, level_db: float = DEFAULT_LEVEL_DB) -> float:
    """IoU of the cells within ``level_db`` of each image's own peak (images in dB, same shape)."""
    pred_db, target_db = np.asarray(pred_db), np.asarray(target_db)
    if pred_db.shape != target_db.shape:
        raise ValueError(f"radar images differ in shape: {pred_db.shape} vs {target_db.shape}")
    return mask_iou(pred_db >= pred_db.max() - level_db, target_db >= target_db.max() - level_db)


def profile_radar_db(profile, aspect_rad, freq_hz, size_m: float = 1.0, segments: int = 64,
                     floor_db: float = -100.0) -> np.ndarray:
    """dB image ``[A, F]`` of a profile's solid of revolution at roll 0, simulated at ``size_m``.

    The same path as the dataset builder: normalised mesh scaled to its physical size, PO with
    shadowing; roll 0 stands for every roll of a solid of revolution.
    """
    mesh = scaled(profile_to_mesh(profile, segments), size_m)
    return to_db(simulate(mesh, aspect_rad, [0.0], freq_hz)[:, 0], floor_db)


# ---- predictions and targets as profiles -----------------------------------------------------
def as_profiles(values) -> list[np.ndarray | None]:
    """A batch ``[B, P, 2]`` (tensor or array) or a list of ``[P_i, 2]`` arrays / None -> list."""
    if isinstance(values, torch.Tensor):
        values = values.detach().cpu().numpy()
    return [None if v is None else np.asarray(v, dtype=np.float64) for v in values]


def is_valid_profile(profile) -> bool:
    """True when ``profile`` is not None and passes ``validate_profile``."""
    if profile is None:
        return False
    try:
        validate_profile(profile)
    except UserInputError:
        return False
    return True



def predicted_profile(rec) -> np.ndarray | None:
    """A reconstruction's profile: the model's own (``rec.profile``) or the mesh's section y = 0.

    The fallback lets any model with a mesh output (e.g. the full 3D Radar2Shape) be scored; a mesh
    that is not one solid of revolution about z gives ``None`` (scored as invalid).
    """
    profile = getattr(rec, "profile", None)
    if profile is not None:
        return np.asarray(profile, dtype=np.float64)
    mesh = getattr(rec, "mesh", None)
    if mesh is None or len(mesh.faces) == 0:
        return None
    try:
        return mesh_to_profile(mesh)
    except (UserInputError, ValueError, IndexError):
        return None
