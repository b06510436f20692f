"""Crops that prefer saturated regions, and the paper's rotation and flip augmentation."""

from __future__ import annotations

import numpy as np

SATURATED_QUANTILE = 0.985  # a crop is centred on one of the brightest 1.5 % of pixels...
SATURATED_PREFERENCE = 0.8  # ...with this probability; otherwise anywhere


def saturated_crop(image: np.ndarray, size_px: int, rng: np.random.Generator,
                   preference: float = SATURATED_PREFERENCE) -> np.ndarray:
    """A size x size crop of an H x W x C image, usually about a bright pixel (reflect-padded if small)."""
    height, width = image.shape[:2]
    if height < size_px or width < size_px:
        pad_y, pad_x = max(0, size_px - height), max(0, size_px - width)
        image = np.pad(image, ((pad_y // 2, pad_y - pad_y // 2), (pad_x // 2, pad_x - pad_x // 2), (0, 0)),
                       mode="reflect" if min(height, width) > max(pad_y, pad_x) else "edge")
        height, width = image.shape[:2]
    if rng.random() < preference:
        brightest = np.max(image, axis=-1)
        level = np.quantile(brightest, SATURATED_QUANTILE)
        above = brightest > level  # strictly brighter when any are (a few tiny lights in a dark frame)...
        rows, columns = np.nonzero(above if above.any() else brightest >= level)  # ...else the tied top
        pick = int(rng.integers(len(rows)))
        top = int(np.clip(rows[pick] - rng.integers(size_px), 0, height - size_px))
        left = int(np.clip(columns[pick] - rng.integers(size_px), 0, width - size_px))
    else:
        top, left = int(rng.integers(height - size_px + 1)), int(rng.integers(width - size_px + 1))
    return image[top:top + size_px, left:left + size_px]


def rotate_flip(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One of the 8 rotations by multiples of 90 degrees with or without a mirror flip."""
    image = np.rot90(image, int(rng.integers(4)))
    if rng.random() < 0.5:
        image = image[:, ::-1]
    return np.ascontiguousarray(image)
