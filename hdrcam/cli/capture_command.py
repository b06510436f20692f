"""``hdrcam capture bracket``: shoot an exposure bracket (RAW frames + bracket.json) with a camera backend."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from hdrcam.capture.backends import CAMERA_KINDS
from hdrcam.capture.manifest import MANIFEST_NAME, load_bracket, sha256_of
from hdrcam.capture.notches import nearest_shutter
from hdrcam.cli.arguments import (add_profile_option, exposure_seconds, integers, positive_float, positive_int,
                                  thirds_of_ev)
from hdrcam.errors import InputError, OutputExistsError
from hdrcam.profiles import load_profile


def register(commands) -> None:
    capture = commands.add_parser("capture", help="capture with a camera", description=__doc__)
    actions = capture.add_subparsers(dest="action", metavar="<action>", required=True)
    parser = actions.add_parser("bracket", help="shoot an exposure bracket", description=__doc__)
    parser.add_argument("--camera", choices=CAMERA_KINDS, default="sim",
                        help="sim: simulated A7; sim-usb: emulated A7 over the PTP/USB code path; usb: a real A7")
    add_profile_option(parser)
    parser.add_argument("--out", type=Path, required=True, help="new folder for the frames and bracket.json")
    parser.add_argument("--stops", type=positive_int, default=None, help="number of exposures (--auto: at most)")
    parser.add_argument("--ev-step", type=thirds_of_ev, default=None,
                        help="EV between exposures, a multiple of 1/3 (e.g. 1, 2/3, 3)")
    parser.add_argument("--shortest", type=exposure_seconds, default=1 / 4000, metavar="S",
                        help="shortest exposure, e.g. 1/4000 (--auto: the first one tried)")
    parser.add_argument("--iso", type=positive_float, default=100.0, help="ISO (default 100)")
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
    simulation.add_argument("--size", type=integers(2, "x", minimum=2), default=None, metavar="WxH",
                            help="frame size (default: the profile's sensor)")
    simulation.add_argument("--seed", type=int, default=0, help="noise, scene and defect seed")
    simulation.add_argument("--hot-pixels", type=float, default=2e-5, metavar="FRACTION")
    simulation.add_argument("--exposure-error", type=float, default=0.02, metavar="FRACTION",
                            help="largest per-notch error of the true shutter time (default 0.02)")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.capture.backends import open_camera
    from hdrcam.capture.bracket import BracketCapture, BracketPlan
    from hdrcam.capture.scene import load_scene
    from hdrcam.capture.simulated import simulation_psf

    profile = load_profile(arguments.profile)
    folder: Path = arguments.out
    lights_manifest, darks_manifest = folder / MANIFEST_NAME, folder / "darks" / MANIFEST_NAME
    saved = saved_darks = None
    if arguments.resume:
        saved = load_bracket(lights_manifest)
        saved_darks = load_bracket(darks_manifest) if darks_manifest.exists() else None
        if saved.status == "complete" and (not arguments.darks or getattr(saved_darks, "status", "") == "complete"):
            raise InputError(f"{folder}: the capture is complete; nothing to resume")
    else:
        for manifest in (lights_manifest, darks_manifest):
            if manifest.exists():
                raise OutputExistsError(f"{manifest} exists: a capture is never overwritten; choose another --out "
                                        "(or pass --resume to continue an incomplete one)")
    plan = BracketPlan(shortest_s=arguments.shortest, stops=arguments.stops or profile.calibration.stops,
                       ev_step=arguments.ev_step or profile.calibration.ev_step, iso=arguments.iso,
                       auto=arguments.auto, roi=arguments.roi, target_snr=profile.calibration.target_snr,
                       snr_percentile=profile.calibration.snr_percentile)
    scene = psf = None
    if arguments.camera != "usb":
        width, height = arguments.size or (profile.camera.width_px, profile.camera.height_px)
        scene = load_scene(arguments.scene, height, width, seed=arguments.seed)
        psf = simulation_psf(profile, arguments.psf)  # the DOE is part of the camera, not of the seed
    camera, simulated = open_camera(arguments.camera, profile, scene=scene, psf=psf, seed=arguments.seed,
                                    hot_pixel_fraction=arguments.hot_pixels, exposure_error=arguments.exposure_error)
    options = {"scene": scene.description if scene else None, "psf": arguments.psf if scene else None,
               "seed": arguments.seed, "profile_sha256": sha256_of(profile.path)}
    truth = simulated.true_exposure_s if simulated else None
    started = time.perf_counter()
    shot = 0
    with camera:
        print(f"camera: {camera.model} ({arguments.camera}); profile {profile.name}")
        capture = BracketCapture(camera, profile.camera, folder, backend=arguments.camera, profile=profile.name,
                                 options=options, true_exposure_s=truth)
        if saved is not None and saved.status == "complete":
            bracket = saved
        else:
            bracket = capture.shoot(plan, resume=saved)
            shot += len(bracket.frames) - (len(saved.frames) if saved else 0)
        _print_frames(bracket, folder)
        if arguments.darks:
            darks = BracketCapture(camera, profile.camera, folder / "darks", backend=arguments.camera,
                                   profile=profile.name, options=options, true_exposure_s=truth)
            notches = [nearest_shutter(frame.exposure_s) for frame in bracket.frames]
            dark_bracket = darks.shoot(plan, dark_notches=notches, resume=saved_darks)
            shot += len(dark_bracket.frames) - (len(saved_darks.frames) if saved_darks else 0)
            _print_frames(dark_bracket, folder / "darks")
    seconds = time.perf_counter() - started
    print(f"{shot} frames in {seconds:.1f} s ({seconds / max(shot, 1):.2f} s per frame) -> {lights_manifest}")
    for note in bracket.notes:
        print(f"note: {note}")
    return 0


def _print_frames(bracket, folder: Path) -> None:
    for frame in bracket.frames:
        print(f"  {folder / frame.file}  {frame.exposure_label:>7} ({frame.exposure_s:g} s)  ISO {frame.iso:g}  "
              f"f/{frame.f_number:g}")
