"""Body frame: the stated up axis goes onto +z by a proper rotation."""

import numpy as np
import pytest
import trimesh

from radar2shape.errors import UserInputError
from radar2shape.geometry.frames import UP_AXES, to_body_frame, up_rotation


def test_y_up_mesh_gets_its_y_axis_onto_z_by_a_proper_rotation():
    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    body = to_body_frame(mesh, "y")
    assert np.allclose(body.vertices, [[0, 0, 0], [1, 0, 0], [0, 0, 1], [0, -1, 0]])  # x stays, y -> z, z -> -y
    assert np.linalg.det(up_rotation("y")) == pytest.approx(1.0)
    assert body.volume == pytest.approx(mesh.volume)  # no mirror: winding and volume sign kept
    assert np.array_equal(body.faces, mesh.faces)


@pytest.mark.parametrize("up", UP_AXES)
def test_every_up_axis_maps_onto_plus_z(up):
    axis = np.zeros(3)
    axis["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    rotation = up_rotation(up)
    assert np.allclose(rotation @ axis, [0, 0, 1])
    assert np.allclose(rotation @ rotation.T, np.eye(3)) and np.linalg.det(rotation) == pytest.approx(1.0)


def test_unknown_up_is_refused():
    with pytest.raises(UserInputError, match="up: expected one of"):
        up_rotation("w")
