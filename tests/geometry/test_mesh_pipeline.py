"""Loading, repair, simplification: every input becomes a watertight solid or a clear MeshError."""

import numpy as np
import pytest
import trimesh
from winding_reference import winding_number

from radar2shape.geometry.mesh_io import MeshError, load_mesh
from radar2shape.geometry.prepare import MeshConfig, prepare_mesh
from radar2shape.geometry.repair import is_solid, make_watertight
from radar2shape.geometry.simplify import simplify


@pytest.mark.parametrize("suffix", [".off", ".obj", ".ply", ".stl", ".glb"])
def test_formats_load_as_one_mesh(tmp_path, suffix):
    box = trimesh.creation.box(extents=[1, 2, 3])
    path = tmp_path / f"box{suffix}"
    box.export(path)
    mesh = load_mesh(path)
    assert is_solid(mesh) and mesh.volume == pytest.approx(6.0)


def test_scenes_are_merged_with_their_transforms(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(), transform=trimesh.transformations.translation_matrix([3, 0, 0]))
    scene.add_geometry(trimesh.creation.icosphere())
    scene.export(tmp_path / "scene.glb")
    mesh = load_mesh(tmp_path / "scene.glb")
    assert len(mesh.split()) == 2 and mesh.bounds[1, 0] == pytest.approx(3.5)


@pytest.mark.parametrize("content, message", [(b"this is not a mesh\n", "no triangles"), (b"OFF\n0 0 0\n", "no triangles")])
def test_unreadable_files_raise_mesh_error(tmp_path, content, message):
    path = tmp_path / "bad.obj"
    path.write_bytes(content)
    with pytest.raises(MeshError, match=message):
        load_mesh(path)


def test_nan_vertices_are_dropped_and_the_hole_repaired():
    box = trimesh.creation.box()
    vertices = box.vertices.copy()
    vertices[0] = np.nan
    mesh, step = make_watertight(trimesh.Trimesh(vertices, box.faces, process=False), resolution=48)
    assert is_solid(mesh) and step in ("fixed", "remeshed")


def test_all_nan_mesh_is_rejected():
    with pytest.raises(MeshError, match="NaN"):
        make_watertight(trimesh.Trimesh(np.full((3, 3), np.nan), [[0, 1, 2]], process=False))


def test_non_manifold_soup_is_remeshed_into_a_solid():
    a = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]])
    b = trimesh.creation.box(bounds=[[1, 1, 0], [2, 2, 1]])  # shares one edge with a: non-manifold
    rng = np.random.default_rng(0)
    soup = trimesh.util.concatenate([a, b])
    faces = soup.faces.copy()
    flip = rng.random(len(faces)) < 0.3
    faces[flip] = faces[flip][:, ::-1]
    mesh, step = make_watertight(trimesh.Trimesh(soup.vertices, np.vstack([faces, faces[:4]]), process=False), 48)
    assert is_solid(mesh)
    assert mesh.volume == pytest.approx(2.0, rel=0.1)


def test_open_sheet_becomes_a_thin_shell():
    sheet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    mesh, step = make_watertight(sheet, resolution=32)
    assert step == "remeshed" and is_solid(mesh)
    assert np.ptp(mesh.vertices[:, 2]) < 0.15


def test_overlapping_closed_parts_are_unioned():
    a = trimesh.creation.box(bounds=[[0, 0, 0], [2, 1, 1]])
    b = trimesh.creation.box(bounds=[[1, 0, 0], [3, 1, 1]])
    mesh, step = make_watertight(trimesh.util.concatenate([a, b]))
    assert step == "union" and is_solid(mesh) and mesh.volume == pytest.approx(3.0)
    points = np.random.default_rng(1).uniform([0, 0, 0], [3, 1, 1], size=(400, 3))
    from radar2shape.geometry.query import contains

    assert (contains(mesh, points) == (winding_number(mesh.vertices, mesh.faces, points) > 0.5)).mean() > 0.99


def test_simplify_meets_the_budget_and_stays_watertight():
    sphere = trimesh.creation.icosphere(subdivisions=5)  # 20480 faces
    small = simplify(sphere, 2000)
    assert 1000 <= len(small.faces) <= 2000 and is_solid(small)
    assert abs(np.linalg.norm(small.vertices, axis=1) - 1).max() < 0.02


def test_prepare_normalises_and_respects_limits():
    sphere = trimesh.creation.icosphere(subdivisions=4).apply_scale([3, 1, 1]).apply_translation([5, 0, 0])
    prepared = prepare_mesh(sphere, MeshConfig(face_budget=1000))
    lo, hi = prepared.mesh.bounds
    assert is_solid(prepared.mesh) and len(prepared.mesh.faces) <= 1000
    np.testing.assert_allclose(lo + hi, 0, atol=1e-9)
    assert (hi - lo).max() == pytest.approx(1.0)
    with pytest.raises(MeshError, match="max_input_faces"):
        prepare_mesh(sphere, MeshConfig(max_input_faces=100))


def test_turned_in_frame_is_the_turned_object_normalised_in_its_new_heading():
    """A 1 x 0.2 x 0.1 box turned 45 degrees has a bounding box (1 + 0.2) / sqrt 2 wide: normalised
    in that heading it is smaller by sqrt 2 / 1.2, which is what the placement returns; a mirror keeps
    it outward, and no turn changes nothing."""
    from radar2shape.geometry.normalise import normalise, turned_in_frame

    box = trimesh.creation.box((1.0, 0.2, 0.1))
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    quarter_eighth = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    placed = turned_in_frame(box, quarter_eighth)
    lo, hi = placed.bounds
    np.testing.assert_allclose(hi - lo, [1.0, 1.0, 0.1 * np.sqrt(2) / 1.2], atol=1e-12)
    assert placed.volume == pytest.approx(0.02 * (np.sqrt(2) / 1.2) ** 3, rel=1e-9)
    turned = box.copy().apply_transform(trimesh.transformations.rotation_matrix(np.pi / 4, (0, 0, 1)))
    np.testing.assert_allclose(placed.vertices, normalise(turned)[0].vertices, atol=1e-12)
    mirrored = turned_in_frame(box, np.diag([1.0, -1.0, 1.0]) @ quarter_eighth)
    assert mirrored.volume > 0 and mirrored.is_winding_consistent
    shifted = box.copy().apply_translation((0.1, 0.0, 0.0))  # off centre: no turn leaves it where it was,
    np.testing.assert_allclose(turned_in_frame(shifted, np.eye(3)).vertices, shifted.vertices, atol=1e-15)
    quarter = trimesh.transformations.rotation_matrix(np.pi / 2, (0, 0, 1))[:3, :3]  # a quarter turn only turns
    np.testing.assert_allclose(turned_in_frame(shifted, quarter).vertices, shifted.vertices @ quarter.T, atol=1e-12)
    # at 45 degrees: turned and scaled about the origin, its offset with it (not re-centred on its box)
    np.testing.assert_allclose(turned_in_frame(shifted, quarter_eighth).bounds.mean(axis=0),
                               np.sqrt(2) / 1.2 * quarter_eighth @ [0.1, 0.0, 0.0], atol=1e-12)
