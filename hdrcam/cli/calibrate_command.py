"""``hdrcam calibrate psf BRACKET --darks DIR --out calibration/NAME``: measure the PSF from point sources."""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

from hdrcam.cli.arguments import add_profile_option, positive_finite_float, positive_int
from hdrcam.errors import InputError
from hdrcam.io.atomic import check_outputs
from hdrcam.profiles import load_profile


def fraction(text: str) -> float:
    value = float(text)
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"{text} is not a fraction in (0, 1]")
    return value


def register(commands) -> None:
    parser = commands.add_parser("calibrate", help="calibrate from captured brackets", description=__doc__)
    kinds = parser.add_subparsers(dest="calibration", metavar="<what>", required=True)
    psf = kinds.add_parser("psf", help="measured PSF from a point-source (or pinhole-array) bracket",
                           description=__doc__)
    psf.add_argument("bracket", type=Path, nargs="+", help="bracket.json, a folder of RAW files, or RAW files")
    psf.add_argument("--darks", type=Path, default=None,
                     help="dark frames (bracket.json or folder): hot pixels are found in them")
    psf.add_argument("--bad-pixels", type=Path, default=None, metavar="LIST",
                     help="the sensor's hot and dead pixels (a dcraw list, from 'hdrcam bad-pixels'): left out of "
                          "the fit with the hot pixels the darks show")
    psf.add_argument("--out", type=Path, required=True, help="record folder, e.g. calibration/NAME")
    psf.add_argument("--size", type=positive_int, default=None, metavar="PX",
                     help="PSF size to fit, odd (default: the profile's psf_size_px)")
    psf.add_argument("--energy-fraction", type=fraction, default=None, metavar="F",
                     help="crop to the smallest size holding this fraction of every channel's energy")
    psf.add_argument("--source-diameter-mm", type=positive_finite_float, default=None, metavar="MM",
                     help="the point source's (pinhole's) diameter in mm: its image on the sensor is computed, "
                          "warned about over 1 px and refused over --size")
    psf.add_argument("--source-distance-m", type=positive_finite_float, default=None, metavar="M",
                     help="the source's distance from the lens in metres, with --source-diameter-mm (default: the "
                          "profile's calibration.point_source_distance_m)")
    psf.add_argument("--overwrite", action="store_true")
    add_profile_option(psf)
    psf.set_defaults(run=run, command_name="calibrate psf")


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.calibrate.psf_calibration import calibrate_psf, source_size
    from hdrcam.calibrate.record import OUTPUT_NAMES, write_record
    from hdrcam.hdr.bracket_input import bracket_input_files
    from hdrcam.io.bad_pixels import read_bad_pixels

    profile = load_profile(arguments.profile)
    size = arguments.size or profile.simulation.psf_size_px
    if size % 2 == 0:
        raise InputError(f"--size {size}: the PSF size must be odd (a centre pixel)")
    diameter_mm = arguments.source_diameter_mm
    source = source_size(None if diameter_mm is None else diameter_mm / 1000, arguments.source_distance_m, profile)
    inputs = bracket_input_files(arguments.bracket)
    if arguments.darks:
        inputs += bracket_input_files([arguments.darks], kind="dark")
    if arguments.bad_pixels:
        inputs.append(arguments.bad_pixels)
    check_outputs([arguments.out / name for name in OUTPUT_NAMES], overwrite=arguments.overwrite, inputs=inputs)
    bad_pixels = read_bad_pixels(arguments.bad_pixels) if arguments.bad_pixels else None
    started = time.perf_counter()
    calibration = calibrate_psf(arguments.bracket, profile.camera, darks=arguments.darks, size_px=size,
                                energy_fraction=arguments.energy_fraction, source=source, bad_pixels=bad_pixels)
    command = "hdrcam " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:] else "hdrcam calibrate psf"
    paths = write_record(arguments.out, calibration, profile, command, overwrite=arguments.overwrite)
    fit = calibration.fit
    print(f"{len(calibration.windows)} point sources ({calibration.rejected_sources} rejected), "
          f"{calibration.hot_pixels} hot (or listed bad) pixels and {fit.outlier_samples} outlying samples left "
          f"out; PSF "
          f"{calibration.psf.shape[-1]} px, energy in crop " + "/".join(f"{e:.4f}" for e in calibration.energy_in_crop)
          + f"; reduced chi2 {fit.reduced_chi2:.3f}")
    print("peak SNR R/G/B " + "/".join(f"{s:.3g}" for s in calibration.peak_snr)
          + "; background " + "/".join(f"{b:.3g}" for b in calibration.background))
    print(f"-> {', '.join(str(p) for p in paths)} in {time.perf_counter() - started:.1f} s")
    return 0
