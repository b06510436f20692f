"""``hdrcam inspect FILE...``: one JSON line per RAW file - make, model, format, size (the sensor's), orientation
(the EXIF code that displays it upright), CFA, exposure, ISO, black level, metadata white level, the clip level
measured from the data, the clipped fraction and where the colour matrix comes from. Files that cannot be read
get one line each on stderr (exit status 1)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hdrcam.errors import InputError


def register(commands) -> None:
    parser = commands.add_parser("inspect", help="what a RAW file holds, before trusting a capture",
                                 description=__doc__)
    parser.add_argument("files", type=Path, nargs="+", metavar="FILE", help="RAW files (anything LibRaw reads)")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.io.raw_summary import raw_summary

    failed = 0
    for path in arguments.files:
        try:
            summary = raw_summary(path)
        except InputError as error:
            print(f"hdrcam inspect: error: {error}", file=sys.stderr)
            failed += 1
            continue
        print(json.dumps(summary), flush=True)
    return 1 if failed else 0
