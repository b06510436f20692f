"""fuse against the floor: reading the same RAW files with rawpy, side by side in one run.

A bracket of five 6000 x 4000 DNGs from the simulated A7 (night scene, 3 EV apart from 1/4000 s; made in a
temporary folder unless --bracket names one). Each repeat times, in turn: rawpy reading the five files
(imread + the visible Bayer data), ``hdrcam.fuse`` (read, merge, demosaic, colour; nothing written), what the
command adds to it - writing the EXR (RGB and the clipped mask, uncompressed, flushed to disk), the PNG
preview, and start-up (``hdrcam fuse --help`` in a fresh process) - and the ``hdrcam fuse`` command itself (a
fresh process: start-up, fuse, the EXR and the preview). Medians of --repeats.
Usage: python tools/bench_fuse.py [--bracket DIR] [--repeats 3] [--out tools/results/fuse-speed.md]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402
from reports import add_report_options, publish  # noqa: E402

import rawpy

import hdrcam
from hdrcam.cli.fuse_command import PREVIEW_SIDE_PX
from hdrcam.hdr.bracket_input import bracket_paths
from hdrcam.io.exr import write_exr_channels
from hdrcam.io.png import write_png
from hdrcam.parallel import worker_threads
from hdrcam.preview import reduced_for_preview, tonemap_rgb

PROFILE = "sony-a7-zeiss50-rank1"


def read_with_rawpy(paths: list[Path]) -> None:
    for path in paths:
        with rawpy.imread(str(path)) as raw:
            raw.raw_image_visible.copy()


def seconds(function) -> float:
    started = time.perf_counter()
    function()
    return time.perf_counter() - started


def measure(bracket: Path, repeats: int, scratch: Path) -> list[str]:
    paths = bracket_paths([bracket])
    hdrcam_command = str(Path(sys.executable).parent / "hdrcam")
    command = [hdrcam_command, "fuse", str(bracket), "--profile", PROFILE, "--overwrite", "--out",
               str(scratch / "fused.exr")]
    runs: dict[str, list[float]] = {label: [] for label in (
        "rawpy read", "hdrcam.fuse", "+ EXR write", "+ PNG preview", "+ start-up (`hdrcam fuse --help`)",
        "hdrcam fuse (command)")}
    load_before = os.getloadavg()[0]
    for _ in range(repeats):
        runs["rawpy read"].append(seconds(lambda: read_with_rawpy(paths)))
        started = time.perf_counter()
        image = hdrcam.fuse([bracket], profile=PROFILE)
        runs["hdrcam.fuse"].append(time.perf_counter() - started)
        runs["+ EXR write"].append(seconds(lambda: write_exr_channels(
            scratch / "library.exr", {"RGB": image.rgb, "clipped": image.clipped}, overwrite=True, compression="none")))
        runs["+ PNG preview"].append(seconds(lambda: write_png(
            scratch / "library.png", tonemap_rgb(reduced_for_preview(image.rgb, PREVIEW_SIDE_PX)), overwrite=True)))
        image = None  # freed before the command runs with its own images
        runs["+ start-up (`hdrcam fuse --help`)"].append(seconds(lambda: subprocess.run(
            [hdrcam_command, "fuse", "--help"], check=True, stdout=subprocess.DEVNULL)))
        runs["hdrcam fuse (command)"].append(seconds(lambda: subprocess.run(command, check=True,
                                                                           stdout=subprocess.DEVNULL)))
    floor = statistics.median(runs["rawpy read"])
    lines = [f"{len(paths)} frames of 6000 x 4000 (`python tools/bench_fuse.py --repeats {repeats}`; {worker_threads()} "
             "threads; medians):", "", "| what | seconds | x rawpy's read |", "|---|---|---|"]
    for label, times in runs.items():
        median = statistics.median(times)
        lines.append(f"| {label} | {median:.2f} | {median / floor:.1f} |")
    return lines + ["", f"Load average (1 min) {load_before:.1f} at the start, {os.getloadavg()[0]:.1f} at the end."]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bracket", type=Path, default=None, help="an existing bracket (default: make one)")
    parser.add_argument("--repeats", type=int, default=3)
    add_report_options(parser, "tools/results/fuse-speed.md")
    arguments = parser.parse_args()
    one_line_errors.refuse_existing(arguments.out, arguments.overwrite)
    with tempfile.TemporaryDirectory() as folder:
        bracket = arguments.bracket
        if bracket is None:
            bracket = Path(folder) / "bracket"
            hdrcam.capture_bracket(bracket, camera="sim", profile=PROFILE, scene="night", size_px=(6000, 4000),
                                   stops=5, ev_step=3.0, seed=0)
        lines = measure(bracket, arguments.repeats, Path(folder))
    publish(arguments, lines)


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
