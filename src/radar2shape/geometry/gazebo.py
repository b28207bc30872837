"""Reading COLLADA files with their unit and up axis, and Gazebo models assembled from ``model.sdf``.

trimesh reads COLLADA (with the optional ``pycollada`` package) and applies the node transforms,
but keeps the file's ``<unit meter=...>`` only as metadata and ignores ``<up_axis>``; a Gazebo
model of a bus in inches would then be 39 times too large and a Y_UP file lie on its side. Here
the unit scales the vertices to metres and the up axis is turned onto +z (``geometry.frames``).

A Gazebo model is one object made of parts: every ``<visual>`` of every ``<link>`` is placed by
the model, link and visual ``<pose>`` (``x y z roll pitch yaw``, metres and radians, rotation
``Rz(yaw) Ry(pitch) Rx(roll)``), with its mesh ``<scale>``; box, cylinder and sphere visuals are
built from their sizes. Several visuals that name ``<submesh>`` pieces of one file take the file
once (its pieces are already placed in it); a piece asked to be re-centred (``<center>true``)
cannot be placed without the piece split and is left out. Collision geometry is not read.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import trimesh

from radar2shape.geometry.frames import up_rotation
from radar2shape.errors import MeshError

_UP = {"X_UP": "x", "Y_UP": "y", "Z_UP": "z"}


class _Quiet:
    """Raise a logger's level to ERROR while reading, restoring it after."""

    def __init__(self, name: str):
        self.logger = logging.getLogger(name)

    def __enter__(self):
        self.level = self.logger.level
        self.logger.setLevel(logging.ERROR)

    def __exit__(self, *exc):
        self.logger.setLevel(self.level)


def _strip_namespaces(root: ET.Element) -> ET.Element:
    for element in root.iter():
        if isinstance(element.tag, str) and "}" in element.tag:
            element.tag = element.tag.split("}", 1)[1]
    return root


def collada_asset(path: str | Path) -> tuple[float, str]:
    """``(metres per unit, up axis)`` of a COLLADA file's ``<asset>`` (defaults: 1.0 and z)."""
    try:
        root = _strip_namespaces(ET.parse(path).getroot())
    except (ET.ParseError, OSError) as err:
        raise MeshError(f"{path}: not a readable COLLADA file ({err})") from err
    unit = root.find("asset/unit")
    up = root.findtext("asset/up_axis", default="Z_UP").strip().upper()
    meters = float(unit.get("meter", "1")) if unit is not None else 1.0
    if not (np.isfinite(meters) and meters > 0):
        raise MeshError(f"{path}: <unit meter={meters}> is not a positive length")
    return meters, _UP.get(up, "z")


def load_collada(path: str | Path) -> trimesh.Trimesh:
    """A COLLADA file as one mesh in metres, z up."""
    try:
        import collada  # noqa: F401  (trimesh's COLLADA reader needs it)
    except ImportError:
        raise MeshError(f"{path}: reading COLLADA needs the pycollada package (pip install pycollada)") from None
    meters, up = collada_asset(path)
    quiet = _Quiet("trimesh")  # textures are absent and not geometry: no warning per missing image
    try:
        with quiet, open(path, "rb") as stream:
            loaded = trimesh.load(stream, file_type="dae", force="mesh", process=False)
    except Exception as err:  # pycollada raises many types for malformed files
        raise MeshError(f"{path}: cannot be read as COLLADA ({type(err).__name__}: {err})") from err
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f"{path}: holds no triangles")
    vertices = np.asarray(loaded.vertices, dtype=np.float64) * meters @ up_rotation(up).T
    return trimesh.Trimesh(vertices, np.asarray(loaded.faces), process=False)


def pose_matrix(text: str | None) -> np.ndarray:
    """4x4 transform of an SDF pose ``x y z roll pitch yaw`` (empty: identity)."""
    values = [float(v) for v in (text or "").split()] or [0.0] * 6
    if len(values) != 6:
        raise MeshError(f"pose {text!r}: expected six numbers x y z roll pitch yaw")
    x, y, z, roll, pitch, yaw = values
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    matrix = np.eye(4)
    matrix[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                      [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                      [-sp, cp * sr, cp * cr]]
    matrix[:3, 3] = x, y, z
    return matrix


def _load_part(path: Path) -> trimesh.Trimesh:
    if path.suffix.lower() == ".dae":
        return load_collada(path)
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as err:
        raise MeshError(f"{path}: cannot be read as a mesh ({type(err).__name__}: {err})") from err
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f"{path}: holds no triangles")
    return loaded


def _primitive(geometry: ET.Element) -> trimesh.Trimesh | None:
    if (box := geometry.find("box")) is not None:
        return trimesh.creation.box([float(v) for v in box.findtext("size", "1 1 1").split()])
    if (cylinder := geometry.find("cylinder")) is not None:
        return trimesh.creation.cylinder(float(cylinder.findtext("radius", "1")), float(cylinder.findtext("length", "1")),
                                         sections=24)
    if (sphere := geometry.find("sphere")) is not None:
        return trimesh.creation.icosphere(2, float(sphere.findtext("radius", "1")))
    return None


def _mesh_file(uri: str, model_dir: Path) -> Path:
    """``model://NAME/rest`` -> the file in the model database beside ``model_dir``."""
    uri = uri.strip()
    if uri.startswith("model://"):
        name, _, rest = uri[len("model://"):].partition("/")
        return model_dir.parent / name / rest
    return model_dir / uri.removeprefix("file://")


def load_gazebo_model(model_dir: str | Path) -> tuple[trimesh.Trimesh, dict]:
    """The model's visuals as one mesh in metres (Gazebo frame: z up, x forward) and a parts report.

    Without a ``model.sdf`` every mesh file in ``meshes/`` is taken as placed. Raises
    :class:`MeshError` when no part can be read.
    """
    model_dir = Path(model_dir)
    sdf = model_dir / "model.sdf"
    parts: list[trimesh.Trimesh] = []
    report = {"parts": 0, "missing": [], "centred_submesh": 0}
    if not sdf.is_file():
        files = sorted(p for p in (model_dir / "meshes").glob("*") if p.suffix.lower() in (".dae", ".obj", ".stl"))
        parts = [_load_part(p) for p in files]
    else:
        try:
            root = _strip_namespaces(ET.parse(sdf).getroot())
        except ET.ParseError as err:
            raise MeshError(f"{sdf}: not readable XML ({err})") from err
        seen: set[tuple[str, str]] = set()
        for model in root.iter("model"):
            model_pose = pose_matrix(model.findtext("pose"))
            for link in model.findall("link"):
                link_pose = model_pose @ pose_matrix(link.findtext("pose"))
                for visual in link.findall("visual"):
                    geometry = visual.find("geometry")
                    if geometry is None:
                        continue
                    transform = link_pose @ pose_matrix(visual.findtext("pose"))
                    mesh = geometry.find("mesh")
                    if mesh is None:
                        part = _primitive(geometry)
                    else:
                        submesh = mesh.find("submesh")
                        if submesh is not None and submesh.findtext("center", "false").strip() == "true":
                            report["centred_submesh"] += 1
                            continue
                        key = (mesh.findtext("uri", ""), mesh.findtext("scale", "1 1 1"))
                        if submesh is not None and key in seen:
                            continue
                        seen.add(key)
                        path = _mesh_file(key[0], model_dir)
                        if not path.is_file():
                            report["missing"].append(key[0])
                            continue
                        part = _load_part(path)
                        scale = [float(v) for v in key[1].split()]
                        part = trimesh.Trimesh(np.asarray(part.vertices) * scale, part.faces, process=False)
                    if part is not None:
                        part = part.copy()
                        part.apply_transform(transform)
                        parts.append(part)
    if not parts:
        raise MeshError(f"{model_dir}: no visual part could be read (missing: {report['missing'] or 'none'})")
    report["parts"] = len(parts)
    return trimesh.util.concatenate(parts), report
