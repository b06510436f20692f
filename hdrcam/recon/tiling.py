"""Reconstruct a whole frame in overlapping tiles, running the network only where the frame needs it.

Tiles: the frame is reflect-padded and cut into windows of ``core + 2 halo`` pixels at a stride of
``core``. Each window's output is weighted by a separable trapezoid that is 1 over its core and ramps
linearly to 0 across ``2 blend`` pixels centred on the core's edges; neighbouring ramps sum to one, so
tiles join without seams, and memory is bounded by one window plus the output accumulators whatever the
frame size. ``halo`` gives each core context from outside it (the splitting net sees 255 px).

Scene-adaptive compute ("model only what a scene requires"): streaks and highlights exist only within the
PSF's reach of a clipped pixel. With ``adaptive`` on, a window whose core, grown by the PSF radius, holds
no clipped pixel is passed through unchanged (I_hat = the frame: nothing is clipped, nothing is spread
into it that matters), and a frame with no clipped pixel at all skips the network entirely.
"""

from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np
import torch

from hdrcam.recon.network import ReconstructionNet

CLIP_LEVEL = 0.99  # a pixel whose brightest channel reaches this (relative to white) is clipped
DEFAULT_CORE_PX = 256
DEFAULT_HALO_PX = 64
MULTIPLE_PX = 16  # the U-Net pools four times


@dataclasses.dataclass
class TileReport:
    """What a reconstruction did: windows run and skipped, clipped pixels, seconds."""

    windows: int
    windows_run: int
    clipped_pixels: int
    seconds: float

    @property
    def windows_skipped(self) -> int:
        return self.windows - self.windows_run

    def summary(self) -> str:
        if self.windows_run == 0:
            return f"no clipped pixels: highlight recovery skipped ({self.windows} windows passed through)"
        return (f"{self.clipped_pixels} clipped pixels; network ran on {self.windows_run} of {self.windows} "
                f"windows, {self.windows_skipped} skipped")


def clipped_mask(ldr: np.ndarray, level: float = CLIP_LEVEL) -> np.ndarray:
    """H x W bool: the brightest channel reaches ``level``."""
    return np.max(ldr, axis=-1) >= level


def _ramp(length: int, halo: int, blend: int) -> np.ndarray:
    position = np.arange(length, dtype=np.float32) + 0.5
    rise = np.clip((position - (halo - blend)) / (2 * blend), 0.0, 1.0)
    return np.minimum(rise, rise[::-1])


def reconstruct_frame(network: ReconstructionNet, ldr: np.ndarray, *, psf_radius_px: int, adaptive: bool = True,
                      core_px: int = DEFAULT_CORE_PX, halo_px: int = DEFAULT_HALO_PX,
                      device: torch.device = torch.device("cpu"), dtype: torch.dtype = torch.float32,
                      progress=None) -> tuple[np.ndarray, TileReport]:
    """H x W x 3 LDR frame in [0, 1] -> H x W x 3 float32 HDR estimate and what was run."""
    started = time.perf_counter()
    if (core_px + 2 * halo_px) % MULTIPLE_PX:
        raise ValueError(f"tile core + 2 halo must be a multiple of {MULTIPLE_PX}")
    blend = max(1, min(halo_px, core_px // 2) // 2)
    height, width = ldr.shape[:2]
    rows, columns = -(-height // core_px), -(-width // core_px)
    pad_bottom, pad_right = rows * core_px - height + halo_px, columns * core_px - width + halo_px
    mode = cv2.BORDER_REFLECT_101 if min(height, width) > max(halo_px, pad_bottom, pad_right) else cv2.BORDER_REPLICATE
    padded = cv2.copyMakeBorder(np.ascontiguousarray(ldr, np.float32), halo_px, pad_bottom, halo_px, pad_right, mode)
    clipped = clipped_mask(ldr)
    if adaptive and not clipped.any():  # nothing to recover anywhere: the frame is its own HDR estimate
        windows = window_count(height, width, core_px)
        return ldr.astype(np.float32, copy=True), TileReport(windows, 0, 0, time.perf_counter() - started)
    near_clipped = cv2.dilate(clipped.astype(np.uint8), cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * psf_radius_px + 1, 2 * psf_radius_px + 1))) > 0 if adaptive else None
    window = core_px + 2 * halo_px
    weight = np.outer(_ramp(window, halo_px, blend), _ramp(window, halo_px, blend))[..., None]
    total = np.zeros((rows * core_px + 2 * halo_px, columns * core_px + 2 * halo_px, 3), np.float32)
    weights = np.zeros(total.shape[:2] + (1,), np.float32)
    run = 0
    network = network.to(device=device, dtype=dtype).eval()
    for row in range(rows):
        for column in range(columns):
            top, left = row * core_px, column * core_px
            patch = padded[top:top + window, left:left + window]
            core = (slice(top, min(top + core_px, height)), slice(left, min(left + core_px, width)))
            if adaptive and not near_clipped[core].any():
                output = patch  # nothing clipped within the PSF's reach of this core
            else:
                run += 1
                with torch.no_grad():
                    tensor = torch.from_numpy(patch).permute(2, 0, 1)[None].to(device=device, dtype=dtype)
                    output = network(tensor).hdr[0].permute(1, 2, 0).float().cpu().numpy()
            total[top:top + window, left:left + window] += output * weight
            weights[top:top + window, left:left + window] += weight
            if progress:
                progress.step()
    hdr = total[halo_px:halo_px + height, halo_px:halo_px + width] / weights[halo_px:halo_px + height,
                                                                             halo_px:halo_px + width]
    return hdr, TileReport(rows * columns, run, int(clipped.sum()), time.perf_counter() - started)


def window_count(height_px: int, width_px: int, core_px: int = DEFAULT_CORE_PX) -> int:
    return -(-height_px // core_px) * -(-width_px // core_px)
