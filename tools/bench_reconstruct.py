"""Speed-accuracy of `hdrcam reconstruct`: preset x frame size x scene-adaptive compute on/off.

Test frames: procedural night scenes (seeds 0..N-1) scaled so 1.5 % of the pixels clip, captured through
the checkpoint's PSF with the simulated sensor's noise. Layout ``uniform``: about 12 light sources per
megapixel anywhere (the 1.5 % then includes bright background, so clipping is everywhere); ``clustered``:
a dark frame (background at 1/20) whose lights, 200 per megapixel of their block, fill a block of 1/4 x 1/2
of the frame (a lit street in a dark scene). For each
configuration: median wall time of the reconstruction (the default tiles: cores of at most 512 px, 32 px halos), peak RSS of the process
that ran it (one subprocess per configuration), windows run, and linear PSNR (peak 2^8) against the truth;
also the LDR frame's PSNR. Presets other than the checkpoint's have no trained weights here: their rows
give cost only. Writes a markdown table and a Pareto plot (PSNR against time).
Usage: python tools/bench_reconstruct.py [--sizes 512,1024,4000x6000] [--presets fast,lite] [--frames 3]
       [--layout clustered|uniform]
       [--out tools/results/reconstruct]
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

from hdrcam.data.night_scene import night_scene
from hdrcam.data.saturation import scale_to_clipped_fraction
from hdrcam.evaluate.metrics import psnr_linear
from hdrcam.io.png import write_png
from hdrcam.preview import line_plot
from hdrcam.profiles import load_profile
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.presets import preset
from hdrcam.recon.tiling import reconstruct_frame
from hdrcam.recon.vgg import load_vgg19
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import capture_scene

SOURCES_PER_MEGAPIXEL = 12


def test_frame(height: int, width: int, seed: int, psf: np.ndarray, profile, layout: str = "uniform"
               ) -> tuple[np.ndarray, np.ndarray]:
    margin = psf.shape[-1] // 2
    if layout == "uniform":
        sources = max(4, round(SOURCES_PER_MEGAPIXEL * height * width / 1e6))
        scene = night_scene(height + 2 * margin, width + 2 * margin, seed=seed, sources=sources)
    else:
        scene = night_scene(height + 2 * margin, width + 2 * margin, seed=seed, sources=0) / 20.0
        block_height, block_width = height // 2, width // 4
        lights = night_scene(block_height, block_width, seed=seed + 1,
                             sources=max(4, round(200 * block_height * block_width / 1e6)))
        top, left = margin + height // 4, margin + width // 8
        scene[top:top + block_height, left:left + block_width] = lights
    scene = scale_to_clipped_fraction(scene, 0.015, scale_region=scene[margin:-margin, margin:-margin])
    return capture_scene(scene, psf, profile, seed), scene[margin:-margin, margin:-margin]


def single(arguments) -> None:
    """One configuration in this process; prints one JSON line."""
    model = load_model(arguments.checkpoint)
    network = model.network
    if arguments.preset != model.preset:
        torch.manual_seed(0)
        chosen = preset(arguments.preset)
        network = ReconstructionNet(chosen, load_vgg19(random_features=True) if chosen.vgg_features else None)
    profile = load_profile(model.profile)
    height, width = arguments.height, arguments.width
    times, psnrs, ldr_psnrs, runs = [], [], [], []
    for seed in range(arguments.frames):
        frame, truth = test_frame(height, width, seed, model.psf, profile, arguments.layout)
        started = time.perf_counter()
        hdr, report = reconstruct_frame(network, frame, psf_radius_px=model.psf.shape[-1] // 2,
                                        adaptive=arguments.adaptive)
        times.append(time.perf_counter() - started)
        psnrs.append(psnr_linear(hdr, truth))
        ldr_psnrs.append(psnr_linear(frame, truth))
        runs.append(f"{report.windows_run} ({100 * report.network_pixels / report.full_frame_network_pixels:.0f} %)")
    print(json.dumps({"seconds": statistics.median(times), "psnr": float(np.mean(psnrs)),
                      "ldr_psnr": float(np.mean(ldr_psnrs)), "windows": runs,
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="512,1024,4000x6000")
    parser.add_argument("--presets", default="fast,lite")
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--layout", choices=("uniform", "clustered"), default="clustered")
    parser.add_argument("--checkpoint", default=None)
    parser.add_argument("--out", type=Path, default=Path("tools/results/reconstruct"))
    parser.add_argument("--single", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--preset", default="fast", help=argparse.SUPPRESS)
    parser.add_argument("--height", type=int, default=512, help=argparse.SUPPRESS)
    parser.add_argument("--width", type=int, default=512, help=argparse.SUPPRESS)
    parser.add_argument("--adaptive", type=int, default=1, help=argparse.SUPPRESS)
    arguments = parser.parse_args()
    if arguments.single:
        return single(arguments)
    trained = load_model(arguments.checkpoint).preset
    arguments.out.mkdir(parents=True, exist_ok=True)
    lines = [f"Machine: {platform.processor() or platform.machine()}, {torch.get_num_threads()} threads, CPU, "
             f"float32. Layout {arguments.layout}; {arguments.frames} frames per size (1 at 24 MP).", "",
             "| preset | size | adaptive | median s | peak RSS MB | windows run (share of full-frame network px) | PSNR (dB) | LDR PSNR (dB) |",
             "|---|---|---|---|---|---|---|---|"]
    points: dict[str, tuple[list, list]] = {}
    for name in arguments.presets.split(","):
        for size in arguments.sizes.split(","):
            height, width = (int(v) for v in (size.split("x") if "x" in size else (size, size)))
            frames = 1 if height * width > 4e6 else arguments.frames
            for adaptive in (1, 0):
                command = [sys.executable, __file__, "--single", "--preset", name, "--height", str(height),
                           "--width", str(width), "--adaptive", str(adaptive), "--frames", str(frames),
                           "--layout", arguments.layout]
                if arguments.checkpoint:
                    command += ["--checkpoint", arguments.checkpoint]
                result = json.loads(subprocess.run(command, check=True, capture_output=True,
                                                   text=True).stdout.strip().splitlines()[-1])
                scored = name == trained
                psnr = f"{result['psnr']:.2f}" if scored else "untrained"
                lines.append(f"| {name} | {height}x{width} | {'on' if adaptive else 'off'} | {result['seconds']:.2f} | "
                             f"{result['peak_rss_mb']:.0f} | {', '.join(result['windows'])} | {psnr} | "
                             f"{result['ldr_psnr']:.2f} |")
                print(lines[-1], flush=True)
                if scored:
                    key = f"{name} {'adaptive' if adaptive else 'full'}"
                    points.setdefault(key, ([], []))
                    points[key][0].append(np.log10(result["seconds"]))
                    points[key][1].append(result["psnr"])
    text = "\n".join(lines) + "\n"
    (arguments.out / "table.md").write_text(text)
    if points:
        write_png(arguments.out / "pareto.png", line_plot(points, "PSNR (dB) vs log10 seconds, per frame size",
                                                          log_y=False), overwrite=True)
    print(text)


if __name__ == "__main__":
    main()
