"""Do no harm: an HDR estimate made consistent with the frame it came from (paper Eq. 1 and 6).

The frame is y = clip(P * H + eta): on an unclipped pixel it measured the scene convolved with the PSF.
An estimate proposes, for each cluster of clipped pixels (hdrcam.recon.tiling.clipped_clusters) and each
colour channel c, an excess E over the clip level on the pixels where channel c clipped. That excess is kept
only in the proportion the frame supports, a scale s in [0, 1] (s = 0: the captured frame itself there):

- Upper bound (never far above what the recorded streaks support). The scene under the streaks is
  non-negative and a clipped pixel is at least 1, so on every unclipped pixel the re-imaged excess may add at
  most what the frame recorded beyond the clipped pixels' own light:
  s (P * E)(x) <= y(x) + K_SIGMA sigma(y(x)) + TOLERANCE - (P * 1_C)(x),
  sigma from the camera's shot and read noise (relative units, 1 = full well).
- Evidence (fall back where it is weak). The streak amplitude a is fitted by least squares to the frame on the
  unclipped pixels within RING_PX of the cluster, y - P * 1_C = a P * E + b0 + b1 row + b2 column (a planar
  background), and shrunk by its significance z = a / std(a) (residuals taken as TEXTURE_CORRELATION
  correlated pixels each): a (1 - (Z_MIN / z)^2)+. Streaks the frame does not show clearly (bright smooth
  surroundings of a highlight barely above the clip level, a camera without a DOE whose lens keeps the light
  in the highlight) leave the frame as it was.

s = min(1, upper bound, evidence): the frame can only take a highlight down, never up, so an estimate is
never brighter than its own proposal. The streaks measure how much light a blob holds, not how it is spread
inside it, so last each pixel's excess is capped at SHAPE_CAP times its blob's mean excess (per channel,
blobs = 8-connected clipped pixels): a network's misplaced peak (values of 50-100 where the truth is 1.5 on
sky seen through leaves) costs far more linear PSNR than a flatter fill. Clipped channels are at least 1;
channels that did not clip keep the frame's value. Unclipped pixels are then the frame less the kept highlights' spill
(:mod:`hdrcam.recon.highlight_spill`), which the upper bound keeps at least -K_SIGMA sigma before clamping.

Measured (12 real validation photographs, tools/results/real-data/): see README, "Do no harm".
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import torch

from hdrcam.recon.tiling import CLIP_LEVEL, clipped_clusters
from hdrcam.sensor import fft_convolve

K_SIGMA = 3.0  # noise allowance of the upper bound, in standard deviations
TOLERANCE = 0.002  # relative frame units: ADC steps, PSF calibration error
RING_PX = 8  # the evidence fit uses unclipped pixels this close to the cluster
Z_MIN = 3.0  # a streak amplitude this many standard deviations above zero is kept at (1 - 1/z^2) of its value
TEXTURE_CORRELATION = 4.0  # neighbouring residuals of a planar background are correlated: variance x this
MIN_FIT_PIXELS = 8  # fewer unclipped pixels near a cluster: no evidence, the frame is kept
SHAPE_CAP = 4.0  # a pixel's excess is at most this multiple of its blob's mean excess


@dataclasses.dataclass(frozen=True)
class NoiseModel:
    """Shot + read noise of the frame, in electrons at the full well (relative value 1)."""

    full_well_e: float = 25000.0
    read_noise_e: float = 4.0

    def sigma(self, relative: np.ndarray) -> np.ndarray:
        """Standard deviation (relative units) of a pixel that recorded ``relative``."""
        return np.sqrt(np.clip(relative, 0.0, None) * self.full_well_e + self.read_noise_e ** 2) / self.full_well_e


@dataclasses.dataclass
class ConsistencyReport:
    clusters: int
    proposed_excess: float  # sum of the estimate's excess over 1 on clipped channels (relative radiance x pixels)
    kept_excess: float
    clipped_pixels: int
    fallen_back_pixels: int  # clipped pixels whose kept share is below a half in their brightest channel

    @property
    def fallback_fraction(self) -> float:
        """Share of the proposed highlight excess the frame did not support (0: all kept, 1: the frame)."""
        return 1.0 - self.kept_excess / self.proposed_excess if self.proposed_excess > 0 else 0.0

    def summary(self) -> str:
        if not self.clusters:
            return "consistency: no clipped pixel"
        return (f"consistency: {self.clusters} clusters, kept {100 * (1 - self.fallback_fraction):.0f} % of the "
                f"proposed highlight excess; {self.fallen_back_pixels} of {self.clipped_pixels} clipped pixels "
                f"fell back towards the frame")


def make_consistent(frame: np.ndarray, estimate: np.ndarray, psf: np.ndarray, *, noise: NoiseModel = NoiseModel()
                    ) -> tuple[np.ndarray, np.ndarray, ConsistencyReport]:
    """H x W x 3 frame in [0, 1], an H x W x 3 HDR estimate (relative radiance) and the (3, k, k) unit-sum PSF
    -> (the estimate on clipped pixels with each cluster's excess scaled as the frame supports, the frame
    elsewhere; H x W confidence in [0, 1]: the kept share on clipped pixels, 1 elsewhere; the report).

    Unclipped pixels are returned as the frame: subtract the highlights' spill afterwards."""
    clipped_channels = frame >= CLIP_LEVEL
    clipped = clipped_channels.any(axis=-1)
    floored = np.where(clipped_channels, np.maximum(estimate, 1.0), frame).astype(np.float32)
    confidence = np.ones(frame.shape[:2], np.float32)
    if not clipped.any():
        return floored, confidence, ConsistencyReport(0, 0.0, 0.0, 0, 0)
    kernel = torch.from_numpy(np.ascontiguousarray(psf, np.float32))
    output = floored.copy()
    proposed = kept = 0.0
    clusters = clipped_clusters(clipped, psf.shape[-1] // 2)
    for crop, own in clusters:
        mine = clipped_channels[crop] & own[..., None]
        excess = np.where(mine, floored[crop] - 1.0, 0.0).astype(np.float32)
        scales = _supported_scales(frame[crop], clipped_channels[crop], own, excess, kernel, noise)
        output[crop] = np.where(mine, 1.0 + scales * excess, output[crop])
        share = np.where(mine, scales, 1.0).min(axis=-1)
        confidence[crop] = np.where(own, np.minimum(confidence[crop], share), confidence[crop])
        proposed += float(excess.sum())
        kept += float((scales * excess).sum())
    output = _cap_shapes(output, clipped_channels, clipped)
    fallen_back = int((confidence[clipped] < 0.5).sum())
    return output, confidence, ConsistencyReport(len(clusters), proposed, kept, int(clipped.sum()), fallen_back)


def _cap_shapes(estimate: np.ndarray, clipped_channels: np.ndarray, clipped: np.ndarray) -> np.ndarray:
    """Each clipped channel's excess over 1 capped at SHAPE_CAP times its blob's mean excess in that channel."""
    blob_count, labels = cv2.connectedComponents(clipped.astype(np.uint8), connectivity=8)
    index = labels.ravel()
    capped = estimate.copy()
    for channel in range(3):
        mine = clipped_channels[..., channel]
        excess = np.where(mine, estimate[..., channel] - 1.0, 0.0)
        pixels = np.bincount(index, weights=mine.ravel().astype(np.float64), minlength=blob_count)
        mean = np.bincount(index, weights=excess.ravel(), minlength=blob_count) / np.maximum(pixels, 1.0)
        limit = (SHAPE_CAP * mean)[labels]
        capped[..., channel] = np.where(mine, 1.0 + np.minimum(excess, limit), estimate[..., channel])
    return capped.astype(np.float32)


def _convolve(image: np.ndarray, kernel: torch.Tensor) -> np.ndarray:
    planes = torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1), np.float32))
    return fft_convolve(planes, kernel).numpy().transpose(1, 2, 0)


def _supported_scales(frame: np.ndarray, clipped_channels: np.ndarray, own: np.ndarray, excess: np.ndarray,
                      kernel: torch.Tensor, noise: NoiseModel) -> np.ndarray:
    """One cluster's crop -> (3,) scales in [0, 1] of its excess per channel (module docstring)."""
    spill = _convolve(excess, kernel)  # s = 1
    floor_light = _convolve(clipped_channels.astype(np.float32), kernel)  # clipped pixels at exactly 1
    explained = frame - floor_light
    slack = explained + K_SIGMA * noise.sigma(frame) + TOLERANCE
    ring = cv2.dilate(own.astype(np.uint8), np.ones((2 * RING_PX + 1,) * 2, np.uint8)) > 0
    height, width = own.shape
    rows, columns = np.mgrid[0:height, 0:width].astype(np.float64)
    rows, columns = rows / max(height, 1), columns / max(width, 1)
    scales = np.zeros(3, np.float32)
    for channel in range(3):
        if not excess[..., channel].any():
            continue
        unclipped = ~clipped_channels[..., channel]
        reach = unclipped & (spill[..., channel] > 0)
        if not reach.any():
            continue  # nothing recorded the streaks: no evidence
        upper = float((np.clip(slack[..., channel][reach], 0.0, None) / spill[..., channel][reach]).min())
        near = reach & ring
        if near.sum() < MIN_FIT_PIXELS:
            continue
        design = np.stack([spill[..., channel][near], np.ones(int(near.sum())), rows[near], columns[near]], axis=1)
        observed = explained[..., channel][near].astype(np.float64)
        coefficients, *_ = np.linalg.lstsq(design, observed, rcond=None)
        residual = observed - design @ coefficients
        covariance = np.linalg.pinv(design.T @ design) * max(float(np.mean(residual ** 2)), 1e-12)
        amplitude = float(coefficients[0])
        deviation = float(np.sqrt(max(covariance[0, 0] * TEXTURE_CORRELATION, 1e-24)))
        z = amplitude / deviation
        supported = amplitude * max(0.0, 1.0 - (Z_MIN / z) ** 2) if z > Z_MIN else 0.0
        scales[channel] = min(1.0, upper, supported)
    return scales
