"""``hdrcam ingest DIR``: group the RAW files of a folder into brackets and write a manifest for each."""

from __future__ import annotations

import argparse
from pathlib import Path

from hdrcam.capture.ingest import DEFAULT_MAX_GAP_S, bracket_manifest, ingest_folder
from hdrcam.cli.arguments import positive_float
from hdrcam.io.atomic import check_writable


def register(commands) -> None:
    parser = commands.add_parser("ingest", help="group RAW files into brackets", description=__doc__)
    parser.add_argument("folder", type=Path, help="folder of RAW files (ARW, DNG, ...)")
    parser.add_argument("--out", type=Path, default=None, help="where the manifests go (default: the folder)")
    parser.add_argument("--max-gap", type=positive_float, default=DEFAULT_MAX_GAP_S, metavar="S",
                        help=f"longest pause inside a bracket, after the exposure (default {DEFAULT_MAX_GAP_S:g} s)")
    parser.add_argument("--overwrite", action="store_true", help="replace existing manifests")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    out = arguments.out or arguments.folder
    result = ingest_folder(arguments.folder, arguments.max_gap)
    names = [out / f"bracket-{index:02d}.json" for index in range(1, len(result.brackets) + 1)]
    for path in names:
        check_writable(path, overwrite=arguments.overwrite)
    for path, frames in zip(names, result.brackets):
        manifest = bracket_manifest(frames, out, {"ingested_from": str(arguments.folder)})
        manifest.write(out, path.name, overwrite=arguments.overwrite)
        exposures = ", ".join(f"{frame.exposure_s:g}" for frame in manifest.frames)
        print(f"{path}: {len(frames)} frames, ISO {frames[0].iso or '?'}, f/{frames[0].f_number or '?'}, "
              f"exposures {exposures} s")
    for line in result.report:
        print(line)
    if not result.brackets:
        print(f"no brackets found in {arguments.folder}")
        return 1
    return 0
