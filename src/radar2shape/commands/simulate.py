"""``radar2shape simulate MESH --out OUT.npz``: the radar response of one mesh file (PO, PO + SBR,
either with equivalent edge currents), in one polarisation or all four.

The axes come from ``--grid`` (default conf/radar/default.yaml's values) and can be overridden
one by one with START:STOP:COUNT (both ends included). The mesh is centred and scaled so its
longest bounding-box side is ``--size-m`` metres (default: the grid's size_m, 1 m), unless
``--keep-size`` simulates it as given, in metres.

Everything is checked before the simulation starts (axes, options, the memory the grid needs,
both output paths, the mesh and the memory its faces need, counted from the file's header before it
is loaded: preflight.BYTES_PER_FACE per face), and the outputs are written together at the end, atomically: a
failed run leaves no file behind.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from radar2shape.atomic import atomic_paths, check_output_path
from radar2shape.errors import UserInputError
from radar2shape.preflight import add_memory_option, check_input_file, check_memory, check_mesh_memory, count_faces

# Mesh, radar and plotting modules are imported in main(): ``--help`` and argument errors stay fast.
IMAGE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")
# Peak bytes per (aspect, roll, frequency) cell: the complex64 result, the complex128 phase
# correction and its cast, the reordered copy and the copy written.
BYTES_PER_CELL = 48


def _range(text: str, name: str) -> np.ndarray:
    """'START:STOP:COUNT' -> linspace with both ends included."""
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise UserInputError(f"{name}: expected START:STOP:COUNT (e.g. 0:180:32), got {text!r}") from None
    if count < 1:
        raise UserInputError(f"{name}: COUNT must be at least 1, got {count}")
    return np.linspace(start, stop, count)


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mesh", help="mesh file (.obj, .off, .ply, .stl, .glb, .gltf)")
    parser.add_argument("--out", required=True, help="output .npz (response complex64 [A, R, F] + axes)")
    parser.add_argument("--grid", help="radar grid YAML (default: conf/radar/default.yaml values)")
    parser.add_argument("--aspect-deg", help="aspect axis START:STOP:COUNT in degrees, within 0..180")
    parser.add_argument("--roll-deg", help="roll axis START:STOP:COUNT in degrees")
    parser.add_argument("--freq-ghz", help="frequency axis START:STOP:COUNT in GHz")
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--size-m", type=float, help="longest bbox side in metres after centring (default: grid size_m)")
    size.add_argument("--keep-size", action="store_true", help="simulate the mesh as given, in metres")
    parser.add_argument("--up", default="z", choices=["x", "y", "z", "-x", "-y", "-z"],
                        help="the file's up axis, turned onto +z, the body frame's (AC3D, glTF: y; default z)")
    parser.add_argument("--no-shadow", action="store_true", help="back-face culling only (no occlusion rays)")
    parser.add_argument("--method", default="po", choices=["po", "sbr", "po+ec", "sbr+ec"],
                        help="po, sbr (PO first bounce + shooting and bouncing rays, docs/sbr_lora.md), "
                             "or either plus equivalent edge currents of the sharp edges (+ec)")
    parser.add_argument("--pol", default="VV", type=str.upper, choices=["VV", "HH", "HV", "VH", "ALL"],
                        help="polarisation, first letter transmit, second receive (V = theta-hat, H = phi-hat); "
                             "ALL writes [A, R, F, 4] in the order VV, VH, HV, HH")
    parser.add_argument("--edge-threshold-deg", type=float, default=30.0,
                        help="+ec: normal turn (deg) from which an edge between two faces is sharp, in (0, 180]")
    parser.add_argument("--edge-krho", type=float, default=1.0,
                        help="+ec: a convex rounded edge diffracts at wavenumber k while k * (its radius of "
                             "curvature) <= this, >= 0 (0: only the sharp edges)")
    parser.add_argument("--edge-order", type=int, default=2,
                        help="+ec: 1 single edge diffraction, 2 (default) also the double diffraction between "
                             "the facing edges of flat sheets (plates, fins)")
    parser.add_argument("--bounces", type=int, default=5, help="sbr: bounces traced, >= 1 (1 = PO only)")
    parser.add_argument("--rays-per-wavelength", type=float, default=8.0,
                        help="sbr: ray tubes per wavelength at the highest frequency, > 0")
    parser.add_argument("--plot", help="also write a picture of the dB response (.png, .pdf, .svg, .jpg)")
    add_memory_option(parser)
    parser.epilog = ("Bad input is one 'error:' line (exit code 2) and nothing is written; outputs appear "
                     "complete or not at all.")


def main(args: argparse.Namespace) -> int:
    from radar2shape.radar.grid import RadarGrid
    from radar2shape.radar.edges import check_krho, check_order, check_threshold
    from radar2shape.radar.sbr import check_options

    grid = RadarGrid.from_yaml(args.grid) if args.grid else RadarGrid.default()
    aspect = np.radians(_range(args.aspect_deg, "--aspect-deg")) if args.aspect_deg else grid.aspect_rad
    roll = np.radians(_range(args.roll_deg, "--roll-deg")) if args.roll_deg else grid.roll_rad
    freq = _range(args.freq_ghz, "--freq-ghz") * 1e9 if args.freq_ghz else grid.freq_hz
    size = None if args.keep_size else (grid.size_m if args.size_m is None else args.size_m)
    if size is not None and not (np.isfinite(size) and size > 0):
        raise UserInputError(f"--size-m: expected a positive number of metres, got {size}")
    grid = RadarGrid(aspect, roll, freq, size or 1.0)  # validates the axes before any work
    if args.method.startswith("sbr"):
        check_options(args.bounces, args.rays_per_wavelength)
    if args.method.endswith("+ec"):
        check_threshold(args.edge_threshold_deg)
        check_krho(args.edge_krho)
        check_order(args.edge_order)
    channels = 4 if args.pol == "ALL" else 1
    cells = len(grid.aspect_rad) * len(grid.roll_rad) * len(grid.freq_hz) * channels
    check_memory(cells * BYTES_PER_CELL, f"a response of {len(grid.aspect_rad)} x {len(grid.roll_rad)} x "
                 f"{len(grid.freq_hz)} (aspect x roll x freq)", args.memory_limit_gb)
    outputs = [check_output_path(args.out, "--out", (".npz",))]
    if args.plot:
        outputs.append(check_output_path(args.plot, "--plot", IMAGE_SUFFIXES))
        if outputs[1].resolve() == outputs[0].resolve():
            raise UserInputError(f"--plot: {args.plot} is also --out; expected two different files")
    check_input_file(args.mesh, "mesh", "a mesh file")
    grid_text = f"{len(grid.aspect_rad)} x {len(grid.roll_rad)} x {len(grid.freq_hz)} (aspect x roll x freq)"

    def check_faces(faces: int) -> None:
        check_mesh_memory(faces, cells * BYTES_PER_CELL, f"{args.mesh}: a mesh of {faces} faces with a response "
                          f"of {grid_text}", args.memory_limit_gb)

    declared = count_faces(args.mesh)
    if declared is not None:
        check_faces(declared)  # before loading: a mesh too large for memory is refused at once

    from radar2shape.geometry.mesh_io import load_mesh
    from radar2shape.geometry.normalise import normalise, scaled
    from radar2shape.radar import save_response, simulate, to_db
    from radar2shape.radar.edges import ALL_POLARIZATIONS

    mesh = load_mesh(args.mesh)
    if args.up != "z":  # into the body frame: aspect from +z, roll from +x
        from radar2shape.geometry.frames import to_body_frame

        mesh = to_body_frame(mesh, args.up)
    if declared is None or len(mesh.faces) > declared:  # polygons split into more triangles
        check_faces(len(mesh.faces))
    if size is not None:
        mesh = scaled(normalise(mesh)[0], size)
    start = time.perf_counter()
    options = {"polarization": args.pol.lower() if args.pol == "ALL" else args.pol}
    if args.method.startswith("sbr"):
        options.update(max_bounces=args.bounces, rays_per_wavelength=args.rays_per_wavelength)
    if args.method.endswith("+ec"):
        options.update(edge_threshold_deg=args.edge_threshold_deg, edge_krho=args.edge_krho, edge_order=args.edge_order)
    response = simulate(mesh, grid.aspect_rad, grid.roll_rad, grid.freq_hz, method=args.method,
                        shadowing=not args.no_shadow, **options)
    seconds = time.perf_counter() - start
    names = ALL_POLARIZATIONS if args.pol == "ALL" else args.pol
    with atomic_paths(*outputs) as temps:  # both files, or neither
        save_response(temps[0], response, grid.aspect_rad, grid.roll_rad, grid.freq_hz, size_m=size,
                      polarization=names)
        if args.plot:
            from radar2shape.radar.plot import plot_response  # matplotlib only when asked for

            first = response if response.ndim == 3 else response[..., 0]  # "all": the VV channel
            plot_response(temps[1], first, grid.aspect_rad, grid.roll_rad, grid.freq_hz,
                          title=f"{args.mesh} ({names if isinstance(names, str) else names[0]})")
    print(f"wrote {outputs[0]}: response {list(response.shape)} (aspect, roll, freq), "
          f"{len(mesh.faces)} faces, peak {to_db(response).max():.1f} dBsm, {seconds:.2f} s")
    if args.plot:
        print(f"wrote {outputs[1]}")
    return 0
