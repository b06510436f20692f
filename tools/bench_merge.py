"""Merge accuracy and speed: hdrcam's merge vs an oracle, OpenCV MergeDebevec and MergeRobertson.

A simulated A7 (simulated profile, Dirac PSF, no hot pixels) shoots 5 frames 3 EV apart of a night scene
stretched towards 1e5:1 (background 0.0025 .. 0.3, lamps up to 256; the contrast reached, 7e4:1 at full
size, is printed) with shutter times off their labels by up to 7 %. Every method merges the same
black-subtracted Bayer data; the oracle and OpenCV are given the true exposure times, hdrcam's merge
estimates them. OpenCV (8/16-bit input, hat weights, linear response) gets
each frame as a 3-channel uint16 image and its radiance is scaled to the truth by a median ratio (its units
are arbitrary). SNR = 20 log10(rms truth / rms error) over the darkest 20 %, the middle 20 % and the
brightest 5 % of pixels not clipped in every frame.
Also, with --full-size, times `hdrcam fuse` on a 6000 x 4000 bracket (peak RSS from /usr/bin/time).
Usage: python tools/bench_merge.py [--size 768x1024] [--full-size]
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from hdrcam.capture.backends import open_camera
from hdrcam.capture.bracket import BracketCapture, BracketPlan
from hdrcam.capture.scene import Scene
from hdrcam.data.night_scene import night_scene
from hdrcam.hdr.bracket_input import read_bracket
from hdrcam.hdr.merge import black_subtracted, merge_bayer
from hdrcam.optics.analytic import dirac
from hdrcam.profiles import load_profile


def snr_db(estimate: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    error = estimate[mask] - truth[mask]
    return 20 * np.log10(np.sqrt(np.mean(truth[mask] ** 2)) / np.sqrt(np.mean(error ** 2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", default="768x1024", help="HxW of the accuracy test")
    parser.add_argument("--full-size", action="store_true", help="also time hdrcam fuse at 6000 x 4000")
    arguments = parser.parse_args()
    height, width = map(int, arguments.size.split("x"))
    profile = load_profile("simulated")
    radiance = night_scene(height, width, seed=7)
    radiance[: height // 3, : width // 3] *= 0.5  # darker corner: 1e5:1 overall
    with tempfile.TemporaryDirectory() as folder:
        camera, simulated = open_camera("sim", profile, scene=Scene(height, width, radiance), psf=dirac(9), seed=7,
                                        exposure_error=0.07, hot_pixel_fraction=0.0)
        with camera:
            bracket = BracketCapture(camera, profile.camera, Path(folder), backend="sim", profile="simulated",
                                     show_progress=False, true_exposure_s=simulated.true_exposure_s).shoot(
                BracketPlan(shortest_s=1 / 4000, stops=5, ev_step=3.0))
        truth = simulated._rate(False) / simulated.reference_exposure_s
        frames = read_bracket([Path(folder)])
    true_s = np.array([f.true_exposure_s for f in bracket.frames])
    results = {}
    started = time.perf_counter()
    merged = merge_bayer(frames, profile.camera)
    results["hdrcam (estimated ratios)"] = (merged.rate, time.perf_counter() - started)
    relabelled = [dataclasses.replace(f, metadata=dataclasses.replace(f.metadata, exposure_s=t))
                  for f, t in zip(frames, true_s)]
    started = time.perf_counter()
    results["oracle (true exposures)"] = (merge_bayer(relabelled, profile.camera, estimate_ratios=False).rate,
                                          time.perf_counter() - started)
    images = [np.repeat(np.clip(black_subtracted(f), 0, 65535).astype(np.uint16)[..., None], 3, axis=2)
              for f in frames]
    for name, merger in (("OpenCV MergeDebevec", cv2.createMergeDebevec()),
                         ("OpenCV MergeRobertson", cv2.createMergeRobertson())):
        started = time.perf_counter()
        radiance_cv = merger.process(images, true_s.astype(np.float32))[..., 0]
        results[name] = (radiance_cv, time.perf_counter() - started)
    valid = ~merged.clipped_everywhere & (truth > 0)
    levels = truth[valid]
    dark = valid & (truth <= np.percentile(levels, 20))
    mid = valid & (truth >= np.percentile(levels, 40)) & (truth <= np.percentile(levels, 60))
    bright = valid & (truth >= np.percentile(levels, 95))
    print(f"scene {width} x {height}, contrast {levels.max() / levels.min():.3g}:1, exposures "
          f"{', '.join(f'{t:.5g}' for t in true_s)} s (labels {', '.join(f.exposure_label for f in bracket.frames)})")
    print("| method | SNR dark (dB) | SNR mid (dB) | SNR bright (dB) | time (s) |")
    print("|---|---|---|---|---|")
    for name, (estimate, seconds) in results.items():
        if name.startswith("OpenCV"):
            estimate = estimate * np.median(truth[mid] / np.maximum(estimate[mid], 1e-30))
        row = [snr_db(estimate, truth, region) for region in (dark, mid, bright)]
        print(f"| {name} | {row[0]:.1f} | {row[1]:.1f} | {row[2]:.1f} | {seconds:.3f} |")
    ratio_error = np.abs(np.diff(np.log(merged.exposures_s)) - np.diff(np.log(true_s))).max()
    label_error = np.abs(np.diff(np.log(merged.labelled_exposures_s)) - np.diff(np.log(true_s))).max()
    print(f"largest exposure-ratio error: labels {100 * label_error:.2f} %, estimated {100 * ratio_error:.3f} %")
    if arguments.full_size:
        full_size()


def full_size() -> None:
    with tempfile.TemporaryDirectory() as folder:
        capture = [sys.executable, "-m", "hdrcam", "capture", "bracket", "--camera", "sim", "--out",
                   f"{folder}/b", "--scene", "night", "--psf", "dirac", "--seed", "1"]
        subprocess.run(capture, check=True, capture_output=True)
        fuse = ["/usr/bin/time", "-v", sys.executable, "-m", "hdrcam", "fuse", f"{folder}/b", "--out",
                f"{folder}/hdr.exr"]
        started = time.perf_counter()
        result = subprocess.run(fuse, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - started
        peak_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", result.stderr).group(1))
        inner = re.search(r"in ([\d.]+) s", result.stdout).group(1)
        print(f"hdrcam fuse, 5 frames of 6000 x 4000: {inner} s merge+demosaic+colour+write, {wall:.1f} s wall, "
              f"peak RSS {peak_kb / 1e6:.2f} GB")


if __name__ == "__main__":
    main()
