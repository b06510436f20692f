"""``hdrcam bad-pixels FRAME... --out LIST``: find a sensor's hot and dead pixels in RAW frames (darks, flats, or
photographs of different scenes) and write them as a dcraw bad-pixel list, which ``hdrcam reconstruct
--bad-pixels LIST`` repairs (as do dcraw -P and LibRaw). The finding is
:func:`hdrcam.calibrate.bad_pixels.find_bad_pixels`."""

from __future__ import annotations

import argparse
from pathlib import Path

from hdrcam.calibrate.bad_pixels import DEFAULT_CONFIRM_SHARE
from hdrcam.cli.arguments import share
from hdrcam.io.atomic import check_outputs


def register(commands) -> None:
    parser = commands.add_parser("bad-pixels", help="find hot and dead pixels in RAW frames", description=__doc__)
    parser.add_argument("frames", nargs="+", type=Path, metavar="FRAME",
                        help="RAW files of one camera, or folders of them (at least two frames)")
    parser.add_argument("--out", type=Path, required=True, help="the list to write (dcraw's format, text)")
    parser.add_argument("--confirm-share", type=share, default=DEFAULT_CONFIRM_SHARE, metavar="SHARE",
                        help="a pixel is bad where it stands out in at least this share of the frames "
                             f"(default {DEFAULT_CONFIRM_SHARE:g})")
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.calibrate.bad_pixels import bad_pixels_in, frames_of_one_camera, listed_frames
    from hdrcam.io.bad_pixels import write_bad_pixels

    check_outputs([arguments.out], overwrite=arguments.overwrite, inputs=listed_frames(arguments.frames))
    metadata = frames_of_one_camera(arguments.frames)  # a folder's non-RAW files skipped, with a warning
    frames = [meta.path for meta in metadata]
    bad = bad_pixels_in(metadata, arguments.confirm_share)
    write_bad_pixels(arguments.out, bad, overwrite=arguments.overwrite,
                     comment=f"found by hdrcam bad-pixels in {len(frames)} frames (confirm share "
                             f"{arguments.confirm_share:g}): {', '.join(path.name for path in frames[:4])}"
                             f"{', ...' if len(frames) > 4 else ''}")
    height, width = bad.shape
    print(f"{arguments.out}: {int(bad.sum())} bad pixels of {width} x {height} in {len(frames)} frames")
    return 0
