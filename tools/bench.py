"""The reconstruction network on this machine: its roofline, and speed against accuracy per preset, precision
and size.

1. Roofline of the default network (the shipped ``fast`` checkpoint) at 512^2, all measured in this one run:
   the fp32 matmul peak (2048^2 matmul, best of 5), the copy bandwidth (torch copy of 256 MiB, best of 5,
   bytes read + written), the forward's FLOPs (2 x multiply-adds of every convolution, hdrcam.recon.flops) and
   its memory traffic (every module's inputs, outputs and parameters read or written once: a lower bound).
   Bound = max(FLOPs / peak, traffic / bandwidth); the forward is timed as the product runs it
   (hdrcam.recon.cpu_forward: OpenVINO, compiled once before timing; its build time is listed) and as PyTorch's
   eager forward in NCHW and channels_last, on --threads threads (default: the cores; peak and bandwidth on
   the same threads), each row with the 1-minute load average at its end.
2. Speed-accuracy table: each preset x precision x size in a fresh process (peak RSS of that process minus
   its RSS before the first forward, Linux's resettable peak); time = median of --repeats forwards after a warm-up (1 for paper);
   float32 runs the product's forward (hdrcam.recon.cpu_forward), other precisions PyTorch's;
   PSNR (dB, peak 2^8 as the paper's linear PSNR) of the output against PyTorch's fp32 forward, on a
   procedural night scene captured at 1.5 % clipped pixels. ``fast`` is the shipped checkpoint; ``lite`` and
   ``paper`` have seeded random weights (paper with random VGG-19 features). bf16 and fp16 run only at 128^2:
   on this CPU they are many times slower than fp32 (REFERENCE.md sec. 7).
On a machine shared with other jobs, OpenMP threads that outnumber the free cores wait on each other (one
forward of ``fast`` at 128^2 took 2.5 s on 2 threads and 0.21 s on 1 with 4 other processes running):
the output records the load average; measure with --threads 1 there.
Each run is put, dated and with its commit, above the earlier runs in --out.
Usage: python tools/bench.py [--repeats 3] [--threads N] [--out tools/results/bench-cpu.md]
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from timing import timed_seconds  # noqa: E402

CONFIGS = [("fast", "float32", 256), ("fast", "float32", 512), ("fast", "float32", 1024),
           ("lite", "float32", 256), ("lite", "float32", 512), ("paper", "float32", 256),
           ("paper", "float32", 512), ("fast", "bfloat16", 128), ("fast", "float16", 128)]
PEAK_RADIANCE = 2.0 ** 8


def cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def matmul_peak_flops(size: int = 2048) -> float:
    a, b = torch.rand(size, size), torch.rand(size, size)
    return 2 * size ** 3 / timed_seconds(lambda: a @ b, 5)


def copy_bandwidth_bytes_per_s(mebibytes: int = 256) -> float:
    source = torch.rand(mebibytes * 2 ** 20 // 4)
    target = torch.empty_like(source)
    return 2 * source.numel() * 4 / timed_seconds(lambda: target.copy_(source), 5)


def traffic_bytes(network: torch.nn.Module, image: torch.Tensor) -> float:
    """Bytes every leaf module reads (inputs, parameters) and writes (outputs) once in a forward pass."""
    total = [0]

    def tensors(value):
        if isinstance(value, torch.Tensor):
            return [value]
        if isinstance(value, (tuple, list)):
            return [t for item in value for t in tensors(item)]
        return []

    def count(module, inputs, output):
        total[0] += sum(t.numel() * t.element_size() for t in tensors(inputs) + tensors(output))
        total[0] += sum(p.numel() * p.element_size() for p in module.parameters(recurse=False))

    leaves = [m for m in network.modules() if not list(m.children())]
    handles = [m.register_forward_hook(count) for m in leaves]
    try:
        with torch.no_grad():
            network(image)
    finally:
        for handle in handles:
            handle.remove()
    return float(total[0])


def build(name: str) -> torch.nn.Module:
    from hdrcam.recon.network import ReconstructionNet
    from hdrcam.recon.presets import preset
    from hdrcam.recon.vgg import load_vgg19
    from hdrcam.train.checkpoint import load_model

    if name == "fast":
        return load_model().network.eval()
    torch.manual_seed(0)
    chosen = preset(name)
    return ReconstructionNet(chosen, load_vgg19(random_features=True) if chosen.vgg_features else None).eval()


def test_frame(size_px: int) -> torch.Tensor:
    """A procedural night scene scaled so 1.5 % of its pixels clip, clipped to [0, 1]: (1, 3, S, S)."""
    from hdrcam.data.night_scene import night_scene
    from hdrcam.data.saturation import scale_to_clipped_fraction

    scene = scale_to_clipped_fraction(night_scene(size_px, size_px, seed=1), 0.015)
    return torch.from_numpy(np.clip(scene, 0.0, 1.0).astype(np.float32)).permute(2, 0, 1)[None].contiguous()


def _status_mb(field: str) -> float:
    """VmRSS or VmHWM (peak RSS) of this process in MB, from /proc/self/status."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no {field} in /proc/self/status")


def worker(name: str, precision: str, size_px: int, repeats: int, threads: int) -> dict:
    """One configuration in this (fresh) process."""
    from hdrcam.recon.cpu_forward import hdr_forward

    torch.set_num_threads(threads)
    network, frame = build(name), test_frame(size_px)
    dtype = getattr(torch, precision)
    reference_network = copy.deepcopy(network) if dtype != torch.float32 else network
    network, image = network.to(dtype), frame.to(dtype)
    forward = hdr_forward(network, torch.device("cpu"), dtype)
    Path("/proc/self/clear_refs").write_text("5")  # resets the peak RSS to the current RSS (Linux)
    before = _status_mb("VmRSS")
    times = []
    with torch.no_grad():
        for _ in range(1 + (1 if name == "paper" or dtype != torch.float32 else repeats)):
            started = time.perf_counter()
            output = forward(image).float()
            times.append(time.perf_counter() - started)
        peak_mb = _status_mb("VmHWM") - before
        reference = reference_network(frame).hdr
    error = float(torch.mean((output - reference) ** 2))
    psnr = float("inf") if error == 0 else 10 * np.log10(PEAK_RADIANCE ** 2 / error)
    return {"seconds": statistics.median(times[1:]), "memory_mb": peak_mb, "psnr_db": psnr}


def roofline(repeats: int, threads: int) -> list[str]:
    from hdrcam.recon.cpu_forward import hdr_forward
    from hdrcam.recon.flops import forward_gflops

    torch.set_num_threads(threads)
    peak, bandwidth = matmul_peak_flops(), copy_bandwidth_bytes_per_s()
    network, image = build("fast"), test_frame(512)
    flops = forward_gflops(network, image) * 1e9
    traffic = traffic_bytes(network, image)
    bound = max(flops / peak, traffic / bandwidth)
    started = time.perf_counter()
    product = hdr_forward(network, torch.device("cpu"), torch.float32)
    build_seconds = time.perf_counter() - started
    channels_last = copy.deepcopy(network).to(memory_format=torch.channels_last)
    paths = [("OpenVINO (the product's, hdrcam.recon.cpu_forward)", product, image),
             ("PyTorch eager, NCHW", lambda x: network(x).hdr, image),
             ("PyTorch eager, channels_last", lambda x: channels_last(x).hdr,
              image.contiguous(memory_format=torch.channels_last))]
    with torch.no_grad():
        reference = network(image).hdr
    lines = [f"Machine: {platform.processor() or platform.machine()}, {cores()} cores, torch {torch.__version__} "
             f"({torch.get_num_threads()} threads); fp32 matmul peak {peak / 1e9:.0f} GFLOP/s, copy bandwidth "
             f"{bandwidth / 1e9:.1f} GB/s (measured in this run).", "",
             f"Default network (`fast`, the shipped checkpoint) at 512^2: {flops / 1e9:.1f} GFLOP -> "
             f"{flops / peak:.3f} s at the matmul peak; traffic >= {traffic / 1e9:.2f} GB -> "
             f"{traffic / bandwidth:.3f} s at the copy bandwidth; roofline bound {bound:.3f} s. The product's "
             f"OpenVINO forward took {build_seconds:.2f} s to build (ONNX export, compilation, probe check; once "
             "per process and set of weights).", "",
             "| forward | @512^2 (s) | x roofline bound | GFLOP/s | vs PyTorch NCHW: PSNR (dB), max abs diff "
             "| load (1 min) |", "|---|---|---|---|---|---|"]
    for label, forward, x in paths:
        with torch.no_grad():
            times = [timed_seconds(lambda: forward(x), 1) for _ in range(repeats)]
            error = forward(x) - reference
        seconds, mse = statistics.median(times), float(torch.mean(error ** 2))
        psnr = "identical" if mse == 0 else f"{10 * np.log10(PEAK_RADIANCE ** 2 / mse):.1f}"
        lines.append(f"| {label} | {seconds:.3f} | {seconds / bound:.2f} | {flops / seconds / 1e9:.0f} | "
                     f"{psnr}, {float(error.abs().max()):.1e} | {os.getloadavg()[0]:.1f} |")
        print(lines[-1], flush=True)
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=cores(), help="torch threads (default: the cores)")
    parser.add_argument("--out", type=Path, default=Path("tools/results/bench-cpu.md"))
    parser.add_argument("--worker", nargs=3, metavar=("PRESET", "PRECISION", "SIZE"), help=argparse.SUPPRESS)
    arguments = parser.parse_args()
    if arguments.worker:
        name, precision, size = arguments.worker
        print(json.dumps(worker(name, precision, int(size), arguments.repeats, arguments.threads)))
        return
    load_before = os.getloadavg()[0]
    lines = roofline(arguments.repeats, arguments.threads)
    lines += ["", "| preset | precision | size | forward (s) | peak memory (MB) | PSNR vs PyTorch fp32 (dB) | "
                  "load (1 min) |", "|---|---|---|---|---|---|---|"]
    for name, precision, size in CONFIGS:
        done = subprocess.run([sys.executable, __file__, "--repeats", str(arguments.repeats), "--threads",
                               str(arguments.threads), "--worker", name, precision, str(size)],
                              capture_output=True, text=True, check=True)
        result = json.loads(done.stdout.strip().splitlines()[-1])
        psnr = "identical" if result["psnr_db"] == float("inf") else f"{result['psnr_db']:.1f}"
        lines.append(f"| {name} | {precision} | {size}^2 | {result['seconds']:.3f} | {result['memory_mb']:.0f} | "
                     f"{psnr} | {os.getloadavg()[0]:.1f} |")
        print(lines[-1], flush=True)
    lines += ["", f"Load average (1 min) {load_before:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, on "
                  f"{cores()} cores."]
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=Path(__file__).parent).stdout.strip() or "unknown"
    text = "\n".join([f"## {time.strftime('%Y-%m-%d %H:%M')} (commit {commit})", "",
                       f"`python tools/bench.py --repeats {arguments.repeats} --threads {arguments.threads}`", "",
                       *lines]) + "\n"
    print(text)
    arguments.out.parent.mkdir(parents=True, exist_ok=True)
    earlier = arguments.out.read_text() if arguments.out.exists() else ""
    arguments.out.write_text(text + ("\n" + earlier if earlier else ""))  # newest first, earlier runs kept


if __name__ == "__main__":
    main()
