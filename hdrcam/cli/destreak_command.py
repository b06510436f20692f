"""``hdrcam destreak``: remove windshield streaks (paper Sec. 7) from captured frames.

Wiper-scratched windshields smear every light into a thin streak through it, like a 2-point star PSF.
A network trained behind random 2-point stars (rotations in (-8, -2.5) U (2.5, 8) degrees; ``hdrcam
design --psf windshield``) splits a frame into the streak-free image I_U and the streaks; this command
writes I_U within the streaks' reach of each clipped light and keeps the frame elsewhere
(:mod:`hdrcam.recon.destreak`). The default network is the shipped one (hdrcam/checkpoints/windshield-fast.pt).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from hdrcam.cli.arguments import compute_device
from hdrcam.errors import InputError
from hdrcam.io.atomic import check_writable

SHIPPED_WINDSHIELD = Path(__file__).resolve().parent.parent / "checkpoints" / "windshield-fast.pt"


def register(commands) -> None:
    parser = commands.add_parser("destreak", help="remove windshield streaks from frames", description=__doc__)
    parser.add_argument("inputs", nargs="+", type=Path, metavar="INPUT", help="RAW, EXR or 16-bit TIFF/PNG frames")
    parser.add_argument("--checkpoint", type=Path, default=SHIPPED_WINDSHIELD)
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--no-gate", dest="gate", action="store_false",
                        help="use the network's output everywhere, not only within the streaks' reach of a "
                             "clipped light")
    parser.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"))
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.io.exr import write_exr
    from hdrcam.io.ldr_frame import read_ldr_frame
    from hdrcam.io.png import write_png
    from hdrcam.preview import tonemap_rgb
    from hdrcam.recon.destreak import destreak_frame
    from hdrcam.train.checkpoint import load_model, read_checkpoint

    if read_checkpoint(arguments.checkpoint)["config"].get("psf") != "windshield":
        raise InputError(f"{arguments.checkpoint} was not trained on windshield streaks (design --psf windshield)")
    outputs = [(arguments.out / f"{s.stem}.exr", arguments.out / f"{s.stem}.png") for s in arguments.inputs]
    for pair in outputs:
        for path in pair:
            check_writable(path, overwrite=arguments.overwrite, inputs=arguments.inputs)
    model = load_model(arguments.checkpoint)
    frames = [read_ldr_frame(source) for source in arguments.inputs]
    for source, frame, (exr_path, png_path) in zip(arguments.inputs, frames, outputs):
        started = time.perf_counter()
        clean, report = destreak_frame(model.network, frame, psf_radius_px=model.psf.shape[-1] // 2,
                                       gate=arguments.gate, device=compute_device(arguments.device))
        write_exr(exr_path, clean, channel_names=("R", "G", "B"),
                  attributes={"source": str(source), "checkpoint": str(model.source)}, overwrite=arguments.overwrite)
        write_png(png_path, tonemap_rgb(clean), overwrite=arguments.overwrite)
        print(json.dumps({"input": str(source), "destreaked": str(exr_path), "preview": str(png_path),
                          "streak_zone_fraction": round(report.streak_zone_fraction, 4),
                          "seconds": round(time.perf_counter() - started, 2)}))
    return 0
