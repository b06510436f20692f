"""Augmentations real photographs need beyond the paper's (Sec. 5: saturation scaling, rotations, flips).

- Colour jitter. ``reconstruct`` sees a RAW frame in the camera's own RGB, without white balance: the
  simulated A7's colour matrix puts sRGB white at (0.36, 1.00, 0.81), and real sensors under daylight are
  alike (red and blue well below green), under tungsten the other way. A network trained on white-balanced
  photographs alone meets that as a domain shift (tools/bench_raw_path.py: +0.84 dB on a studio photograph in
  camera RGB against +3.10 dB in sRGB). So half the draws are white-balanced photographs with each channel's
  gain within +-WB_JITTER_STOPS (one illuminant's colour is not learned), and half are raw camera colour: red
  and blue gains drawn log-uniformly in RAW_GAIN_STOPS relative to green. Exposure is jittered by the
  saturation scaling itself (1-3 % of the pixels clip).
- Equirectangular panoramas (width = 2 x height, the Poly Haven HDRIs) are stretched near their poles:
  crops are taken from the middle half of their rows (:func:`undistorted_rows`), where they look like
  ordinary photographs.
"""

from __future__ import annotations

import numpy as np

WB_JITTER_STOPS = 0.25  # +-0.25 stop per channel: the spread of daylight to tungsten after camera white balance
RAW_GAIN_STOPS = (-1.6, 0.5)  # red and blue relative to green in a camera's raw RGB (A7: 0.36 and 0.81)
RAW_COLOUR_SHARE = 0.5  # share of draws in raw camera colour


def colour_jitter(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """H x W x 3 linear RGB -> the same with per-channel gains (green 1): with probability RAW_COLOUR_SHARE red
    and blue in 2^RAW_GAIN_STOPS, else each channel within 2^+-WB_JITTER_STOPS of the others."""
    if rng.random() < RAW_COLOUR_SHARE:
        stops = np.array([rng.uniform(*RAW_GAIN_STOPS), 0.0, rng.uniform(*RAW_GAIN_STOPS)])
    else:
        stops = rng.uniform(-WB_JITTER_STOPS, WB_JITTER_STOPS, size=3)
        stops -= stops[1]
    return (image * (2.0 ** stops).astype(np.float32)).astype(np.float32)


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
