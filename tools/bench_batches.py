"""How fast training batches are drawn (hdrcam.train.batches) against the number of worker threads.

At the paper's scale (512 px crops; the A7 rank-1 PSF's 127 px margin) drawing, not the step, bounds a GPU
run: this times ``BatchStream.next_batch`` for --batches batches of --batch scenes per worker count, after
a warm-up batch drawn by another stream (photographs loaded), timed from the stream's start, so the batches it
drew ahead count; prints scenes per second and the load average.
Usage: python tools/bench_batches.py --data runs/data/train:0.6,procedural:0.3,../shared/data/hdr:0.1
           [--crop 512] [--margin 127] [--batch 8] [--batches 3] [--workers 1,2] [--out tools/results/batches.md]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402
from reports import add_report_options, publish  # noqa: E402

from hdrcam.data.scenes import SceneSource
from hdrcam.train.batches import BatchStream


def worker_counts(text: str) -> list[int]:
    """'1,2' -> [1, 2]; argparse reports anything but counts of at least 0 in one line."""
    try:
        counts = [int(value) for value in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected thread counts such as 1,2, got {text!r}") from None
    if any(count < 0 for count in counts):
        raise argparse.ArgumentTypeError(f"thread counts are at least 0, got {text!r}")
    return counts


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True)
    parser.add_argument("--crop", type=int, default=512)
    parser.add_argument("--margin", type=int, default=127)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--batches", type=int, default=3)
    parser.add_argument("--workers", type=worker_counts, default=[1, 2], help="comma-separated thread counts")
    add_report_options(parser, "tools/results/batches.md")
    arguments = parser.parse_args()
    one_line_errors.refuse_existing(arguments.out, arguments.overwrite)
    source = SceneSource(arguments.data)
    load_start = os.getloadavg()[0]
    lines = [f"`python tools/bench_batches.py --data {arguments.data} --crop {arguments.crop} --margin "
             f"{arguments.margin} --batch {arguments.batch} --batches {arguments.batches} --workers "
             f"{','.join(map(str, arguments.workers))}` on {os.cpu_count()} cores", "",
             "| worker threads | seconds per batch | scenes per second |", "|---|---|---|"]
    with BatchStream(source, crop_px=arguments.crop, margin_px=arguments.margin, batch=arguments.batch,
                     run_seed=1) as warm_up:
        warm_up.next_batch()
    for workers in arguments.workers:
        began = time.perf_counter()
        with BatchStream(source, crop_px=arguments.crop, margin_px=arguments.margin, batch=arguments.batch,
                         run_seed=0, workers=workers) as stream:
            for _ in range(arguments.batches):
                stream.next_batch()
            seconds = (time.perf_counter() - began) / arguments.batches
        lines.append(f"| {workers} | {seconds:.2f} | {arguments.batch / seconds:.1f} |")
    lines += ["", f"Load average (1 min) {load_start:.1f} at the start, {os.getloadavg()[0]:.1f} at the end."]
    publish(arguments, lines)
    return 0


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
