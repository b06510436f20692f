"""``hdrcam simulate``: what the camera records of an HDR scene through a PSF (linear EXR frame + the truth).

The scene (``night`` for a seeded procedural night scene, or an HDR EXR/.hdr file) is exposure-scaled so
that a set fraction of its pixels exceed white (default 1.5 %, the paper's test protocol), blurred by the
PSF (light from outside the frame included), exposed with shot and read noise, clipped and quantised as
the profile's sensor does. Writes FRAME (the capture, 0 .. 1) and, with --truth, the scaled scene.
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

from hdrcam.cli.arguments import fraction_between_0_and_1, positive_int, random_seed
from hdrcam.errors import InputError, missing_input
from hdrcam.io.atomic import atomic_paths, check_outputs
from hdrcam.train.choices import FIXED_PSFS


NIGHT_SIZE_PX = (768, 1024)  # height, width of the procedural scene unless --size says otherwise


def register(commands) -> None:
    parser = commands.add_parser("simulate", help="render what the camera records of an HDR scene",
                                 description=__doc__)
    parser.add_argument("scene", help="'night' or an HDR scene file (.exr, .hdr)")
    parser.add_argument("--psf", default=None, help="PSF EXR, or dirac|star8|dual-peak (default: the checkpoint's)")
    parser.add_argument("--checkpoint", type=Path, default=None, help="take PSF and profile from this checkpoint")
    parser.add_argument("--out", type=Path, required=True, help="the captured frame (EXR)")
    parser.add_argument("--truth", type=Path, default=None, help="also write the exposure-scaled scene here")
    parser.add_argument("--size", type=positive_int, nargs=2, default=None, metavar=("H", "W"),
                        help="frame size of the procedural 'night' scene (default 768 1024); a scene file keeps "
                             "its own size")
    parser.add_argument("--clipped-fraction", type=fraction_between_0_and_1, default=0.015, metavar="F",
                        help="share of the scene's pixels above 1 after scaling, between 0 and 1 (default 0.015)")
    parser.add_argument("--seed", type=random_seed, default=0, help="scene and noise seed")
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    import numpy as np

    from hdrcam.data.hdr_folder import read_hdr_image
    from hdrcam.data.night_scene import night_scene
    from hdrcam.data.saturation import clipped_fraction, fraction_shortfall, scale_to_clipped_fraction
    from hdrcam.io.exr import exr_orientation, is_exr_file, read_exr_attributes, write_exr
    from hdrcam.profiles import load_profile
    from hdrcam.train.checkpoint import load_model
    from hdrcam.limits import check_image_size
    from hdrcam.train.optical_capture import CAPTURE_BYTES_PER_PIXEL, capture_scene, fixed_psf

    if arguments.size is not None and arguments.scene != "night":
        raise InputError(f"--size sets the procedural 'night' scene's frame; {arguments.scene} is captured at its "
                         "own size (crop or resize the file instead)")
    outputs = [arguments.out] + ([arguments.truth] if arguments.truth else [])
    for option, path in zip(("--out", "--truth"), outputs):  # an EXR named .png fails every other program
        if path.suffix.lower() != ".exr":
            raise InputError(f"{option} {path}: simulate writes an OpenEXR file; name it NAME.exr")
    inputs = [] if arguments.scene == "night" else [Path(arguments.scene)]
    inputs += [Path(arguments.psf)] if arguments.psf and arguments.psf not in FIXED_PSFS else []
    inputs += [arguments.checkpoint] if arguments.checkpoint else []
    check_outputs(outputs, overwrite=arguments.overwrite, inputs=inputs)
    model = load_model(arguments.checkpoint) if arguments.checkpoint or not arguments.psf else None
    profile = load_profile(model.profile if model else "simulated")
    if arguments.psf:
        if arguments.psf not in FIXED_PSFS and not Path(arguments.psf).is_file():
            raise missing_input(arguments.psf, "a PSF (EXR file)", option="--psf",
                                missing=f"--psf {arguments.psf} does not exist")
        psf = fixed_psf(arguments.psf, profile)
    else:
        psf = model.psf
    margin = psf.shape[-1] // 2
    if arguments.scene == "night":
        height, width = arguments.size or NIGHT_SIZE_PX
        check_image_size("--size", height + 2 * margin, width + 2 * margin, CAPTURE_BYTES_PER_PIXEL,
                         "use a smaller --size")
        scene = night_scene(height + 2 * margin, width + 2 * margin, seed=arguments.seed, sources=40)
    else:
        scene = read_hdr_image(Path(arguments.scene), warn_negative=True)
        check_image_size(arguments.scene, scene.shape[0] + 2 * margin, scene.shape[1] + 2 * margin,
                         CAPTURE_BYTES_PER_PIXEL, "use a smaller scene")
        scene = np.pad(scene, ((margin, margin), (margin, margin), (0, 0)), mode="reflect")
    inner = scene[margin:scene.shape[0] - margin, margin:scene.shape[1] - margin]
    try:
        scene = scale_to_clipped_fraction(scene, arguments.clipped_fraction, scale_region=inner)
    except InputError as error:  # the scene's own fault: named, as every input error is
        raise InputError(f"{arguments.scene}: {error}") from None
    frame = capture_scene(scene, psf, profile, arguments.seed)
    truth = scene[margin:scene.shape[0] - margin, margin:scene.shape[1] - margin]
    reached = clipped_fraction(truth)
    shortfall = fraction_shortfall(reached, arguments.clipped_fraction, truth.shape[0] * truth.shape[1])
    if shortfall:
        warnings.warn(f"{arguments.scene}: scaled as asked, {shortfall}")
    attributes = {"scene": arguments.scene, "seed": arguments.seed, "units": "relative to sensor white"}
    if arguments.scene != "night" and is_exr_file(Path(arguments.scene)):  # a fused image in a sensor's orientation
        attributes["orientation"] = exr_orientation(read_exr_attributes(Path(arguments.scene)))
    outputs = [(arguments.out, frame)] + ([(arguments.truth, truth)] if arguments.truth else [])
    with atomic_paths([path for path, _ in outputs], overwrite=arguments.overwrite) as temporaries:  # both, or none
        for temporary, (_, pixels) in zip(temporaries, outputs):
            write_exr(temporary, pixels, channel_names=("R", "G", "B"), attributes=attributes, overwrite=True)
    print(json.dumps({"frame": str(arguments.out), "truth": str(arguments.truth) if arguments.truth else None,
                      "size": list(frame.shape[:2]), "clipped_fraction_scene": round(reached, 5),
                      "clipped_fraction_frame": round(float(np.mean(frame.max(axis=-1) >= 0.99)), 5)}))
    return 0
