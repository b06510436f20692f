"""Find the images of point sources in a merged Bayer frame and cut a window around each.

Units: the merged rate (relative radiance, full wells per second at ISO 100), pixel positions with pixel
centres at integers (row y, column x).
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from hdrcam.io.demosaic import cfa_masks

DETECTION_FRACTION = 0.05  # a source's peak must reach this fraction of the brightest source's peak
ANNULUS_WIDTH_PX = 8
BACKGROUND_BLOCK_PX = 32  # side of the squares whose medians give the background under the sources


@dataclasses.dataclass
class SourceWindow:
    """Bayer samples around one source: rows ``top ..``, columns ``left ..`` of the frame."""

    top: int
    left: int
    rate: np.ndarray  # W x W, background-subtracted
    weight: np.ndarray  # W x W inverse variance; 0 where a sample is not to be trusted
    channel: np.ndarray  # W x W ints 0/1/2 (R, G, B) from the CFA
    background: np.ndarray  # 3, per channel, subtracted from ``rate``
    noise: np.ndarray  # 3, per channel standard deviation in the annulus
    y_px: float  # first guess of the source's position in the frame
    x_px: float


def channel_map(cfa_pattern: str, height_px: int, width_px: int) -> np.ndarray:
    """H x W ints: which of R (0), G (1), B (2) each Bayer sample measures."""
    return np.argmax(cfa_masks((height_px, width_px), cfa_pattern), axis=0).astype(np.int8)


def smooth_background(image: np.ndarray, block_px: int = BACKGROUND_BLOCK_PX) -> np.ndarray:
    """A smooth estimate of ``image``'s background: the median of each block_px square, interpolated linearly
    over the frame (point sources light too few of a block's samples to move its median)."""
    height, width = image.shape
    rows, columns = max(1, height // block_px), max(1, width // block_px)
    block_y, block_x = height // rows, width // columns
    blocks = image[:rows * block_y, :columns * block_x].reshape(rows, block_y, columns, block_x)
    medians = np.median(blocks.transpose(0, 2, 1, 3).reshape(rows, columns, -1), axis=-1).astype(np.float32)
    return cv2.resize(medians, (width, height), interpolation=cv2.INTER_LINEAR)


def detect_sources(rate: np.ndarray, usable: np.ndarray, min_separation_px: int) -> list[tuple[int, int]]:
    """(row, column) of local maxima of the 2 x 2-summed rate, at least ``min_separation_px`` apart, standing
    above the smooth background (:func:`smooth_background`) by DETECTION_FRACTION of the brightest's excess;
    brightest first. Measured from zero instead, a lit room's light (0.7 full wells per reference exposure) was
    itself above the threshold, its noise peaks taken for pinholes 32 px apart and every source refused as
    crowded; at 0.4, 36 of 48 sources were left out and the PSF was 46 / 15 / 25 % off in L1."""
    summed = cv2.blur(np.where(usable, rate, 0.0).astype(np.float32), (2, 2), borderType=cv2.BORDER_CONSTANT) * 4
    size = max(3, min_separation_px | 1)
    local_max = summed >= cv2.dilate(summed, np.ones((size, size), np.uint8))
    excess = summed - smooth_background(summed)
    peak = float(excess.max())
    if not peak > 0:
        return []
    rows, columns = np.nonzero(local_max & (excess >= DETECTION_FRACTION * peak))
    order = np.argsort(-excess[rows, columns])
    return [(int(rows[i]), int(columns[i])) for i in order]


def cut_window(rate: np.ndarray, weight: np.ndarray, channels: np.ndarray, row: int, column: int,
               half_px: int) -> SourceWindow | None:
    """A (2 half + 1)^2 window of samples centred on (row, column), with the background subtracted: per channel,
    a plane fitted to an annulus just outside it (:func:`_background_plane`; its value at the centre is the
    window's ``background``); None when window and annulus do not fit in the frame."""
    outer = half_px + ANNULUS_WIDTH_PX
    height, width = rate.shape
    if row - outer < 0 or column - outer < 0 or row + outer >= height or column + outer >= width:
        return None
    rows, columns = slice(row - outer, row + outer + 1), slice(column - outer, column + outer + 1)
    y, x = np.mgrid[-outer:outer + 1, -outer:outer + 1]
    ring = (np.maximum(np.abs(y), np.abs(x)) > half_px) & (weight[rows, columns] > 0)
    inner = slice(ANNULUS_WIDTH_PX, ANNULUS_WIDTH_PX + 2 * half_px + 1)
    window_channels = channels[rows, columns][inner, inner]
    window_rate = rate[rows, columns][inner, inner].astype(np.float64)
    background, noise = np.zeros(3), np.zeros(3)
    for c in range(3):
        in_ring = ring & (channels[rows, columns] == c)
        if in_ring.any():
            plane, noise[c] = _background_plane(y[in_ring], x[in_ring], rate[rows, columns][in_ring])
            background[c] = plane[0]
            here = window_channels == c
            window_rate[here] -= plane @ np.stack([np.ones(int(here.sum())), y[inner, inner][here],
                                                   x[inner, inner][here]])
    window_weight = weight[rows, columns][inner, inner]
    green = (window_channels == 1) & (window_weight > 0)
    yy, xx = y[inner, inner], x[inner, inner]
    core = green & (np.hypot(yy, xx) <= 3)
    mass = np.clip(window_rate, 0, None) * core
    total = float(mass.sum())
    y_guess = row + (float((mass * yy).sum()) / total if total > 0 else 0.0)
    x_guess = column + (float((mass * xx).sum()) / total if total > 0 else 0.0)
    return SourceWindow(row - half_px, column - half_px, window_rate.astype(np.float64),
                        window_weight.astype(np.float64), window_channels, background, noise, y_guess, x_guess)


BACKGROUND_CLIP_SIGMAS = 3.0  # annulus samples further from the first plane are left out of the second


def _background_plane(y: np.ndarray, x: np.ndarray, samples: np.ndarray) -> tuple[np.ndarray, float]:
    """(a, b, c) of the plane a + b y + c x through an annulus's samples (y, x from the window's centre) and
    their noise (1.4826 median absolute deviation from it). A median level alone left a sloping background
    (ambient light across the bench) inside every window, where it moved the fitted centroids and put the PSF
    10-14 % (L1) off for a slope of 0.3 full wells across the frame; fitted twice, the second time without
    samples BACKGROUND_CLIP_SIGMAS from the first fit (a neighbour's streak, a hot pixel)."""
    design = np.stack([np.ones_like(y, dtype=np.float64), y, x], axis=1).astype(np.float64)
    samples = samples.astype(np.float64)
    keep = np.ones(samples.size, bool)
    plane, noise = np.array([float(np.median(samples)), 0.0, 0.0]), 0.0
    for _ in range(2):
        if keep.sum() >= 3:
            plane = np.linalg.lstsq(design[keep], samples[keep], rcond=None)[0]
        residual = samples - design @ plane
        noise = float(1.4826 * np.median(np.abs(residual - np.median(residual))))
        keep = np.abs(residual) <= BACKGROUND_CLIP_SIGMAS * max(noise, 1e-30)
    return plane, noise
