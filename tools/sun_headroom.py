"""Where a test set's remaining gain lies: highlights at the protocol's 2^8 cap (a sun), per photograph.

For each test crop of ``hdrcam evaluate`` (the paper's protocol: 1.5 % of pixels above 1, clipped at 2^8) that
holds pixels at the cap, prints
- the LDR capture's linear PSNR (peak 2^8) and the share of its squared error in pixels at the cap;
- the gain (dB) of three oracles over the LDR capture, each changing only capped pixels: ``exact`` (the truth
  there), ``at-64`` (64 where the truth is capped: the right place, a quarter of the value) and ``deepest`` (a
  disc of the capped area at the pixel deepest inside its clipped blob, at 2^8: where a prior without streaks
  would put it), and how far (px) that disc's centre lies from the capped pixels' centroid;
- for each ``--checkpoint NAME=PATH``, the share of the capped pixels' light that its PSF puts on pixels the
  frame leaves unclipped, and that light's signal-to-noise ratio against the checkpoint profile's shot and read
  noise: sqrt(sum over unclipped pixels of (light / sigma)^2), sigma^2 = (s FW + RN^2) / FW^2 (s the frame's
  signal, white = 1; FW full well, RN read noise, electrons).

    python tools/sun_headroom.py runs/data/train --checkpoint rank1=hdrcam/checkpoints/table2/rank1.pt

A diagnostic: nothing in the product reads it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.ndimage as ndi
import torch

from hdrcam.data.saturation import HIGHLIGHT_PEAK
from hdrcam.data.scenes import SceneSource
from hdrcam.profiles import load_profile
from hdrcam.sensor import fft_convolve
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import OpticalCapture

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402

CROP_PX = 512
CAPPED = HIGHLIGHT_PEAK - 0.1  # a pixel whose brightest channel is here or above sits at the 2^8 cap
PEAK = HIGHLIGHT_PEAK


def psnr_db(estimate: np.ndarray, truth: np.ndarray) -> float:
    return float(10 * np.log10(PEAK ** 2 / max(float(((estimate - truth) ** 2).mean()), 1e-30)))


def oracles(truth: np.ndarray) -> str:
    """The LDR capture's PSNR, the capped share of its error and the three oracles' gains (module docstring)."""
    ldr = np.minimum(truth, 1.0)
    brightest = truth.max(axis=-1)
    capped = brightest >= CAPPED
    error = (truth - ldr) ** 2
    share = error[capped].sum() / error.sum()
    base = psnr_db(ldr, truth)
    exact = np.where(capped[..., None], truth, ldr)
    quarter = np.where(capped[..., None], np.maximum(ldr, 64.0), ldr)
    blobs, _ = ndi.label(brightest > 1.0)
    guess, offsets = np.zeros_like(capped), []
    rows, columns = np.mgrid[:truth.shape[0], :truth.shape[1]]
    for blob in np.unique(blobs[capped]):
        inside = blobs == blob
        depth = ndi.distance_transform_edt(inside)
        deep = np.unravel_index(int(np.argmax(depth)), depth.shape)
        centroid = np.argwhere(capped & inside).mean(axis=0)
        offsets.append(float(np.hypot(*(centroid - deep))))
        radius_sq = np.count_nonzero(capped & inside) / np.pi
        guess |= (rows - deep[0]) ** 2 + (columns - deep[1]) ** 2 <= radius_sq
    deepest = np.where(guess[..., None], PEAK, ldr)
    return (f"ldr {base:6.2f} dB, capped {np.count_nonzero(capped):3d} px {100 * share:3.0f} % of its error | "
            f"exact {psnr_db(exact, truth) - base:+5.2f} at-64 {psnr_db(quarter, truth) - base:+5.2f} "
            f"deepest {psnr_db(deepest, truth) - base:+5.2f} (off {', '.join(f'{o:.0f}' for o in offsets)} px)")


def visible_light(scene: np.ndarray, seed: int, name: str, model, capture: OpticalCapture, margin_px: int) -> str:
    """Share and SNR of the capped pixels' light on the frame's unclipped pixels, through ``model``'s PSF."""
    inset = margin_px - capture.margin_px
    local = scene[inset:scene.shape[0] - inset, inset:scene.shape[1] - inset]
    capped_only = np.where(local.max(axis=-1, keepdims=True) >= CAPPED, local, 0.0).astype(np.float32)
    to_torch = lambda image: torch.from_numpy(np.ascontiguousarray(image)).permute(2, 0, 1)[None]  # noqa: E731
    with torch.no_grad():
        frame, _ = capture(to_torch(local), torch.Generator().manual_seed(seed))
        light = fft_convolve(to_torch(capped_only), torch.from_numpy(np.asarray(model.psf, np.float32)))
    m = capture.margin_px
    frame, light = frame[0].numpy(), light[0, :, m:m + CROP_PX, m:m + CROP_PX].numpy()
    unclipped = frame < 1.0
    full_well, read_noise = capture.sensor.full_well_e, capture.sensor.read_noise_e
    sigma = np.sqrt(np.maximum(frame, 0.0) * full_well + read_noise ** 2) / full_well
    share = light[unclipped].sum() / light.sum()
    snr = np.sqrt(((light / sigma)[unclipped] ** 2).sum())
    return f"{name} {100 * share:5.2f} % snr {snr:5.0f}"


def checkpoint_option(text: str) -> tuple[str, Path]:
    """NAME=PATH; argparse reports anything else in one line."""
    name, separator, path = text.partition("=")
    if not (name and separator and path):
        raise argparse.ArgumentTypeError(f"expected NAME=PATH, got {text!r}")
    return name, Path(path)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path, help="a folder of HDR photographs (evaluate's --data)")
    parser.add_argument("--checkpoint", type=checkpoint_option, action="append", default=[], metavar="NAME=PATH")
    arguments = parser.parse_args()
    models = {name: load_model(path) for name, path in arguments.checkpoint}
    captures = {name: OpticalCapture(load_profile(model.profile), psf=model.psf) for name, model in models.items()}
    margin = max([capture.margin_px for capture in captures.values()], default=0)
    for name, scene, seed in SceneSource(arguments.data, lenient=True).test_scenes(CROP_PX, margin, 10 ** 6):
        truth = scene[margin:margin + CROP_PX, margin:margin + CROP_PX]
        if not (truth.max(axis=-1) >= CAPPED).any():
            continue
        shown = [visible_light(scene, seed, label, models[label], capture, margin)
                 for label, capture in captures.items()]
        print(f"{name[:36]:36s} {oracles(truth)}" + ("".join(f" | {item}" for item in shown)))
    return 0


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
