"""``hdrcam destreak``: remove windshield streaks (paper Sec. 7) from captured frames.

Wiper-scratched windshields smear every light into a thin streak through it, like a 2-point star PSF.
``--method fit`` (the default) fits the streaks' angle and each clipped light's brightness to the frame and
subtracts them (:mod:`hdrcam.recon.windshield_fit`). ``--method network`` uses a network trained behind
random 2-point stars (rotations in (-8, -2.5) U (2.5, 8) degrees; ``hdrcam design --psf windshield``), which
splits a frame into the streak-free image I_U and the streaks, and writes I_U within the streaks' reach of
each clipped light (:mod:`hdrcam.recon.destreak`); its default is the shipped network
(hdrcam/checkpoints/windshield-fast.pt). tools/bench_destreak.py measures both.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from hdrcam.cli.arguments import compute_device
from hdrcam.errors import InputError
from hdrcam.io.atomic import atomic_paths, check_outputs_of_inputs

SHIPPED_WINDSHIELD = Path(__file__).resolve().parent.parent / "checkpoints" / "windshield-fast.pt"


def register(commands) -> None:
    parser = commands.add_parser("destreak", help="remove windshield streaks from frames", description=__doc__)
    parser.add_argument("inputs", nargs="+", type=Path, metavar="INPUT", help="RAW, EXR or 16-bit TIFF/PNG frames")
    parser.add_argument("--method", choices=("fit", "network"), default="fit",
                        help="fit: subtract the fitted streaks (default); network: the windshield network's I_U")
    parser.add_argument("--checkpoint", type=Path, default=None,
                        help="with --method network: the windshield network (default: the shipped one)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--no-gate", dest="gate", action="store_false",
                        help="with --method network: use the network's output everywhere (clipped channels "
                             "excepted), not only within the streaks' reach of a clipped light")
    parser.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"))
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.io.exr import write_exr
    from hdrcam.io.ldr_frame import read_ldr_frame_and_orientation
    from hdrcam.io.png import write_png
    from hdrcam.preview import display_oriented, tonemap_rgb
    from hdrcam.recon.destreak import destreak_frame
    from hdrcam.recon.tiling import refuse_all_clipped
    from hdrcam.recon.windshield_fit import subtract_windshield_streaks
    from hdrcam.train.checkpoint import load_model

    network = arguments.method == "network"
    if not network:
        for option, given in (("--checkpoint", arguments.checkpoint is not None), ("--no-gate", not arguments.gate),
                              (f"--device {arguments.device}", arguments.device != "auto")):
            if given:
                raise InputError(f"{option} applies only to --method network (--method fit, the default, "
                                 "uses no network)")
    checkpoint = arguments.checkpoint or SHIPPED_WINDSHIELD
    model = load_model(checkpoint) if network else None  # read once: its fixed PSF says what it was trained for
    if model is not None and model.fixed_psf != "windshield":
        raise InputError(f"{checkpoint} was not trained on windshield streaks (design --psf windshield)")
    outputs = [(arguments.out / f"{s.stem}.exr", arguments.out / f"{s.stem}.png") for s in arguments.inputs]
    check_outputs_of_inputs(zip(arguments.inputs, outputs), overwrite=arguments.overwrite, inputs=arguments.inputs)
    frames = [read_ldr_frame_and_orientation(source) for source in arguments.inputs]  # RAW: sensor orientation
    for source, (frame, _) in zip(arguments.inputs, frames):  # every input checked before any work
        refuse_all_clipped(frame, str(source))
    for source, (frame, orientation), (exr_path, png_path) in zip(arguments.inputs, frames, outputs):
        started = time.perf_counter()
        if network:
            clean, report = destreak_frame(model.network, frame, psf_radius_px=model.psf.shape[-1] // 2,
                                           gate=arguments.gate, device=compute_device(arguments.device))
            method = {"checkpoint": str(model.source)}
            work = {"streak_zone_fraction": round(report.streak_zone_fraction, 4)}
        else:
            clean, fit = subtract_windshield_streaks(frame)
            removed = fit.clusters - fit.clusters_left  # the angle says something only where streaks were removed
            method = {"method": "streak fit", "clusters_destreaked": f"{removed} of {fit.clusters}",
                      "angle_deg": f"{fit.angle_deg:.2f}" if removed else "none"}
            work = {"work": fit.summary()}
        with atomic_paths((exr_path, png_path), overwrite=arguments.overwrite) as (exr_temporary, png_temporary):
            write_exr(exr_temporary, clean, channel_names=("R", "G", "B"),  # a frame's two files, or neither
                      attributes={"source": str(source), "orientation": orientation, **method}, overwrite=True)
            write_png(png_temporary, display_oriented(tonemap_rgb(clean), orientation), overwrite=True)
        print(json.dumps({"input": str(source), "destreaked": str(exr_path), "preview": str(png_path), **work,
                          "seconds": round(time.perf_counter() - started, 2)}))
    return 0
