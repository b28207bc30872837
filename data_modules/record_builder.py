"""One shape task -> one record: generate, prepare the mesh, sample points, simulate the radar.

A record is a pure function of (build config, task): every random draw is seeded from the task,
so re-building a record, in any worker or shard, gives byte-equal arrays.
"""

from __future__ import annotations

import json

import numpy as np

from data_modules.config import BuildConfig
from radar2shape.geometry.families import Family, ShapeTask
from radar2shape.geometry.normalise import scaled
from radar2shape.geometry.prepare import prepare_mesh
from radar2shape.geometry.sampling import sample_shape
from radar2shape.radar import RadarGrid, simulate


class RecordBuilder:
    """Builds records of one config; create once per worker (family and grid are reused)."""

    def __init__(self, config: BuildConfig):
        self.config = config
        self.family: Family = config.make_family()  # data_modules families too
        self.grid = RadarGrid.from_config(config.radar)

    def radar(self, mesh) -> np.ndarray:
        """Complex response [A, R, F] of the normalised ``mesh`` at the grid's physical size.

        Roll-symmetric families are simulated at the first roll only and repeated along roll:
        exact for the ideal solid of revolution, and R times cheaper.
        """
        grid = self.grid
        roll = grid.roll_rad[:1] if self.family.roll_symmetric else grid.roll_rad
        response = simulate(scaled(mesh, grid.size_m), grid.aspect_rad, roll, grid.freq_hz, **self.config.simulator)
        shape = (len(grid.aspect_rad), len(grid.roll_rad), len(grid.freq_hz))
        return np.ascontiguousarray(np.broadcast_to(response, shape), dtype=np.complex64)

    def build(self, task: ShapeTask) -> dict[str, np.ndarray]:
        """The arrays of ``task``'s record (keys: ``data_modules.records.RECORD_KEYS``)."""
        shape = self.family.generate(task)
        prepared = prepare_mesh(shape.mesh, self.config.mesh)
        mesh = prepared.mesh
        grid = self.grid
        record = {
            "vertices": np.asarray(mesh.vertices, dtype=np.float32),
            "faces": np.asarray(mesh.faces, dtype=np.int32),
            **sample_shape(mesh, self.config.sampling, task.seed),
            "radar": self.radar(mesh),
            "aspect_rad": np.asarray(grid.aspect_rad, dtype=np.float64),
            "roll_rad": np.asarray(grid.roll_rad, dtype=np.float64),
            "freq_hz": np.asarray(grid.freq_hz, dtype=np.float64),
            "size_m": np.float64(grid.size_m),
            "label": np.int64(task.label),
            "class_name": np.str_(task.class_name),
            "record_id": np.str_(task.record_id),
            "split": np.str_(task.split),
        }
        provenance = {**shape.provenance, "repair": prepared.repair,
                      "normalisation": {"centre": prepared.centre.tolist(), "scale": prepared.scale}}
        record["provenance"] = np.str_(json.dumps(provenance, sort_keys=True))
        if shape.profile is not None:
            centre_z = prepared.centre[2]
            record["profile"] = ((shape.profile - [0.0, centre_z]) * prepared.scale).astype(np.float32)
        return record
