"""A second opinion from the mirrored frame: keep only the highlights the network paints in both.

A frame is the scene convolved with the PSF (paper Eq. 6). When the PSF equals its own mirror image, the
mirrored frame is what the same camera would record of the mirrored scene, so the network's answer for it,
mirrored back, is a second estimate of equal standing. Light that the streaks show appears in both answers;
a blotch the network invents from texture (a window's mullions, a sky barely above white) need not. The agreed
estimate is the per-pixel, per-channel minimum of the two: where they disagree, the smaller is kept, which
moves the estimate toward the frame (the judge, :mod:`hdrcam.recon.consistency`, floors clipped channels at 1
afterwards). Measured on dev photographs and night scenes in tools/results/real-data/README.md ("Mirror
agreement").

Only mirrors the PSF respects are used: left-right first, else up-down, each when the relative L1 distance
between the PSF and its mirror image is at most MIRROR_TOLERANCE; a PSF symmetric under neither gets one pass.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

MIRROR_TOLERANCE = 0.05  # relative L1 between the PSF and its mirror image (shipped rank-1: 0.014 left-right)
_AXES = {"left-right": 1, "up-down": 0}  # mirror name -> image axis reversed (H x W x C images; (C, k, k) PSFs: +1)


def psf_mirror(psf: np.ndarray) -> str | None:
    """The first mirror ("left-right", then "up-down") under which the (C, k, k) PSF equals its own mirror
    image within MIRROR_TOLERANCE, or None."""
    psf = np.asarray(psf, np.float64)
    total = float(np.abs(psf).sum())
    for name, axis in _AXES.items():
        if total > 0 and float(np.abs(psf - np.flip(psf, axis=axis + 1)).sum()) <= MIRROR_TOLERANCE * total:
            return name
    return None


def mirrored(image: np.ndarray, mirror: str) -> np.ndarray:
    """An H x W (x C) image mirrored (a contiguous copy)."""
    return np.ascontiguousarray(np.flip(image, axis=_AXES[mirror]))


def mirrored_region(region, mirror: str, frame_shape: tuple[int, int]):
    """A :class:`hdrcam.recon.tiling.Region` of a frame of ``frame_shape`` (H, W), mirrored with the frame."""
    if mirror == "left-right":
        return dataclasses.replace(region, left=frame_shape[1] - region.left - region.width)
    return dataclasses.replace(region, top=frame_shape[0] - region.top - region.height)


def mirror_agreed(estimate: Callable[[np.ndarray, str | None], np.ndarray], frame: np.ndarray,
                  mirror: str | None) -> np.ndarray:
    """``estimate(frame, None)`` and ``estimate(mirrored frame, mirror)`` mirrored back -> their per-pixel,
    per-channel minimum (H x W x 3, relative radiance); just the first without a mirror. ``estimate`` is told
    which mirror its input went through (None: the frame itself), e.g. to mirror precomputed regions."""
    direct = estimate(frame, None)
    if mirror is None:
        return direct
    return np.minimum(direct, mirrored(estimate(mirrored(frame, mirror), mirror), mirror))
