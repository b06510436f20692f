"""``hdrcam capture bracket``: shoot an exposure bracket (RAW frames + bracket.json) with a camera backend."""

from __future__ import annotations

import argparse
from pathlib import Path

from hdrcam.capture.backends import CAMERA_KINDS, SIMULATED_MIN_SIDE_PX
from hdrcam.capture.notches import ev_step_from_text, iso_setting
from hdrcam.cli.arguments import (add_profile_option, exposure_seconds, fraction_below_one, integers, positive_float,
                                  positive_int, random_seed)
from hdrcam.errors import InputError


def register(commands) -> None:
    capture = commands.add_parser("capture", help="capture with a camera", description=__doc__)
    actions = capture.add_subparsers(dest="action", metavar="<action>", required=True)
    parser = actions.add_parser("bracket", help="shoot an exposure bracket", description=__doc__)
    parser.add_argument("--camera", choices=CAMERA_KINDS, default="sim",
                        help="sim: simulated A7; sim-usb: emulated A7 over the PTP/USB code path; usb: a real A7")
    add_profile_option(parser)
    parser.add_argument("--out", type=Path, required=True, help="new folder for the frames and bracket.json")
    parser.add_argument("--stops", type=positive_int, default=None, help="number of exposures (--auto: at most)")
    parser.add_argument("--ev-step", type=ev_step_argument, default=None,
                        help="EV between exposures, a multiple of 1/3 (the shutter's notches): a fraction (1/3, 2/3, "
                             "4/3, 3) or the camera's label (0.3, 0.7, 1, 1.3, 1.7, 2, 2.3, ...; 0.33 or 0.667 also "
                             "mean 1/3 and 2/3)")
    parser.add_argument("--shortest", type=exposure_seconds, default=1 / 4000, metavar="S",
                        help="shortest exposure, e.g. 1/4000 (--auto: the first one tried)")
    parser.add_argument("--iso", type=iso_argument, default=100.0,
                        help="ISO, one of the camera's settings: 100, 125, 160, 200, ... 25600 in 1/3 EV steps "
                             "(default 100)")
    parser.add_argument("--auto", action="store_true",
                        help="only the exposures the scene needs (no clipping in the ROI, SNR target reached)")
    parser.add_argument("--roi", type=integers(4), default=None, metavar="X,Y,W,H",
                        help="region of interest for --auto, in pixels (default: whole frame)")
    parser.add_argument("--darks", action="store_true", help="also dark frames at the same exposures (DIR/darks)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the incomplete capture in --out (same camera, profile and options): frames "
                             "on disk are checked and kept, only the missing ones are shot")
    simulation = parser.add_argument_group("simulated cameras (sim, sim-usb)")
    simulation.add_argument("--scene", default="point",
                            help="point[:POWER] | pinholes[:POWER[:SPACING]] (PSF calibration target) | night | "
                                 "flat[:LEVEL] | FILE.exr")
    simulation.add_argument("--psf", default="doe", help="doe (the profile's DOE) | dirac | FILE.exr")
    simulation.add_argument("--size", type=integers(2, "x", minimum=SIMULATED_MIN_SIDE_PX), default=None, metavar="WxH",
                            help=f"frame size in pixels, at least {SIMULATED_MIN_SIDE_PX}x{SIMULATED_MIN_SIDE_PX} "
                                 "(LibRaw opens no smaller RAW file; default: the profile's sensor)")
    simulation.add_argument("--seed", type=random_seed, default=0, help="noise, scene and defect seed")
    simulation.add_argument("--hot-pixels", type=fraction_below_one, default=2e-5, metavar="FRACTION",
                            help="share of the pixels that are hot, from 0 up to 1 (default 2e-5)")
    simulation.add_argument("--exposure-error", type=fraction_below_one, default=0.02, metavar="FRACTION",
                            help="largest per-notch error of the true shutter time, from 0 up to 1 (default 0.02)")
    parser.set_defaults(run=run, command_name="capture bracket", usage_error=parser.error)


def ev_step_argument(text: str) -> float:
    """--ev-step in EV (hdrcam.capture.notches.ev_step_from_text)."""
    try:
        return ev_step_from_text(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def iso_argument(text: str) -> float:
    """--iso: a positive number that is one of the camera's ISO settings."""
    try:
        iso_setting(value := positive_float(text))
    except InputError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return value


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.stages import capture_bracket

    if arguments.roi is not None and not arguments.auto:  # it would be taken and ignored: a fixed bracket
        arguments.usage_error("argument --roi: the region --auto meters; give --auto with it, or leave --roi out")
    capture_bracket(arguments.out, camera=arguments.camera, profile=arguments.profile,
                    shortest_s=arguments.shortest, stops=arguments.stops, ev_step=arguments.ev_step,
                    iso=arguments.iso, auto=arguments.auto, roi=arguments.roi, darks=arguments.darks,
                    scene=arguments.scene, psf=arguments.psf, size_px=arguments.size, seed=arguments.seed,
                    hot_pixel_fraction=arguments.hot_pixels, exposure_error=arguments.exposure_error,
                    resume=arguments.resume, show_progress=True, log=print)
    return 0
