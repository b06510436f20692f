"""Time per frame of the simulated cameras (sim, sim-usb) at full A7 size (6000 x 4000) and at 1024 x 1024.

Each configuration runs `hdrcam capture bracket` in a fresh process (so imports and PSF simulation are
counted once, as a user sees them) and reports the command's own per-frame figure and the peak RSS.
Usage: python tools/bench_capture.py [--sizes 6000x4000 1024x1024] [--stops 5]
"""

from __future__ import annotations

import argparse
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run(camera: str, size: str, stops: int, folder: Path) -> tuple[float, float, float]:
    out = folder / f"{camera}-{size}"
    command = [sys.executable, "-m", "hdrcam", "capture", "bracket", "--camera", camera, "--out", str(out),
               "--size", size, "--stops", str(stops), "--scene", "night", "--seed", "0"]
    started = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if result.returncode:
        raise SystemExit(f"{' '.join(command)} failed: {result.stderr.strip()}")
    per_frame = float(re.search(r"\(([\d.]+) s per frame\)", result.stdout).group(1))
    peak_gb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1e6
    return per_frame, wall, peak_gb


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sizes", nargs="+", default=["1024x1024", "6000x4000"])
    parser.add_argument("--stops", type=int, default=5)
    arguments = parser.parse_args()
    print("| camera | frame | s per frame (capture + DNG write + read-back) | command wall s | peak RSS GB (max so far) |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for size in arguments.sizes:
            for camera in ("sim", "sim-usb"):
                per_frame, wall, peak = run(camera, size, arguments.stops, Path(folder))
                print(f"| {camera} | {size} | {per_frame:.2f} | {wall:.1f} | {peak:.2f} |", flush=True)


if __name__ == "__main__":
    main()
