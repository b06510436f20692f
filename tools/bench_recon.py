"""Cost of each network preset on this machine: parameters, GFLOPs and forward latency at 512 x 512,
training step time (batch 4 of 128 x 128 crops, network only, fixed PSF), and the fp32 matmul peak.

GFLOPs count 2 x multiply-adds of every convolution (hdrcam.recon.flops). The paper preset runs with
random VGG-19 features (no weights here): its cost is the same. Latency is the median of --repeats runs
after one warm-up; `torch.get_num_threads()` threads.
Usage: python tools/bench_recon.py [--repeats 3] [--presets fast,lite,paper] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from timing import timed_seconds  # noqa: E402

from hdrcam.recon.flops import forward_gflops, parameter_count
from hdrcam.recon.losses import LossWeights, reconstruction_loss
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.presets import preset
from hdrcam.recon.vgg import load_vgg19


def matmul_peak_gflops(size: int = 2048, repeats: int = 5) -> float:
    a, b = torch.rand(size, size), torch.rand(size, size)
    return 2 * size ** 3 / timed_seconds(lambda: a @ b, repeats) / 1e9


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--presets", default="fast,lite,paper")
    parser.add_argument("--out", type=Path, default=None)
    arguments = parser.parse_args()
    peak = matmul_peak_gflops()
    lines = [f"Machine: {platform.processor() or platform.machine()}, {torch.get_num_threads()} threads, torch "
             f"{torch.__version__}; fp32 matmul peak {peak:.0f} GFLOP/s.", "",
             "| preset | params | GFLOPs @512^2 | forward @512^2 (s) | GFLOP/s | % of matmul peak | "
             "train step, 4 x 128^2 (s) |", "|---|---|---|---|---|---|---|"]
    for name in arguments.presets.split(","):
        chosen = preset(name)
        torch.manual_seed(0)
        vgg = load_vgg19(random_features=True) if chosen.vgg_features else None
        network = ReconstructionNet(chosen, vgg).eval()
        image = torch.rand(1, 3, 512, 512)
        gflops = forward_gflops(network, image)
        repeats = 1 if name == "paper" else arguments.repeats
        with torch.no_grad():
            forward = timed_seconds(lambda: network(image), repeats, statistics.median)
        network.train()
        optimizer = torch.optim.Adam([p for p in network.parameters() if p.requires_grad], lr=1e-4)
        batch, target = torch.rand(4, 3, 128, 128), torch.rand(4, 3, 128, 128) * 4

        def step():
            loss = reconstruction_loss(network(batch), target, LossWeights(), vgg)["total"]
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()

        train_step = timed_seconds(step, repeats, statistics.median)
        rate = gflops / forward
        lines.append(f"| {name} | {parameter_count(network) / 1e6:.2f} M | {gflops:.1f} | {forward:.2f} | "
                     f"{rate:.0f} | {100 * rate / peak:.0f} % | {train_step:.2f} |")
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    print(text)
    if arguments.out:
        arguments.out.write_text(text)


if __name__ == "__main__":
    main()
