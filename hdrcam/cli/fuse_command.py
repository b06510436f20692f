"""``hdrcam fuse BRACKET --out X.exr``: merge a RAW bracket into linear HDR (EXR) with a preview PNG.

The EXR is float32 (``--half``: 16-bit), uncompressed unless ``--compression zip`` (lossless, 15-19 %
smaller for noisy data and 1-2.5 s slower at 18-24 MP), in the sensor's orientation (its ``orientation``
attribute: the EXIF code that displays it upright); the preview is tone-mapped from the image reduced to at
most 2048 px (PREVIEW_SIDE_PX) on its longer side and turned upright. The preview is made on a second thread
while the EXR is written (OpenEXR releases the GIL); the two are published together once both are written: a
failure or an interrupt before that leaves neither."""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from hdrcam.cli.arguments import add_profile_option
from hdrcam.errors import InputError
from hdrcam.io.atomic import check_outputs, check_writable
from hdrcam.io.demosaic import DEFAULT_METHOD, FLOAT_METHODS
from hdrcam.profiles import load_profile

PREVIEW_SIDE_PX = 2048


def register(commands) -> None:
    parser = commands.add_parser("fuse", help="merge a RAW bracket into linear HDR", description=__doc__)
    parser.add_argument("bracket", type=Path, nargs="+", help="bracket.json, a folder of RAW files, or RAW files")
    parser.add_argument("--out", type=Path, required=True, help="output EXR (a PNG preview goes beside it)")
    parser.add_argument("--darks", type=Path, default=None, help="dark frames (bracket.json or folder)")
    parser.add_argument("--bad-pixels", type=Path, default=None, metavar="LIST",
                        help="the sensor's hot and dead pixels (a dcraw list, from 'hdrcam bad-pixels'), replaced "
                             "by their same-colour neighbours in the merged mosaic")
    parser.add_argument("--camera-rgb", action="store_true", help="keep camera RGB (no colour matrix)")
    parser.add_argument("--variance", action="store_true", help="add per-channel variance channels")
    parser.add_argument("--half", action="store_true",
                        help="write RGB as half floats (refused above 65504); variances stay float32")
    parser.add_argument("--compression", choices=("none", "zip"), default="none",
                        help="EXR compression (default none: fastest; zip: lossless, 15-19 %% smaller, slower)")
    parser.add_argument("--overwrite", action="store_true")
    parser.add_argument("--demosaic", choices=FLOAT_METHODS, default=DEFAULT_METHOD,
                        help=f"demosaicing (default {DEFAULT_METHOD}: fast; menon2007: sharper edges, slower)")
    add_profile_option(parser)
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.cli import require_standard_output
    from hdrcam.hdr.bracket_input import bracket_input_files
    from hdrcam.hdr.fuse import fuse
    from hdrcam.io.atomic import atomic_paths, write_bytes_atomic
    from hdrcam.io.bad_pixels import read_bad_pixels
    from hdrcam.io.exr import write_exr_channels
    from hdrcam.io.png import encoded_png
    from hdrcam.preview import display_oriented, reduced_for_preview, tonemap_rgb

    require_standard_output()  # the summary goes there: a closed one is refused before any file is read or written
    profile = load_profile(arguments.profile)
    out: Path = arguments.out
    preview = out.with_suffix(".png")
    inputs = bracket_input_files(arguments.bracket)
    if arguments.darks:
        inputs += bracket_input_files([arguments.darks], kind="dark")
    if arguments.bad_pixels:
        inputs.append(arguments.bad_pixels)
    check_writable(out, overwrite=True, inputs=inputs)  # an input given as the output is refused as such first
    if out.suffix.lower() != ".exr":
        raise InputError(f"--out {out}: name the EXR (NAME.exr); its preview is written beside it as NAME.png")
    check_outputs((out, preview), overwrite=arguments.overwrite, inputs=inputs)
    started = time.perf_counter()
    bad_pixels = read_bad_pixels(arguments.bad_pixels) if arguments.bad_pixels else None
    image = fuse(arguments.bracket, profile.camera, darks=arguments.darks, camera_rgb=arguments.camera_rgb,
                 with_variance=arguments.variance, demosaic_method=arguments.demosaic, bad_pixels=bad_pixels)
    channels = image.exr_channels()

    def preview_png() -> bytes:
        upright = display_oriented(tonemap_rgb(reduced_for_preview(image.rgb, PREVIEW_SIDE_PX)), image.orientation)
        return encoded_png(upright, preview)

    with ThreadPoolExecutor(1) as previewer, atomic_paths((out, preview), overwrite=arguments.overwrite) as (
            exr_temporary, png_temporary):  # both published once both are written, or neither
        png = previewer.submit(preview_png)  # the EXR on this thread, where an interrupt discards it unfinished
        write_exr_channels(exr_temporary, channels, attributes=image.attributes(), half=arguments.half,
                           float32_channels=image.FLOAT32_CHANNELS, overwrite=True, compression=arguments.compression)
        write_bytes_atomic(png_temporary, png.result(), overwrite=True)
    seconds = time.perf_counter() - started
    merge = image.merge
    print(f"{len(image.frame_metadata)} frames {image.rgb.shape[1]} x {image.rgb.shape[0]}, {image.colour}; "
          f"clip level {merge.clip_level_dn:.0f} DN above black; {int(image.clipped.sum())} px clipped in every frame")
    if bad_pixels is not None:
        print(f"  {image.bad_pixels_repaired} listed bad pixels repaired")
    for note in merge.notes:
        print(f"  {note}")
    print(f"-> {out} and {preview} in {seconds:.1f} s")
    return 0
