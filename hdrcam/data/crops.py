"""Crops that prefer saturated regions (training draws and the fixed test scenes), and the paper's rotation and
flip augmentation."""

from __future__ import annotations

import numpy as np

SATURATED_QUANTILE = 0.985  # a crop is centred on one of the brightest 1.5 % of pixels...
SATURATED_PREFERENCE = 0.8  # ...with this probability; otherwise anywhere


def saturated_crop(image: np.ndarray, size_px: int, rng: np.random.Generator,
                   preference: float = SATURATED_PREFERENCE) -> np.ndarray:
    """A size x size crop of an H x W x C image, usually about a bright pixel (reflect-padded if small)."""
    image = padded_to(image, size_px)
    top, left = _origin(image, size_px, rng, preference, 0)
    return image[top:top + size_px, left:left + size_px]


def scored_crop(image: np.ndarray, size_px: int, margin_px: int, context_px: int, rng: np.random.Generator
              ) -> np.ndarray:
    """A (size + 2 margin)^2 crop of a fixed test scene: its centre size^2 - the region scored - holds one of the
    brightest 1.5 % of pixels (drawn as saturated_crop draws) and keeps ``context_px`` of the image on every
    side where the image is large enough, so neither the scored region nor its context within ``context_px``
    depends on ``margin_px`` (a checkpoint's PSF); beyond the image the margin is mirrored. (The crop of size +
    2 margin put the bright pixel anywhere in it: in 2 of 8 lamp photographs at margin 127 the scored centre
    held no lamp, and the same seed scored other regions for PSFs of another size.)"""
    image = padded_to(image, size_px)
    height, width = image.shape[:2]
    top, left = _origin(image, size_px, rng, 1.0, context_px)
    rows = _mirrored(np.arange(top - margin_px, top + size_px + margin_px), height)
    columns = _mirrored(np.arange(left - margin_px, left + size_px + margin_px), width)
    return image[np.ix_(rows, columns)]


def padded_to(image: np.ndarray, size_px: int) -> np.ndarray:
    """``image`` reflect-padded (edge-padded where it is too small to reflect) to at least size x size."""
    height, width = image.shape[:2]
    if height >= size_px and width >= size_px:
        return image
    pad_y, pad_x = max(0, size_px - height), max(0, size_px - width)
    return np.pad(image, ((pad_y // 2, pad_y - pad_y // 2), (pad_x // 2, pad_x - pad_x // 2), (0, 0)),
                  mode="reflect" if min(height, width) > max(pad_y, pad_x) else "edge")


def _origin(image: np.ndarray, size_px: int, rng: np.random.Generator, preference: float, context_px: int
            ) -> tuple[int, int]:
    """Top-left corner of a size x size crop, ``context_px`` (or as much as fits) inside the image's edges:
    with probability ``preference`` about one of the brightest 1.5 % of pixels (which stays in the crop, context
    or not), else anywhere."""
    height, width = image.shape[:2]
    low_y, low_x = min(context_px, (height - size_px) // 2), min(context_px, (width - size_px) // 2)
    if rng.random() < preference:
        brightest = np.max(image, axis=-1)
        level = np.quantile(brightest, SATURATED_QUANTILE)
        above = brightest > level  # strictly brighter when any are (a few tiny lights in a dark frame)...
        rows, columns = np.nonzero(above if above.any() else brightest >= level)  # ...else the tied top
        pick = int(rng.integers(len(rows)))
        top = np.clip(rows[pick] - rng.integers(size_px), low_y, height - size_px - low_y)
        left = np.clip(columns[pick] - rng.integers(size_px), low_x, width - size_px - low_x)
        # the context gives way where it would push the bright pixel out of the crop (a lamp near an edge)
        return (int(np.clip(top, rows[pick] - size_px + 1, rows[pick])),
                int(np.clip(left, columns[pick] - size_px + 1, columns[pick])))
    return (low_y + int(rng.integers(height - size_px - 2 * low_y + 1)),
            low_x + int(rng.integers(width - size_px - 2 * low_x + 1)))


def _mirrored(indices: np.ndarray, length: int) -> np.ndarray:
    """Indices outside 0 .. length - 1 reflected into it as numpy's "reflect" padding does (repeatedly)."""
    if length == 1:
        return np.zeros_like(indices)
    period = 2 * (length - 1)
    folded = np.mod(indices, period)
    return np.where(folded >= length, period - folded, folded)


def rotate_flip(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One of the 8 rotations by multiples of 90 degrees with or without a mirror flip."""
    image = np.rot90(image, int(rng.integers(4)))
    if rng.random() < 0.5:
        image = image[:, ::-1]
    return np.ascontiguousarray(image)
