"""Highlight brightness made consistent with the streaks the frame recorded (inference-time physics).

The network paints every clipped blob, but only the streaks tell how bright it was: the frame is the scene
convolved with the PSF (paper Eq. 6), so a blob's light also lands, through the PSF's tails, on pixels that
did not clip. Each connected clipped blob k gets, per channel, an excess over 1 of a_k phi_k: a mean
amplitude a_k (relative radiance) times a unit-mean shape phi_k. The amplitudes minimise

    || u (y - P * (b + sum_k a_k phi_k)) ||^2 + sum_k lambda_k (a_k - e_k)^2

where y is the frame, u = 1 on unclipped pixels at least GUARD_PX from a clipped one (clipped pixels say
nothing, and right beside a blob the network's streak-free image b is least reliable), P the PSF,
b = I_hat with its excess over 1 removed from the clipped pixels, and e_k the network's mean excess on the
blob. lambda_k = DAMPING R_k + FLOOR n_k, with R_k the data term's curvature along a_k and n_k the blob's
pixel count: the streaks move an amplitude most of the way (1 / (1 + DAMPING) of the least-squares step)
where they see it clearly, faint streaks move it less, and a PSF without tails (Dirac: R_k = 0) leaves the
network's amplitude as it is. FLOOR 1e-4 against 1e-6 and 1e-8 (shape cap 2, no flat share): rank-1 32.58
against 32.10 and 32.07 dB, Dirac 33.53 / 33.53 / 33.55, demo 51.71 / 52.26 / 52.26 (set-up below).
Damped Jacobi steps solve it (hdrcam.recon.blob_amplitudes); a_k >= 0, outputs clamped to 2^8.

The shape is the network's, shrunk towards flat: phi_k = SHAPE_FLAT_WEIGHT f_k + (1 - SHAPE_FLAT_WEIGHT) c_k,
with c_k the network's excess capped at SHAPE_CAP times its blob mean and f_k uniform over the pixels the
network paints (more than SUPPORT_FRACTION of its blob mean), both normalised to mean 1; a blob the network
leaves almost unpainted is filled flat. The network's blob shapes are its least reliable output (sharp peaks
where the truth is smooth), and linear PSNR punishes a misplaced peak far more than a flat fill; the flat
share stays off the pixels the network judged to be the PSF's halo around a blob. Chosen by measurement
(tools/results/streak-fit.md: 8 procedural test scenes with the 2000-step ablation networks, and the demo
frame; linear / PU21 PSNR in dB for the network alone, the capped shape alone, this shape): rank-1
31.74/30.14, 32.58/29.41, 32.53/29.27; Dirac 33.11/34.36, 33.53/34.45, 34.43/34.56; dual-peak
33.27/34.67, 33.97/34.82, 34.79/34.80; demo 44.91/30.87, 51.71/31.05, 52.66/31.07 (the captured frame:
52.37/32.50).

Only what the frame needs is modelled: blobs whose PSF footprints overlap form a cluster, and each cluster
is solved in its own crop (the cluster grown by the PSF radius), so memory and time follow the highlights,
not the frame size.
"""

from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np
import torch

from hdrcam.recon.blob_amplitudes import blob_sums, fit_blob_amplitudes, hessian_row_sums
from hdrcam.recon.stages import HIGHLIGHT_PEAK
from hdrcam.recon.tiling import clipped_clusters, within_px
from hdrcam.sensor import fft_convolve

DEFAULT_ITERATIONS = 10
DEFAULT_DAMPING = 0.1  # relative to the data term's curvature
FLOOR = 1e-4  # per blob pixel, (relative frame value / relative radiance)^2: keeps tail-less PSFs at the guess
GUARD_PX = 1  # unclipped pixels this close to a clipped one are left out of the fit (see the module docstring)
SHAPE_CAP = 2.0  # the network's shape is capped at this multiple of its blob mean
SHAPE_FLAT_WEIGHT = 0.5
PAINTED_MIN = 0.05  # a blob whose mean painted excess is below this (relative radiance) gets a flat shape
SUPPORT_FRACTION = 0.05  # of its blob mean: where the network paints less, the flat share puts nothing


@dataclasses.dataclass
class RefinementReport:
    blobs: int
    clusters: int
    median_scale: float  # of a_k / e_k over blobs and channels the network painted (1 = its amplitudes kept)
    seconds: float

    def summary(self) -> str:
        if not self.blobs:
            return "streak fit: no clipped blob"
        return (f"streak fit: {self.blobs} clipped blobs in {self.clusters} clusters, median amplitude scale "
                f"{self.median_scale:.2f}")


def refine_highlight_amplitudes(ldr: np.ndarray, hdr: np.ndarray, psf: np.ndarray, clipped: np.ndarray, *,
                                iterations: int = DEFAULT_ITERATIONS, damping: float = DEFAULT_DAMPING,
                                floor: float = FLOOR) -> tuple[np.ndarray, RefinementReport]:
    """H x W x 3 frame and its HDR estimate (relative radiance), the (3, k, k) unit-sum PSF the frame was taken
    through and the H x W clipped mask -> the HDR estimate with each clipped blob's excess refitted."""
    started = time.perf_counter()
    radius = psf.shape[-1] // 2
    refined = np.array(hdr, np.float32, copy=True)
    blob_count, _ = cv2.connectedComponents(clipped.astype(np.uint8), connectivity=8)
    if blob_count <= 1:
        return refined, RefinementReport(0, 0, 1.0, time.perf_counter() - started)
    clusters = clipped_clusters(clipped, radius)
    kernel = torch.from_numpy(np.ascontiguousarray(psf, np.float32))
    scales = []
    for crop, own in clusters:
        patch, patch_scales = _refine_crop(ldr[crop], hdr[crop], clipped[crop], own, kernel, iterations, damping,
                                           floor)
        refined[crop] = np.where(own[..., None], patch, refined[crop])
        scales.append(patch_scales)
    all_scales = np.concatenate(scales)
    median = float(np.median(all_scales)) if all_scales.size else 1.0
    return refined, RefinementReport(blob_count - 1, len(clusters), median, time.perf_counter() - started)


def _refine_crop(ldr: np.ndarray, hdr: np.ndarray, clipped: np.ndarray, own: np.ndarray, kernel: torch.Tensor,
                 iterations: int, damping: float, floor: float) -> tuple[np.ndarray, np.ndarray]:
    """One cluster's crop (``own``: its clipped pixels; ``clipped``: all in the crop, which say nothing) ->
    (refined crop, a_k / e_k of the blobs and channels the network painted)."""
    blob_count, labels = cv2.connectedComponents(own.astype(np.uint8), connectivity=8)
    frame = torch.from_numpy(np.ascontiguousarray(ldr.transpose(2, 0, 1), np.float32))
    estimate = torch.from_numpy(np.ascontiguousarray(hdr.transpose(2, 0, 1), np.float32))
    inside = torch.from_numpy(own)
    unclipped = torch.from_numpy(~within_px(clipped, GUARD_PX)).to(torch.float32)
    index = torch.from_numpy(labels.astype(np.int64)).reshape(-1)
    excess = (estimate - 1.0).clamp(min=0.0) * inside
    base = estimate - excess
    pixels = torch.zeros(blob_count).index_add_(0, index, torch.ones(index.numel()))
    painted = blob_sums(excess, index, blob_count) / pixels.clamp(min=1.0)  # e_k, (3, blobs)
    painted[:, 0] = 0.0  # label 0: the unclipped background keeps its values
    shape = _blob_shape(excess, painted, inside, index, blob_count, pixels)
    row_sums = hessian_row_sums(unclipped, shape, index, blob_count, kernel)
    amplitude = fit_blob_amplitudes(frame - fft_convolve(base, kernel), unclipped, shape, index, blob_count, kernel,
                                    iterations, prior_weight=damping * row_sums + floor * pixels,
                                    prior_mean=painted, row_sums=row_sums)
    refined = (base + amplitude[:, index].reshape(shape.shape) * shape).clamp(max=HIGHLIGHT_PEAK)
    seen = painted[:, 1:] > PAINTED_MIN
    return refined.numpy().transpose(1, 2, 0), (amplitude[:, 1:][seen] / painted[:, 1:][seen]).numpy()


def _blob_shape(excess: torch.Tensor, painted: torch.Tensor, inside: torch.Tensor, index: torch.Tensor,
                blob_count: int, pixels: torch.Tensor) -> torch.Tensor:
    """(3, H, W) unit-mean shape of each blob: the network's, capped and shrunk towards flat (module docstring)."""
    per_pixel_painted = painted[:, index].reshape(excess.shape)
    unpainted = per_pixel_painted <= PAINTED_MIN
    support = (inside & ((excess > SUPPORT_FRACTION * per_pixel_painted) | unpainted)).to(torch.float32)
    flat = support / _blob_mean(support, index, blob_count, pixels).clamp(min=1e-12)
    capped = torch.minimum(excess / per_pixel_painted.clamp(min=1e-12), torch.tensor(SHAPE_CAP)) * inside
    network = capped / _blob_mean(capped, index, blob_count, pixels).clamp(min=1e-12)
    return SHAPE_FLAT_WEIGHT * flat + (1.0 - SHAPE_FLAT_WEIGHT) * torch.where(unpainted, flat, network)


def _blob_mean(values: torch.Tensor, index: torch.Tensor, blob_count: int, pixels: torch.Tensor) -> torch.Tensor:
    """(3, H, W) -> (3, H, W): each pixel's blob mean of ``values``."""
    return (blob_sums(values, index, blob_count) / pixels.clamp(min=1.0))[:, index].reshape(values.shape)
