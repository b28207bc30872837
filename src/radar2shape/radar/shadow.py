"""Which facets the radar sees: back-face culling plus Embree occlusion rays.

Back-face culling alone is exact only for convex bodies. For every front-facing facet that is not
on a supporting plane of the mesh, one ray leaves the centroid (offset along the normal) toward
the radar; if anything blocks it, the whole facet is in shadow (the usual facet-level PO rule).
Rays of a whole direction chunk go to Embree in one call: per-call overhead dominates otherwise.
"""

from __future__ import annotations

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from radar2shape.radar.facets import FacetMesh


class Occluder:
    """An Embree scene of the facets (float32, local coordinates) answering occlusion queries."""

    def __init__(self, facets: FacetMesh):
        self.facets = facets
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, facets.vertices.astype(np.float32)[facets.faces])

    def visible(self, directions: np.ndarray, front: np.ndarray) -> np.ndarray:
        """``front`` [F, D] (n.u > 0) with the facets whose ray toward u is blocked removed."""
        test = front & ~self.facets.supported[:, None]
        f_idx, d_idx = np.nonzero(test)
        if len(d_idx) == 0:
            return front
        origins = self.facets.ray_origins[f_idx]
        dirs = directions.astype(np.float32)[d_idx]
        blocked = self.scene.run(origins, dirs, query="OCCLUDED") == 0  # embreex: 0 hit, -1 clear
        out = front.copy()
        out[f_idx[blocked], d_idx[blocked]] = False
        return out
