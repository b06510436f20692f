"""The encoding streaks' own clipping: the paper's known failure case (Sec. 6, limitations).

The network recovers a highlight from its faint streaks; when a source is so bright that the streaks
clip too, that information is lost. From a frame and its PSF:

1. clipped pixels; the "cores" are what survives a 5 x 5 morphological opening (streaks are thin lines;
   a source bright enough to clip its streaks clips a blob at least the size of the PSF's centre);
2. the streak support: PSF pixels outside its centre box (radius ``core_radius_px``) above 1e-3 of the
   brightest streak pixel; the footprint where the cores' streaks land is the cores dilated by it;
3. clipped streaks: clipped pixels in that footprint, away from the cores;
4. a lower bound on the source radiance: a clipped streak pixel at distance d from its core has
   L p(d) >= 1, with p(d) the brightest streak value at radius d, so L >= 1 / p(d). Keeping every streak
   below clipping needs the exposure lowered by L s_max >= max(1 / p(d)) s_max, s_max the brightest
   streak value: the suggested change is that many EV, rounded up (a lower bound).
The mask marks the pixels within the PSF's radius of a clipped streak: there the reconstruction is
unreliable.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from hdrcam.recon.tiling import clipped_mask

STREAK_SUPPORT_FRACTION = 1e-3


@dataclasses.dataclass
class StreakCheck:
    mask: np.ndarray  # H x W bool: unreliable pixels
    clipped_streak_pixels: int
    suggested_exposure_change_ev: float  # negative: shorten the exposure by this much; 0 when all is well

    def warning(self) -> str | None:
        if not self.clipped_streak_pixels:
            return None
        return (f"{self.clipped_streak_pixels} pixels of the DOE's streaks are clipped, so the brightest highlights "
                f"cannot be recovered ({int(self.mask.sum())} pixels marked in the mask); shoot again with at least "
                f"{-self.suggested_exposure_change_ev:.0f} EV less exposure")


def _streak_kernel(psf: np.ndarray, core_radius_px: int) -> np.ndarray:
    """Brightest channel of the PSF (3, S, S) with its centre box zeroed."""
    kernel = np.max(psf, axis=0).astype(np.float64)
    centre = kernel.shape[0] // 2
    kernel[centre - core_radius_px:centre + core_radius_px + 1, centre - core_radius_px:centre + core_radius_px + 1] = 0
    return kernel


def check_streaks(ldr: np.ndarray, psf: np.ndarray, core_radius_px: int) -> StreakCheck:
    """Find clipped streaks in an H x W x 3 frame (relative, 1.0 = white) taken through ``psf``."""
    clipped = clipped_mask(ldr).astype(np.uint8)
    kernel = _streak_kernel(psf, core_radius_px)
    if not clipped.any() or kernel.max() <= 0:
        return StreakCheck(np.zeros(ldr.shape[:2], bool), 0, 0.0)
    cores = cv2.morphologyEx(clipped, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    support = (kernel >= STREAK_SUPPORT_FRACTION * kernel.max()).astype(np.uint8)
    # cv2.dilate takes the maximum over src(x + b): flip the support so a core at s lands at s + offset
    footprint = cv2.dilate(cores, support[::-1, ::-1].copy())
    near_cores = cv2.dilate(cores, np.ones((2 * core_radius_px + 1,) * 2, np.uint8))
    streaks = (clipped > 0) & (footprint > 0) & (near_cores == 0)
    count = int(streaks.sum())
    if not count:
        return StreakCheck(np.zeros(ldr.shape[:2], bool), 0, 0.0)
    distance = cv2.distanceTransform((cores == 0).astype(np.uint8), cv2.DIST_L2, 5)[streaks]
    brightest_at_radius = np.maximum.accumulate(_ring_maxima(kernel)[::-1])[::-1]  # p(d) non-increasing
    radii = np.clip(np.floor(distance).astype(int), 0, len(brightest_at_radius) - 1)
    lower_bound = float(np.max(1.0 / np.maximum(brightest_at_radius[radii], 1e-30)))
    change = -max(1.0, math.ceil(math.log2(max(lower_bound * kernel.max(), 1.0))))
    radius = kernel.shape[0] // 2
    mask = cv2.dilate(streaks.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                                          (2 * radius + 1, 2 * radius + 1))) > 0
    return StreakCheck(mask, count, float(change))


def _ring_maxima(kernel: np.ndarray) -> np.ndarray:
    """Largest kernel value on each whole-pixel ring about the centre."""
    size = kernel.shape[0]
    y, x = np.mgrid[:size, :size] - size // 2
    ring = np.round(np.hypot(y, x)).astype(int).ravel()
    maxima = np.zeros(ring.max() + 1)
    np.maximum.at(maxima, ring, kernel.ravel())
    return maxima
