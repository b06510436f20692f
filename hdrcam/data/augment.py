"""Augmentations real photographs need beyond the paper's (Sec. 4.3: saturation scaling, rotations, flips).

- White-balance jitter: each channel is multiplied by a gain drawn log-uniformly within +-WB_JITTER_STOPS
  stops (then divided by the green gain), so the network does not learn one illuminant's colour of a
  highlight. Exposure is jittered by the saturation scaling itself (1-3 % of the pixels clip). A wider jitter
  covering raw camera colour (red and blue 2^-1.6..2^0.5 of green) was tried for RAW frames, which reach the
  network unbalanced: it did not help them (tools/results/real-data/README.md, "Raw camera colour").
- Equirectangular panoramas (width = 2 x height, the Poly Haven HDRIs) are stretched near their poles:
  crops are taken from the middle half of their rows (:func:`undistorted_rows`), where they look like
  ordinary photographs.
"""

from __future__ import annotations

import numpy as np

WB_JITTER_STOPS = 0.25  # +-0.25 stop per channel: the spread of daylight to tungsten after camera white balance


def white_balance_jitter(image: np.ndarray, rng: np.random.Generator,
                         stops: float = WB_JITTER_STOPS) -> np.ndarray:
    """H x W x 3 linear RGB -> the same with per-channel gains 2^u, u ~ U(-stops, stops), green gain 1."""
    gains = 2.0 ** rng.uniform(-stops, stops, size=3)
    gains /= gains[1]
    return (image * gains.astype(np.float32)).astype(np.float32)


def is_equirectangular(image: np.ndarray) -> bool:
    """True for a 2:1 image (a latitude-longitude panorama)."""
    height, width = image.shape[:2]
    return width == 2 * height


def undistorted_rows(image: np.ndarray, min_rows: int) -> np.ndarray:
    """The middle half of a panorama's rows (widened to ``min_rows`` when a crop needs more); other images
    unchanged."""
    if not is_equirectangular(image):
        return image
    height = image.shape[0]
    rows = min(height, max(height // 2, min_rows))
    top = (height - rows) // 2
    return image[top:top + rows]
