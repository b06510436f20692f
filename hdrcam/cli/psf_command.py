"""``hdrcam psf``: simulate the PSF of a profile's DOE (or a given height map)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

from hdrcam import __version__
from hdrcam.cli.arguments import (add_compute_options, add_profile_option, compute_device, compute_dtype,
                                  naming_input, positive_finite_float, positive_int, random_seed)
from hdrcam.errors import InputError
from hdrcam.io.atomic import atomic_paths, check_outputs, write_text_atomic
from hdrcam.profiles import PROPAGATION_MODELS, load_profile

OUTPUT_NAMES = ("psf.exr", "heightmap.exr", "psf.png", "psf.json")


def register(commands) -> None:
    parser = commands.add_parser("psf", help="simulate the PSF of a DOE", description=__doc__)
    add_profile_option(parser)
    parser.add_argument("--doe", default=None,
                        help="rank1 | freeform (seeded initialisation) | none (clear aperture) | FILE "
                             "(height-map EXR); default: the profile's DOE kind")
    parser.add_argument("--depth", type=positive_finite_float, default=None, metavar="M",
                        help="point-source distance in metres, beyond the lens's focal length (default: the profile's, "
                             "5 m; finite: psf.json is JSON, which has no infinity; 1e9 is as far as inf)")
    parser.add_argument("--out", type=Path, default=Path("psf-out"), help="output folder (default psf-out)")
    parser.add_argument("--psf-size", type=positive_int, default=None, metavar="PX", help="PSF crop in pixels")
    parser.add_argument("--wavelengths-per-band", type=positive_int, default=None, metavar="K")
    parser.add_argument("--propagation", choices=PROPAGATION_MODELS, default=None)
    parser.add_argument("--upsample", type=positive_int, default=None,
                        help="simulation samples per sensor pixel (default: coarsest unaliased)")
    parser.add_argument("--allow-aliasing", action="store_true", help="warn instead of refusing an aliased grid")
    parser.add_argument("--seed", type=random_seed, default=0, help="seed of a rank1/freeform initialisation")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    add_compute_options(parser)
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    import numpy as np
    import torch

    from hdrcam.io.exr import write_exr
    from hdrcam.io.png import write_png
    from hdrcam.optics.fraunhofer import FRAUNHOFER_SUBPIXELS
    from hdrcam.optics.heightmap import heightmap_for_doe, save_heightmap
    from hdrcam.optics.psf import OpticalSetup, PsfSimulator
    from hdrcam.preview import heightmap_rgb, log_psf_rgb, side_by_side

    profile = load_profile(arguments.profile)
    if arguments.propagation:
        profile = _with_propagation(profile, arguments.propagation)
    focal_length_m = profile.lens.focal_length_m
    if arguments.depth is not None and arguments.depth <= focal_length_m:
        raise InputError(f"--depth {arguments.depth:g} m puts the source at or inside the focal length "
                         f"({focal_length_m:g} m) of profile {profile.name}, where the lens forms no image; "
                         "give a farther --depth")
    doe_choice = arguments.doe or profile.doe.kind
    inputs = [Path(doe_choice)] if doe_choice not in ("rank1", "freeform", "none") else []
    outputs = [arguments.out / name for name in OUTPUT_NAMES]
    check_outputs(outputs, overwrite=arguments.overwrite, inputs=inputs)
    dtype, device = compute_dtype(arguments.dtype), compute_device(arguments.device)

    with naming_input(Path(doe_choice)):
        heightmap = heightmap_for_doe(profile.doe, doe_choice, seed=arguments.seed, dtype=dtype)
    setup = OpticalSetup.from_profile(profile, source_distance_m=arguments.depth,
                                      wavelengths_per_band=arguments.wavelengths_per_band,
                                      psf_size_px=arguments.psf_size, upsample=arguments.upsample,
                                      allow_aliasing=arguments.allow_aliasing)
    grid = setup.grid
    started = time.perf_counter()
    simulator = PsfSimulator(setup, heightmap, dtype=dtype).to(device)
    cells_per_feature = simulator.fraunhofer.samples_per_feature if grid is None else None
    sampling = (f"chirp-z on {cells_per_feature} x {cells_per_feature} cells per "
                f"{heightmap.feature_pitch_m * 1e6:.3g} um feature, {FRAUNHOFER_SUBPIXELS} points per pixel"
                if grid is None else
                f"grid {grid.size} x {grid.size} at {grid.pitch_m * 1e6:.3f} um ({grid.upsample} samples per pixel)")
    print(f"profile {profile.name}: DOE {doe_choice}, source at {setup.source_distance_m:g} m, sensor at "
          f"{setup.sensor_distance_m * 1e3:.3f} mm; {sampling}, {sum(map(len, setup.band_wavelengths_m))} "
          f"wavelengths, {device}")
    with torch.no_grad():
        result = simulator()
        heights = heightmap().detach().cpu().numpy()
    if device.type == "cuda":
        torch.cuda.synchronize()
    seconds = time.perf_counter() - started
    psf = result.psf.cpu().numpy().astype(np.float32)
    centre = result.centre_energy_fraction.cpu().numpy()
    crop = result.crop_energy_fraction.cpu().numpy()

    record = {
        "hdrcam_version": __version__, "profile": profile.name, "profile_path": str(profile.path),
        "doe": doe_choice, "seed": arguments.seed, "source_distance_m": setup.source_distance_m,
        "sensor_distance_m": setup.sensor_distance_m, "propagation": setup.propagation,
        "wavelengths_m": [list(band) for band in setup.band_wavelengths_m],
        **({"subpixels": FRAUNHOFER_SUBPIXELS, "cells_per_feature": cells_per_feature} if grid is None else
           {"grid_size": grid.size, "grid_pitch_m": grid.pitch_m, "upsample": grid.upsample,
            "lens_phase_aliased": grid.lens_phase_aliased}),
        "psf_size_px": setup.psf_size_px, "pixel_pitch_m": setup.pixel_pitch_m,
        "centre_energy_fraction_rgb": centre.tolist(), "crop_energy_fraction_rgb": crop.tolist(),
        "seconds": round(seconds, 3), "device": str(device), "dtype": arguments.dtype,
    }
    attributes = {"pixel_pitch_m": setup.pixel_pitch_m, "hdrcam_record": json.dumps(record)}
    with atomic_paths(outputs, overwrite=arguments.overwrite) as (psf_file, heightmap_file, preview_file, record_file):
        write_exr(psf_file, psf.transpose(1, 2, 0), attributes=attributes, overwrite=True)  # all four, or none
        save_heightmap(heightmap_file, heights, heightmap.feature_pitch_m, overwrite=True)
        write_png(preview_file, side_by_side([log_psf_rgb(psf), heightmap_rgb(heights, profile.doe.h_max_m)]),
                  overwrite=True)
        write_text_atomic(record_file, json.dumps(record, indent=2) + "\n", overwrite=True)
    print(f"PSF {setup.psf_size_px} x {setup.psf_size_px} px in {seconds:.2f} s; energy in the "
          f"{2 * setup.energy_centre_radius_px + 1} px centre (R, G, B): {', '.join(f'{v:.4f}' for v in centre)}; "
          f"in the crop: {', '.join(f'{v:.4f}' for v in crop)}")
    print(f"wrote {', '.join(str(p) for p in outputs)}")
    return 0


def _with_propagation(profile, propagation: str):
    return dataclasses.replace(profile, simulation=dataclasses.replace(profile.simulation, propagation=propagation))
