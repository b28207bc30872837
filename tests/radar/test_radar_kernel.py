"""The fast PO kernel against the slow per-facet oracle, branch by branch."""

import numpy as np
import pytest
import trimesh
from po_reference import reference_po

from radar2shape.radar import simulate
from radar2shape.radar.po import frequency_blocks, wavenumbers

BAND = np.linspace(8e9, 12e9, 64)
TOL = {np.complex128: 1e-9, np.complex64: 2e-5}


def angles(u):
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    return np.arccos(np.clip(u[2], -1, 1)), np.arctan2(u[1], u[0])


def facet_scale(tri, u, freq):
    """|S| of a face-on facet of the same area: the natural unit of one facet's error."""
    area = 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0]))
    return wavenumbers(freq) / np.sqrt(np.pi) * area


def special_direction(tri, kind, rng):
    """A direction that exercises one branch: face-on, edge-normal, near face-on or grazing."""
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    n /= np.linalg.norm(n)
    v = rng.normal(size=3)
    v -= (v @ n) * n
    v /= np.linalg.norm(v)
    if kind == "face-on":
        return n
    if kind == "near-face-on":
        return n + 10 ** rng.uniform(-8, 0) * v
    if kind == "grazing":
        return v + 10 ** rng.uniform(-8, -1) * n
    edge = tri[(m := rng.integers(3)) - 2] - tri[m]  # an edge of the triangle
    edge /= np.linalg.norm(edge)
    w = rng.normal(size=3)
    w -= (w @ edge) * edge
    w /= np.linalg.norm(w)
    w += rng.choice([0.0, 1e-9, 1e-6, 1e-3, 1e-1]) * edge
    return w if w @ n > 0 else w - 2 * (w @ n) * n


KINDS = ["face-on", "near-face-on", "grazing", "edge-normal"]


@pytest.mark.parametrize("dtype", [np.complex128, np.complex64])
@pytest.mark.parametrize("kind", KINDS)
def test_single_facet_matches_oracle(kind, dtype):
    rng = np.random.default_rng(KINDS.index(kind))
    freqs = [BAND, np.array([3.5e9]), np.linspace(1e9, 12e9, 23), np.array([5e9, 9e9, 7e9])]
    for trial in range(24):
        tri = rng.normal(size=(3, 3)) * 10 ** rng.uniform(-4, 0.3)  # 0.1 mm .. 2 m facets
        u = special_direction(tri, kind, rng)
        freq = freqs[trial % len(freqs)]
        a, p = angles(u)
        fast = simulate((tri, [[0, 1, 2]]), [a], [p], freq, shadowing=False, dtype=dtype)[0, 0]
        ref = reference_po(tri, [[0, 1, 2]], [a], [p], freq, shadowing=False)[0, 0]
        err = np.abs(fast - ref) / facet_scale(tri, u, freq)
        assert err.max() < TOL[dtype], (kind, trial, err.max())


@pytest.mark.parametrize("dtype", [np.complex128, np.complex64])
def test_random_meshes_match_oracle(dtype):
    rng = np.random.default_rng(7)
    aspect = np.concatenate([[0.0, np.pi / 2, np.pi], rng.uniform(0, np.pi, 4)])
    roll = np.concatenate([[0.0, np.pi / 2], rng.uniform(0, 2 * np.pi, 3)])
    freq = np.linspace(2e9, 6e9, 9)
    meshes = [
        (rng.normal(size=(12, 3)) * 0.1, rng.permutation(np.arange(12))[:9].reshape(3, 3)),
        (trimesh.creation.icosphere(1, radius=0.2).vertices, trimesh.creation.icosphere(1).faces),
        (trimesh.creation.box((0.3, 0.2, 0.1)).vertices + 0.05, trimesh.creation.box().faces),
    ]
    for vertices, faces in meshes:
        fast = simulate((vertices, faces), aspect, roll, freq, shadowing=False, dtype=dtype)
        ref = reference_po(vertices, faces, aspect, roll, freq, shadowing=False)
        scale = np.abs(ref).max()
        assert np.abs(fast - ref).max() / scale < TOL[dtype] * 10


def test_torus_with_shadowing_matches_oracle():
    """Non-convex: the Embree occlusion rays agree with the oracle's brute-force ray test."""
    mesh = trimesh.creation.torus(0.3, 0.1, major_sections=16, minor_sections=8)
    aspect, roll = np.linspace(0.2, 2.9, 5), np.array([0.1, 1.9, 4.0])
    freq = np.linspace(1e9, 2e9, 5)
    fast = simulate(mesh, aspect, roll, freq, shadowing=True, dtype=np.complex128)
    ref = reference_po(mesh.vertices, mesh.faces, aspect, roll, freq, shadowing=True)
    assert np.abs(fast - ref).max() / np.abs(ref).max() < 1e-9
    unshadowed = simulate(mesh, aspect, roll, freq, shadowing=False, dtype=np.complex128)
    assert np.abs(unshadowed - ref).max() / np.abs(ref).max() > 1e-3  # shadowing mattered here


def test_phase_follows_the_mesh_origin():
    """Translating the mesh by t multiplies S by exp(2jk u.t): phases are absolute."""
    mesh = trimesh.creation.icosphere(2, radius=0.1)
    aspect, roll = np.array([0.4, 2.0]), np.array([0.3, 3.0])
    shift = np.array([0.3, -0.2, 0.5])
    s0 = simulate(mesh, aspect, roll, BAND, dtype=np.complex128)
    s1 = simulate((mesh.vertices + shift, mesh.faces), aspect, roll, BAND, dtype=np.complex128)
    a, p = np.meshgrid(aspect, roll, indexing="ij")
    u = np.stack([np.sin(a) * np.cos(p), np.sin(a) * np.sin(p), np.cos(a)], -1)
    expected = s0 * np.exp(2j * (u @ shift)[..., None] * wavenumbers(BAND))
    assert np.abs(s1 - expected).max() < 1e-9 * np.abs(s0).max()


def test_frequency_blocks():
    k = wavenumbers(np.linspace(1e9, 12e9, 12))
    blocks = frequency_blocks(k)
    assert blocks[0].start == 0 and blocks[-1].stop == 12
    for b in blocks:
        assert k[b].max() <= 2 * k[b].min()
    assert len(frequency_blocks(wavenumbers(np.array([5e9, 9e9, 7e9])))) == 2  # non-uniform splits
    assert frequency_blocks(wavenumbers(BAND)) == [slice(0, 64)]


def test_complex64_close_to_complex128_on_a_big_band():
    mesh = trimesh.creation.torus(0.35, 0.15, major_sections=24, minor_sections=12)
    aspect, roll = np.linspace(0, np.pi, 6), np.linspace(0, 2 * np.pi, 5, endpoint=False)
    s64 = simulate(mesh, aspect, roll, BAND, dtype=np.complex64)
    s128 = simulate(mesh, aspect, roll, BAND, dtype=np.complex128)
    assert s64.dtype == np.complex64 and s128.dtype == np.complex128
    assert np.abs(s64 - s128).max() < 1e-5 * np.abs(s128).max()
    assert np.isfinite(s64).all()
