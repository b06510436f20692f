"""``hdrcam ingest DIR``: group the RAW files of a folder into brackets and write a manifest for each."""

from __future__ import annotations

import argparse
from pathlib import Path

from hdrcam.capture.ingest import DEFAULT_MAX_GAP_S, bracket_manifest, ingest_folder, settings_text, subfolder_hint
from hdrcam.cli.arguments import positive_float
from hdrcam.errors import InputError
from hdrcam.io.atomic import atomic_paths, check_outputs, write_text_atomic


def register(commands) -> None:
    parser = commands.add_parser("ingest", help="group RAW files into brackets", description=__doc__)
    parser.add_argument("folder", type=Path, help="folder of RAW files (ARW, DNG, ...)")
    parser.add_argument("--out", type=Path, default=None, help="where the manifests go (default: the folder)")
    parser.add_argument("--max-gap", type=positive_float, default=DEFAULT_MAX_GAP_S, metavar="S",
                        help=f"longest pause inside a bracket, after the exposure and a dark frame as long "
                             f"(long-exposure noise reduction) (default {DEFAULT_MAX_GAP_S:g} s)")
    parser.add_argument("--overwrite", action="store_true", help="replace existing manifests")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    out = arguments.out or arguments.folder
    result = ingest_folder(arguments.folder, arguments.max_gap)
    if not result.brackets:
        reasons = "; ".join(result.report[:3])
        if len(result.report) > 3:
            reasons += f"; and {len(result.report) - 3} more"
        hint = subfolder_hint(arguments.folder)
        raise InputError(f"{arguments.folder}: no brackets found ({reasons or 'no RAW files in it'}); "
                         f"give a folder of bracketed RAW frames{hint}")
    names = [out / f"bracket-{index:02d}.json" for index in range(1, len(result.brackets) + 1)]
    check_outputs(names, overwrite=arguments.overwrite)
    manifests = [bracket_manifest(frames, out, {"ingested_from": str(arguments.folder)}) for frames in result.brackets]
    with atomic_paths(names, overwrite=arguments.overwrite) as temporaries:  # all of them, or none
        for temporary, manifest in zip(temporaries, manifests):
            write_text_atomic(temporary, manifest.to_json(), overwrite=True)  # an error names the file
    for path, frames, manifest in zip(names, result.brackets, manifests):
        exposures = ", ".join(frame.exposure_label for frame in manifest.frames)
        print(f"{path}: {len(frames)} frames, {settings_text(frames[0])}, exposures {exposures}")
    for line in result.report:
        print(line)
    return 0
