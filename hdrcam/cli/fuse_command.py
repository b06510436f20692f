"""``hdrcam fuse BRACKET --out X.exr``: merge a RAW bracket into linear HDR (EXR) with a preview PNG."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from hdrcam.cli.arguments import add_profile_option
from hdrcam.io.atomic import check_outputs
from hdrcam.io.demosaic import DEFAULT_METHOD, FLOAT_METHODS
from hdrcam.profiles import load_profile


def register(commands) -> None:
    parser = commands.add_parser("fuse", help="merge a RAW bracket into linear HDR", description=__doc__)
    parser.add_argument("bracket", type=Path, nargs="+", help="bracket.json, a folder of RAW files, or RAW files")
    parser.add_argument("--out", type=Path, required=True, help="output EXR (a PNG preview goes beside it)")
    parser.add_argument("--darks", type=Path, default=None, help="dark frames (bracket.json or folder)")
    parser.add_argument("--camera-rgb", action="store_true", help="keep camera RGB (no colour matrix)")
    parser.add_argument("--variance", action="store_true", help="add per-channel variance channels")
    parser.add_argument("--half", action="store_true", help="write half floats (refused above 65504)")
    parser.add_argument("--overwrite", action="store_true")
    parser.add_argument("--demosaic", choices=FLOAT_METHODS, default=DEFAULT_METHOD,
                        help=f"demosaicing (default {DEFAULT_METHOD}: fast; menon2007: sharper edges, slower)")
    add_profile_option(parser)
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    import numpy as np

    from hdrcam.hdr.bracket_input import bracket_paths
    from hdrcam.hdr.fuse import fuse
    from hdrcam.io.exr import write_exr
    from hdrcam.io.png import write_png
    from hdrcam.preview import tonemap_rgb

    profile = load_profile(arguments.profile)
    out: Path = arguments.out
    preview = out.with_suffix(".png")
    inputs = bracket_paths(arguments.bracket)
    check_outputs((out, preview), overwrite=arguments.overwrite,
                  inputs=inputs + ([arguments.darks] if arguments.darks else []))
    started = time.perf_counter()
    image = fuse(arguments.bracket, profile.camera, darks=arguments.darks, camera_rgb=arguments.camera_rgb,
                 with_variance=arguments.variance, demosaic_method=arguments.demosaic)
    channels = [image.rgb[..., 0], image.rgb[..., 1], image.rgb[..., 2], image.clipped.astype(np.float32)]
    names = ["R", "G", "B", "clipped"]
    if image.variance is not None:
        channels += [image.variance[..., c] for c in range(3)]
        names += ["variance.R", "variance.G", "variance.B"]
    write_exr(out, np.stack(channels, axis=-1), channel_names=tuple(names), attributes=image.attributes(),
              half=arguments.half, overwrite=arguments.overwrite)
    write_png(preview, tonemap_rgb(image.rgb), overwrite=arguments.overwrite)
    seconds = time.perf_counter() - started
    merge = image.merge
    print(f"{len(image.frames)} frames {image.rgb.shape[1]} x {image.rgb.shape[0]}, {image.colour}; "
          f"clip level {merge.clip_level_dn:.0f} DN above black; {int(image.clipped.sum())} px clipped in every frame")
    for note in merge.notes:
        print(f"  {note}")
    print(f"-> {out} and {preview} in {seconds:.1f} s")
    return 0
