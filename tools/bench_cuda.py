"""The reconstruction network on a CUDA GPU: which precision, memory layout and tiling pay (issue 22, item 7).

Run on a lent GPU (tools/gpu/train.sh's device has torch + CUDA, numpy, scipy, OpenCV; nothing else is needed):

    PYTHONPATH=. python3 tools/bench_cuda.py --out $OUT/bench-cuda.md [--budget-s 150]

1. One 512 x 512 forward of the shipped ``fast`` network and of the ``paper`` preset (seeded random weights,
   random VGG-19 features: cost only): float32 NCHW (TF32 off: the reference), float32 with TF32 matmuls,
   float32 channels_last with cuDNN's autotuner, bfloat16 and float16 weights in channels_last, and (last,
   while a minute of --budget-s is left) torch.compile of the fastest half-precision variant, compile time
   listed. Median of 20 forwards after
   warm-up, CUDA-synchronised; PSNR (dB, peak 2^8, the paper's linear PSNR) of each output against the
   reference, on a procedural night scene scaled so 1.5 % of its pixels clip.
2. A 4000 x 6000 frame (the night scene tiled, no PSF: timing and precision only) through the shipped network:
   hdrcam.recon.tiling.reconstruct_frame as ``reconstruct --device cuda`` runs it today (windows of 512 px
   cores, 32 px halos) in float32 and bfloat16, the same with 2048 px cores, and one whole-frame forward in
   bfloat16 channels_last with the frame uploaded once (upload and download included). PSNR of each against
   the float32 tiled run. Stops starting new rows once --budget-s is spent; every row is written as it ends.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import build as network  # noqa: E402  the shipped `fast` network, or a preset with seeded weights

PEAK_RADIANCE = 2.0 ** 8


def night_frame(height: int, width: int) -> np.ndarray:
    """H x W x 3 float32 LDR frame in [0, 1]: a 1000 px procedural night scene at 1.5 % clipped, tiled."""
    from hdrcam.data.night_scene import night_scene
    from hdrcam.data.saturation import scale_to_clipped_fraction

    tile_px = min(1000, height, width)
    scene = np.clip(scale_to_clipped_fraction(night_scene(tile_px, tile_px, seed=1), 0.015), 0.0, 1.0)
    repeats = (-(-height // tile_px), -(-width // tile_px), 1)
    return np.ascontiguousarray(np.tile(scene, repeats)[:height, :width], np.float32)


def psnr_db(output: torch.Tensor | np.ndarray, reference: torch.Tensor | np.ndarray) -> float:
    difference = torch.as_tensor(output).float().cpu() - torch.as_tensor(reference).float().cpu()
    mse = float(torch.mean(difference ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(PEAK_RADIANCE ** 2 / mse)


def synchronize(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def median_ms(forward, device: torch.device, repeats: int) -> float:
    for _ in range(3):
        forward()
    synchronize(device)
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        forward()
        synchronize(device)
        times.append(time.perf_counter() - started)
    return 1e3 * statistics.median(times)


def set_backends(*, tf32: bool, autotune: bool) -> None:
    torch.backends.cuda.matmul.allow_tf32 = torch.backends.cudnn.allow_tf32 = tf32
    torch.backends.cudnn.benchmark = autotune


def forward_rows(name: str, write, deadline: float, device: torch.device, size_px: int, repeats: int):
    """Part 1's rows but torch.compile; returns what :func:`compile_row` needs (None when out of time)."""
    base = network(name).to(device)
    image = torch.from_numpy(night_frame(size_px, size_px)).permute(2, 0, 1)[None].contiguous().to(device)
    set_backends(tf32=False, autotune=False)
    with torch.no_grad():
        reference = base(image).hdr.float()
    variants = [("float32 NCHW (reference)", torch.float32, False, False, False),
                ("float32 NCHW, TF32", torch.float32, False, True, False),
                ("float32 channels_last, TF32, cuDNN autotune", torch.float32, True, True, True),
                ("bfloat16 channels_last, autotune", torch.bfloat16, True, True, True),
                ("float16 channels_last, autotune", torch.float16, True, True, True)]
    best = None
    for label, dtype, channels_last, tf32, autotune in variants:
        if time.perf_counter() > deadline:
            return None
        set_backends(tf32=tf32, autotune=autotune)
        layout = torch.channels_last if channels_last else torch.contiguous_format
        model = copy.deepcopy(base).to(dtype=dtype, memory_format=layout)
        x = image.to(dtype).contiguous(memory_format=layout)
        with torch.no_grad():
            milliseconds = median_ms(lambda: model(x), device, repeats)
            quality = psnr_db(model(x).hdr, reference)
        write(f"| {name} | {label} | {milliseconds:.2f} | {quality:.1f} | |")
        if dtype != torch.float32 and (best is None or milliseconds < best[0]):
            best = (milliseconds, label, model, x, reference)
    return (name,) + best[1:]


def compile_row(fastest, write, device: torch.device, repeats: int) -> None:
    """torch.compile of the fastest half-precision variant :func:`forward_rows` found."""
    name, label, model, x, reference = fastest
    set_backends(tf32=True, autotune=True)
    started = time.perf_counter()
    compiled = torch.compile(model)
    try:
        with torch.no_grad():
            compiled(x)
            synchronize(device)
            compile_s = time.perf_counter() - started
            milliseconds = median_ms(lambda: compiled(x), device, repeats)
            quality = psnr_db(compiled(x).hdr, reference)
    except Exception as error:  # Inductor's and Triton's own exception types: the row says which
        write(f"| {name} | torch.compile of {label} | failed | | {type(error).__name__}: "
              f"{(str(error).splitlines() or [''])[0][:80]} |")
        return
    write(f"| {name} | torch.compile of {label} | {milliseconds:.2f} | {quality:.1f} | compile {compile_s:.0f} s |")


def frame_rows(write, deadline: float, device: torch.device, height: int, width: int) -> None:
    from hdrcam.recon.tiling import reconstruct_frame

    set_backends(tf32=True, autotune=True)
    model = network("fast")
    frame = night_frame(height, width)
    radius_px = 32  # adaptive=False: every window runs, the PSF's radius plans nothing
    reference = None
    for label, dtype, core_px in [("reconstruct_frame, 512 px cores, float32 (today's --device cuda)",
                                   torch.float32, 512),
                                  ("reconstruct_frame, 512 px cores, bfloat16", torch.bfloat16, 512),
                                  ("reconstruct_frame, 2048 px cores, bfloat16", torch.bfloat16, 2048)]:
        if time.perf_counter() > deadline:
            return
        times = []
        for _ in range(2):
            started = time.perf_counter()
            output, report = reconstruct_frame(model, frame, psf_radius_px=radius_px, adaptive=False,
                                               core_px=core_px, device=device, dtype=dtype)
            synchronize(device)
            times.append(time.perf_counter() - started)
        reference = output if reference is None else reference
        write(f"| {height} x {width} | {label} | {1e3 * min(times):.0f} | {psnr_db(output, reference):.1f} | "
              f"{report.windows_run} windows, first run {1e3 * times[0]:.0f} ms |")
    if time.perf_counter() > deadline:
        return
    whole = copy.deepcopy(model).to(device=device, dtype=torch.bfloat16, memory_format=torch.channels_last)
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats()

    def once() -> np.ndarray:
        x = torch.from_numpy(frame).to(device).permute(2, 0, 1)[None].to(torch.bfloat16)
        with torch.no_grad():
            hdr = whole(x.contiguous(memory_format=torch.channels_last)).hdr
        return hdr[0].permute(1, 2, 0).float().cpu().numpy()

    try:
        once()
        times = []
        for _ in range(2):
            started = time.perf_counter()
            output = once()
            times.append(time.perf_counter() - started)
    except torch.cuda.OutOfMemoryError as error:
        write(f"| {height} x {width} | whole frame, bfloat16 channels_last | out of memory | | "
              f"{str(error).splitlines()[0][:80]} |")
        return
    peak = f"peak {torch.cuda.max_memory_allocated() / 2 ** 30:.1f} GiB on the GPU" if device.type == "cuda" else ""
    write(f"| {height} x {width} | whole frame, bfloat16 channels_last, one upload | {1e3 * min(times):.0f} | "
          f"{psnr_db(output, reference):.1f} | {peak} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--budget-s", type=float, default=150.0, help="no new row starts after this")
    parser.add_argument("--size", default="4000x6000", help="HEIGHTxWIDTH of part 2's frame")
    parser.add_argument("--forward-size", type=int, default=512, help="side of part 1's frame, px")
    parser.add_argument("--repeats", type=int, default=20, help="timed forwards per row of part 1")
    parser.add_argument("--device", default="cuda", help="cpu: a smoke run of this script (tiny sizes)")
    arguments = parser.parse_args()
    device = torch.device(arguments.device)
    if device.type == "cuda" and not torch.cuda.is_available():
        print("error: torch sees no CUDA device: run this on a GPU machine", file=sys.stderr)
        return 2
    deadline = time.perf_counter() + arguments.budget_s
    height, width = (int(side) for side in arguments.size.split("x"))
    name = torch.cuda.get_device_name(0) if device.type == "cuda" else "the CPU (a smoke run)"
    lines = [f"# The network on {name}", "",
             f"torch {torch.__version__}, CUDA {torch.version.cuda}, cuDNN {torch.backends.cudnn.version()}; "
             "made by `PYTHONPATH=. python3 tools/bench_cuda.py` (its docstring says what each row runs).", "",
             "| network / frame | variant | ms | PSNR vs reference (dB) | note |", "|---|---|---|---|---|"]

    def write(line: str) -> None:
        lines.append(line)
        print(line, flush=True)
        arguments.out.write_text("\n".join(lines) + "\n")

    arguments.out.parent.mkdir(parents=True, exist_ok=True)
    arguments.out.write_text("\n".join(lines) + "\n")
    fastest = [forward_rows("fast", write, deadline, device, arguments.forward_size, arguments.repeats)]
    frame_rows(write, deadline, device, height, width)
    fastest.append(forward_rows("paper", write, deadline, device, arguments.forward_size, arguments.repeats))
    for chosen in fastest:  # compiling takes tens of seconds: last, and only with a minute left
        if chosen is not None and time.perf_counter() < deadline - 60:
            compile_row(chosen, write, device, arguments.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
