"""Independent references for geometry tests (not used by the library)."""

import numpy as np


def winding_number(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Generalised winding number (Jacobson et al. 2013): ~1 inside, ~0 outside a closed mesh.

    Sum of signed solid angles of the triangles seen from each point (Van Oosterom-Strackee),
    a reference that shares nothing with the ray-parity containment under test.
    """
    tri = vertices[faces][None] - points[:, None, None, :]  # [N, F, 3, 3]
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    numerator = np.einsum("...i,...i->...", a, np.cross(b, c))
    denominator = (la * lb * lc + np.einsum("...i,...i->...", a, b) * lc
                   + np.einsum("...i,...i->...", b, c) * la + np.einsum("...i,...i->...", c, a) * lb)
    return (2.0 * np.arctan2(numerator, denominator)).sum(axis=1) / (4.0 * np.pi)
