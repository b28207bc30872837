"""SBR batches: identical results for any worker count, failures surface, bounded memory."""

import math
import os
import tracemalloc

import numpy as np
import pytest
import trimesh

from radar2shape.errors import UserInputError
from radar2shape.radar import sbr
from radar2shape.radar.facets import facet_mesh
from radar2shape.radar.simulator import directions
from test_radar_sbr import K, LAM, dihedral, plate


def test_any_worker_count_gives_the_same_response():
    """Batches are planned independently of the workers and summed in batch order."""
    facets = facet_mesh(trimesh.creation.torus(0.35, 0.15, major_sections=24, minor_sections=10))
    u = directions(np.radians([60.0, 85.0]), np.radians([0.0, 40.0, 95.0])).reshape(-1, 3)
    k = np.linspace(8e9, 12e9, 8) * 2 * np.pi / 299_792_458.0
    kwargs = dict(rays_per_wavelength=3, rays_per_batch=4000)
    shot = sbr.prepare(facets, u, k, 5, 3.0, np.float32, 2, "VV")
    assert len(sbr.plan_batches(shot.ends, shot.tubes.n, len(k), 4000)) > 10
    one = sbr.multibounce(facets, u, k, workers=1, **kwargs)
    assert np.abs(one).max() > 1e-3  # the torus's inner ring gives real multi-bounce energy
    for workers in (2, 3):
        many = sbr.multibounce(facets, u, k, workers=workers, **kwargs)
        assert np.abs(many - one).max() <= 1e-6 * np.abs(one).max()  # measured: bit-identical


def test_a_failing_batch_raises_one_error_in_the_parent():
    with pytest.raises(sbr.SBRWorkerError, match=r"batch 2 of 3 failed .*ValueError: math domain error"):
        list(sbr.map_batches(math.sqrt, [(1.0,), (-1.0,), (4.0,)], 2))
    assert list(sbr.map_batches(math.sqrt, [(1.0,), (4.0,)], 2)) == [1.0, 2.0]


def test_a_dead_worker_raises_one_error_and_the_pool_recovers():
    with pytest.raises(sbr.SBRWorkerError, match="worker process died"):
        list(sbr.map_batches(os._exit, [(3,)], 2))
    assert list(sbr.map_batches(math.sqrt, [(9.0,), (16.0,)], 2)) == [3.0, 4.0]


def test_plan_covers_every_ray_once_within_the_budget():
    rng = np.random.default_rng(0)
    for n_dirs, mean_rays, n_rows, n_freq, budget in [(7, 100_000, 400, 64, 4096), (1000, 37, 10, 64, 4096),
                                                      (5, 5000, 80, 1, 5000), (20_000, 3, 4, 2**14, 2**17),
                                                      (3000, 50, 2000, 1, 2**17)]:
        counts = rng.poisson(mean_rays, n_dirs) * (rng.random(n_dirs) > 0.2)  # some directions launch nothing
        ends = np.cumsum(counts)
        plan = sbr.plan_batches(ends, n_rows, n_freq, budget)
        starts, stops = np.array(plan).T
        assert starts[0] == 0 and stops[-1] == ends[-1] and np.array_equal(starts[1:], stops[:-1])
        assert (stops - starts).min() > 0 and (stops - starts).max() <= budget
        dirs = np.searchsorted(ends, stops - 1, side="right") - np.searchsorted(ends, starts, side="right") + 1
        assert (dirs * n_freq).max() <= max(sbr.VALUES_PER_CHUNK, n_freq)  # partial sums bounded
        assert (dirs * n_rows).max() <= max(sbr.CELLS_PER_BATCH, n_rows)  # row tables bounded


def test_high_density_runs_in_bounded_batches():
    """64 rays per wavelength (about 52,000 rays): the peak follows the budget, not the density."""
    facets = facet_mesh(dihedral(3 * LAM, 3 * LAM))
    u = directions(np.array([np.pi / 2]), np.array([np.pi / 4])).reshape(-1, 3)
    k = np.array([K])
    budget = 4096
    shot = sbr.prepare(facets, u, k, 5, 64.0, np.float32, 2, "VV")
    tubes = shot.n_rays
    assert tubes > 12 * budget
    assert len(sbr.plan_batches(shot.ends, shot.tubes.n, 1, budget)) == math.ceil(tubes / budget)

    peaks, values = [], []
    for rays_per_batch in (budget, tubes):
        tracemalloc.start()
        values.append(sbr.multibounce(facets, u, k, rays_per_wavelength=64, workers=1, rays_per_batch=rays_per_batch,
                                      real_dtype=np.float64))
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[0] <= sbr.memory_bound(budget, 1)
    assert peaks[0] * 5 < peaks[1]  # one batch of all the tubes needs far more
    np.testing.assert_allclose(values[0], values[1], rtol=1e-9)  # summation order only
    assert abs(db_ratio(abs(values[0][0, 0]) ** 2, 8 * np.pi * (3 * LAM) ** 4 / LAM**2)) < 0.1


def db_ratio(a, b):
    return 10 * np.log10(a / b)


@pytest.mark.parametrize("kwargs, match", [({"workers": 0}, "workers"), ({"workers": 1.5}, "workers"),
                                           ({"rays_per_batch": 0}, "rays_per_batch"),
                                           ({"rays_per_batch": True}, "rays_per_batch")])
def test_bad_batch_options(kwargs, match):
    with pytest.raises(UserInputError, match=match):
        sbr.multibounce(facet_mesh(plate(LAM, LAM)), np.array([[0.0, 0.0, 1.0]]), np.array([K]), **kwargs)
