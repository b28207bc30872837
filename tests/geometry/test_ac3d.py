"""The AC3D reader on small files written here: exact vertices, face counts, skipped surfaces."""

import numpy as np
import pytest

from radar2shape.geometry.ac3d import read_ac3d
from radar2shape.geometry.mesh_io import MeshError, load_mesh
from radar2shape.geometry.repair import is_solid, signed_volume

CUBE = """AC3Db
MATERIAL "grey" rgb 0.5 0.5 0.5  amb 0.2 0.2 0.2  emis 0 0 0  spec 0 0 0  shi 10  trans 0
OBJECT world
kids 1
OBJECT poly
name "cube"
data 9
kids 5
xy
texture "cube.png"
crease 30.0
numvert 8
0 0 0
1 0 0
1 1 0
0 1 0
0 0 1
1 0 1
1 1 1
0 1 1
numsurf 8
SURF 0x10
mat 0
refs 4
0 0 0
3 0 1
2 1 1
1 1 0
SURF 0x30
mat 0
refs 4
4 0 0
5 1 0
6 1 1
7 0 1
SURF 0x20
mat 0
refs 4
0 0 0
1 1 0
5 1 1
4 0 1
SURF 0x0
mat 0
refs 4
3 0 0
7 0 1
6 1 1
2 1 0
SURF 0x0
mat 0
refs 4
0 0 0
4 0 1
7 1 1
3 1 0
SURF 0x0
mat 0
refs 4
1 0 0
2 1 0
6 1 1
5 0 1
SURF 0x2
mat 0
refs 2
0 0 0
6 1 1
SURF 0x1
mat 0
refs 3
1 0 0
2 0 0
3 0 0
kids 0
"""

# A group turned a quarter about z (rot read row by row: x -> y, y -> -x) and moved by 10 along x,
# holding a triangle moved by 1 along y: vertex v lands at rot @ (v + (0, 1, 0)) + (10, 0, 0).
NESTED = """AC3Db
OBJECT world
kids 1
OBJECT group
name "arm"
loc 10 0 0
rot 0 -1 0 1 0 0 0 0 1
kids 1
OBJECT poly
name "blade"
loc 0 1 0
numvert 3
1 0 0
0 1 0
0 0 1
numsurf 1
SURF 0x10
refs 3
0 0 0
1 0 0
2 0 0
kids 0
"""


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_cube_quads_become_a_closed_unit_cube_and_lines_are_skipped(tmp_path):
    mesh = read_ac3d(write(tmp_path, "cube.ac", CUBE))
    assert len(mesh.faces) == 12  # six quads fanned into two triangles each; the two line surfaces add none
    assert mesh.metadata["ac3d_skipped"]["lines"] == 2
    assert np.array_equal(np.unique(mesh.vertices, axis=0), np.array([[x, y, z] for x in (0, 1) for y in (0, 1)
                                                                      for z in (0, 1)], dtype=float))
    assert mesh.area == pytest.approx(6.0)
    assert signed_volume(mesh) == pytest.approx(1.0)  # outward winding kept by the fan
    loaded = load_mesh(tmp_path / "cube.ac")  # the ordinary loader dispatches .ac here
    assert is_solid(loaded) and len(loaded.vertices) == 8


def test_nested_loc_and_rot_are_applied_down_the_tree(tmp_path):
    mesh = read_ac3d(write(tmp_path, "nested.ac", NESTED))
    expected = np.array([[9.0, 1.0, 0.0], [8.0, 0.0, 0.0], [9.0, 0.0, 1.0]])  # worked by hand, see NESTED
    assert np.allclose(mesh.vertices, expected, atol=1e-12)
    assert mesh.faces.tolist() == [[0, 1, 2]]


def test_triangle_strip_and_missing_children(tmp_path):
    text = ("AC3Db\nOBJECT world\nkids 3\nOBJECT poly\nnumvert 4\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n"
            "numsurf 1\nSURF 0x4\nrefs 4\n0 0 0\n1 0 0\n2 0 0\n3 0 0\nkids 0\n")  # announces 3 kids, holds 1
    mesh = read_ac3d(write(tmp_path, "strip.ac", text))
    assert mesh.faces.tolist() == [[0, 1, 2], [2, 1, 3]]  # alternate triangles keep one winding
    assert mesh.metadata["ac3d_skipped"]["missing_kids"] == 1


@pytest.mark.parametrize("text, match", [
    ("solid x\n", "not an AC3D"),
    ("AC3Db\nOBJECT world\nkids 1\nOBJECT poly\nnumvert 2\n0 0 0\n", "file ends"),
    ("AC3Db\nOBJECT world\nkids 1\nOBJECT poly\nnumvert 1\n0 0 zero\nkids 0\n", "3 numbers"),
    ("AC3Db\nOBJECT world\nkids 1\nOBJECT poly\nnumvert 3\n0 0 0\n1 0 0\n0 1 0\nnumsurf 1\nSURF 0x0\nrefs 3\n"
     "0 0 0\n1 0 0\n7 0 0\nkids 0\n", "vertex 7 of 3"),
    ("AC3Db\nOBJECT world\nkids 1\nOBJECT poly\nnumvert 2\n0 0 0\n1 0 0\nnumsurf 1\nSURF 0x2\nrefs 2\n0 0 0\n"
     "1 0 0\nkids 0\n", "no polygon"),
])
def test_bad_files_raise_one_mesh_error(tmp_path, text, match):
    with pytest.raises(MeshError, match=match):
        read_ac3d(write(tmp_path, "bad.ac", text))
