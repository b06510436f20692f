"""Windshield streak removal (paper Sec. 7): the splitting stage's streak-free image I_U, where streaks can be.

A worn windshield smears every light into a thin streak, like a 2-point star PSF; only light bright enough
to clip leaves a streak that matters. The network's I_U is therefore used only within the streak's reach
(the PSF radius) of a clipped pixel, blended in over ``FEATHER_PX``; everywhere else the frame is kept as it
is. On a CPU training budget the splitting net changes streak-free pixels too, and without the gate that
cost more than the streaks it removed (``tools/bench_destreak.py`` measures both).
"""

from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np
import torch

from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.tiling import CLIP_LEVEL, clipped_mask, reconstruct_frame, refuse_all_clipped

FEATHER_PX = 8


@dataclasses.dataclass
class DestreakReport:
    streak_zone_fraction: float  # of the frame's pixels that the network's output may change
    seconds: float


class _UnsaturatedOnly:
    """The splitting stage of a network, presented as a whole network whose output is I_U in [0, 1]."""

    def __init__(self, network: ReconstructionNet):
        self.network = network

    def to(self, device=None, dtype=None):
        self.network.to(device=device, dtype=dtype)
        return self

    def eval(self):
        self.network.eval()
        return self

    def __call__(self, ldr: torch.Tensor):
        output = self.network(ldr, highlights=False)
        output.hdr = output.unsaturated.clamp(0.0, 1.0)
        return output


def streak_zone(frame: np.ndarray, reach_px: int) -> np.ndarray:
    """H x W float32 weights in [0, 1]: 1 within ``reach_px`` of a clipped pixel, falling to 0 over FEATHER_PX."""
    clipped = clipped_mask(frame).astype(np.uint8)
    if not clipped.any():
        return np.zeros(clipped.shape, np.float32)
    distance = cv2.distanceTransform(1 - clipped, cv2.DIST_L2, 5)
    return np.clip((reach_px + FEATHER_PX - distance) / FEATHER_PX, 0.0, 1.0).astype(np.float32)


def destreak_frame(network: ReconstructionNet, frame: np.ndarray, *, psf_radius_px: int, gate: bool = True,
                   device: torch.device = torch.device("cpu")) -> tuple[np.ndarray, DestreakReport]:
    """H x W x 3 frame in [0, 1] -> the frame with the streaks of its clipped lights removed; clipped channels
    keep the frame's value (a lower bound of their light: the network's I_U took 28 % of a streaked frame's
    clipped values below the clip level, so a later reconstruct saw those lights as less clipped).

    ``gate`` False returns the network's I_U everywhere but on clipped channels (for measuring what the gate is
    worth). InputError for a frame clipped everywhere (hdrcam.recon.tiling.refuse_all_clipped).
    """
    refuse_all_clipped(frame)
    started = time.perf_counter()
    weight = streak_zone(frame, psf_radius_px) if gate else np.ones(frame.shape[:2], np.float32)
    if not weight.any():
        return frame.astype(np.float32, copy=True), DestreakReport(0.0, time.perf_counter() - started)
    clean, _ = reconstruct_frame(_UnsaturatedOnly(network), frame, psf_radius_px=psf_radius_px,
                                 adaptive=gate, device=device)
    blended = np.where(frame >= CLIP_LEVEL, frame, frame + weight[..., None] * (clean - frame))
    return blended.astype(np.float32), DestreakReport(float(weight.mean()), time.perf_counter() - started)
