"""``hdrcam reconstruct``: captured LDR frames -> linear HDR EXR (+ unreliable-pixel mask and confidence map)
and PNG previews. The pipeline is :func:`hdrcam.api.reconstruct`; this module reads and writes files.

A RAW frame is reconstructed in the sensor's orientation (the PSF's): the EXR stays so, with the file's EXIF
Orientation code as its ``orientation`` attribute, and the PNG previews are turned upright."""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

from hdrcam.cli.arguments import compute_device, int_at_least, positive_int
from hdrcam.errors import InputError
from hdrcam.io.atomic import atomic_paths, check_outputs_of_inputs
from hdrcam.io.demosaic import DEFAULT_METHOD, METHODS
from hdrcam.recon.window_sizes import DEFAULT_CORE_PX, DEFAULT_HALO_PX, MIN_TILE_PX


def register(commands) -> None:
    parser = commands.add_parser("reconstruct", help="captured LDR frames -> HDR", description=__doc__)
    parser.add_argument("inputs", nargs="+", type=Path, metavar="INPUT", help="RAW, EXR or 16-bit TIFF/PNG frames")
    parser.add_argument("--checkpoint", type=Path, default=None,
                        help="network: a checkpoint, or an .onnx file from 'hdrcam export' run with onnxruntime "
                             "(default: the shipped checkpoint)")
    parser.add_argument("--psf", type=Path, default=None,
                        help="the camera's measured PSF (calibration/NAME/psf.exr) for the streak check "
                             "(default: the checkpoint's PSF)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--no-adaptive", dest="adaptive", action="store_false",
                        help="run the network on every tile, also far from any clipped pixel")
    parser.add_argument("--streak-fit", action="store_true",
                        help="before the consistency check, refit each clipped blob's brightness to the streaks "
                             "by least squares (off by default: on real photographs it overshoots, see README; one "
                             "network: no partner)")
    partners = parser.add_mutually_exclusive_group()
    partners.add_argument("--partner", type=Path, default=None, metavar="CHECKPOINT",
                          help="a second network trained for the same PSF: keep only what both paint unless the "
                               "streaks confirm one (default: NAME-partner.pt beside the checkpoint NAME.pt, when "
                               "there is one; twice the network time; see README)")
    partners.add_argument("--no-partner", action="store_true",
                          help="the checkpoint's network alone, even where a partner lies beside it")
    parser.add_argument("--no-mirror-check", dest="mirror_check", action="store_false",
                        help="one network pass instead of two (the frame and its mirror image, keeping only what "
                             "both paint): half the network time, more invented highlights (see README)")
    parser.add_argument("--place-highlights", action="store_true",
                        help="add light where long streaks say a clipped blob's light sits (a sun inside its glow), "
                             "vetted by the frame's judge; runs only for PSFs with streaks past 48 px (see README)")
    parser.add_argument("--tile", type=int_at_least(MIN_TILE_PX), default=DEFAULT_CORE_PX, metavar="PX",
                        help=f"largest tile core, at least {MIN_TILE_PX} (default {DEFAULT_CORE_PX}; bounds memory, "
                             "and changes the result: the networks normalise each window by its own statistics; "
                             "the default is what evaluate scores)")
    parser.add_argument("--halo", type=positive_int, default=DEFAULT_HALO_PX, metavar="PX",
                        help=f"tile context per side (default {DEFAULT_HALO_PX})")
    parser.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"))
    parser.add_argument("--precision", default="float32", choices=("float32", "float16", "bfloat16"),
                        help="network precision; half precisions on CUDA only (they are slow on CPUs)")
    parser.add_argument("--demosaic", choices=METHODS, default=DEFAULT_METHOD,
                        help=f"demosaicing of RAW inputs (default {DEFAULT_METHOD}: fast; edge-aware, menon2007: "
                             "sharper edges, slower)")
    parser.add_argument("--bad-pixels", type=Path, default=None, metavar="LIST",
                        help="the sensor's hot and dead pixels (a dcraw list, from 'hdrcam bad-pixels'): each is "
                             "replaced by its same-colour neighbours before anything else, so none is taken for "
                             "light or for its absence")
    parser.add_argument("--vgg-weights", type=Path, default=None)
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def output_paths(out: Path, source: Path) -> tuple[Path, Path, Path]:
    """The HDR EXR, its preview and the confidence map's preview of one input."""
    return out / f"{source.stem}.exr", out / f"{source.stem}.png", out / f"{source.stem}-confidence.png"


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.cli import require_standard_output

    require_standard_output()  # each frame's JSON line goes there: a closed one is refused before any work
    import numpy as np
    import torch

    from tqdm import tqdm

    from hdrcam.io.exr import write_exr
    from hdrcam.io.bad_pixels import read_bad_pixels
    from hdrcam.io.ldr_frame import read_ldr_capture
    from hdrcam.io.png import write_png
    from hdrcam.optics.psf_file import load_psf
    from hdrcam.preview import confidence_preview, display_oriented, tonemap_rgb
    from hdrcam.profiles import load_profile
    from hdrcam.api import checked_device, load_network_model, network_windows, reconstruct, resolve_partner
    from hdrcam.recon.streaks import check_streaks
    from hdrcam.recon.tiling import plan_regions, refuse_all_clipped

    dtype = {"float32": torch.float32, "float16": torch.float16, "bfloat16": torch.bfloat16}[arguments.precision]
    device = checked_device(compute_device(arguments.device), dtype)  # before any file is read
    inputs = [*arguments.inputs, *(path for path in (arguments.psf, arguments.checkpoint, arguments.partner,
                                                     arguments.bad_pixels) if isinstance(path, Path))]
    check_outputs_of_inputs(((source, output_paths(arguments.out, source)) for source in arguments.inputs),
                            overwrite=arguments.overwrite, inputs=inputs)
    if arguments.streak_fit and arguments.partner:
        raise InputError("--streak-fit refits one network's proposal: leave out --partner")
    model = load_network_model(arguments.checkpoint, vgg_weights=arguments.vgg_weights)
    wanted = None if arguments.no_partner or arguments.streak_fit else arguments.partner or "auto"
    partner = resolve_partner(model, wanted, vgg_weights=arguments.vgg_weights)  # before any frame is read
    psf = load_psf(arguments.psf) if arguments.psf else model.psf
    core_radius = load_profile(model.profile).simulation.energy_centre_radius_px
    bad_pixels = read_bad_pixels(arguments.bad_pixels) if arguments.bad_pixels else None
    captures = [read_ldr_capture(source, arguments.demosaic, bad_pixels)
                for source in arguments.inputs]  # every input checked before any work
    frames = [capture.rgb for capture in captures]
    for source, frame in zip(arguments.inputs, frames):
        refuse_all_clipped(frame, str(source))
    plans = [plan_regions(frame, psf_radius_px=psf.shape[-1] // 2, adaptive=arguments.adaptive,
                          core_px=arguments.tile, halo_px=arguments.halo) for frame in frames]
    progress = tqdm(total=sum(network_windows(plan, psf, mirror_check=arguments.mirror_check,
                                                  partner=partner is not None) for plan in plans),
                    desc="reconstruct", unit="window")
    for source, capture, plan in zip(arguments.inputs, captures, plans):
        frame, orientation = capture.rgb, capture.orientation
        started = time.perf_counter()
        result = reconstruct(frame, model, psf=psf, adaptive=arguments.adaptive,
                             tile_px=arguments.tile, halo_px=arguments.halo, streak_fit=arguments.streak_fit,
                             mirror_check=arguments.mirror_check, partner=partner,
                             place_highlights=arguments.place_highlights, neutral_rgb=capture.neutral_rgb,
                             device=device, dtype=dtype, progress=progress, regions=plan)
        streaks = check_streaks(frame, psf, core_radius)
        with tqdm.external_write_mode(file=sys.stderr):  # lines of their own, not run on from the progress bar
            if streaks.warning():
                warnings.warn(f"{source.name}: {streaks.warning()}")
            if result.consistency.fallen_back_pixels or result.consistency.defect_pixels:
                print(f"{source.name}: {result.consistency.summary()} (confidence map: "
                      f"{output_paths(arguments.out, source)[2].name})", file=sys.stderr)
        exr_path, png_path, confidence_path = output_paths(arguments.out, source)
        attributes = {"source": str(source), "checkpoint": str(model.source),
                      "partner": str(partner.source) if partner is not None else "none",
                      "units": "relative radiance, 1.0 = sensor white at the capture's exposure",
                      "colour": "camera RGB", "orientation": orientation,
                      "windows_run": result.tiles.windows_run, "windows": result.tiles.windows,
                      "clipped_streak_pixels": streaks.clipped_streak_pixels,
                      "fallback_fraction": round(result.fallback_fraction, 4),
                      "bad_pixels_repaired": capture.repaired_pixels,
                      "colour_filled_samples": result.colour_filled}
        pixels = np.concatenate([result.hdr, streaks.mask[..., None].astype(np.float32),
                                 result.confidence[..., None]], axis=-1)
        with atomic_paths((exr_path, png_path, confidence_path), overwrite=arguments.overwrite) as (
                exr_temporary, png_temporary, confidence_temporary):  # a frame's three files, or none
            write_exr(exr_temporary, pixels, channel_names=("R", "G", "B", "unreliable", "confidence"),
                      attributes=attributes, overwrite=True)
            write_png(png_temporary, display_oriented(tonemap_rgb(result.hdr), orientation), overwrite=True)
            write_png(confidence_temporary, display_oriented(confidence_preview(result.confidence), orientation),
                      overwrite=True)
        print(json.dumps({"input": str(source), "hdr": str(exr_path), "preview": str(png_path),
                          "confidence": str(confidence_path), "size": list(frame.shape[:2]),
                          "seconds": round(time.perf_counter() - started, 2), "work": result.tiles.summary(),
                          "streak_fit": result.streak_fit, "placement": result.placement,
                          "consistency": result.consistency.summary(),
                          "fallback_fraction": round(result.fallback_fraction, 4),
                          "sensor_defect_pixels": result.consistency.defect_pixels,
                          "bad_pixels_repaired": capture.repaired_pixels,
                          "colour_filled_samples": result.colour_filled,
                          "clipped_streak_pixels": streaks.clipped_streak_pixels}))
    progress.close()
    return 0
