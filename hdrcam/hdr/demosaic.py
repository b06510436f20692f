"""Bilinear demosaicing of float (HDR) Bayer data.

OpenCV's demosaicing takes only 8/16-bit integers, which cannot hold merged HDR rates, so the classic
bilinear kernels are applied to float32 with cv2.filter2D (reflected borders).
"""

from __future__ import annotations

import cv2
import numpy as np

from hdrcam.sensor import CFA_CHANNELS

_GREEN_KERNEL = np.array([[0, 1, 0], [1, 4, 1], [0, 1, 0]], np.float32) / 4
_RED_BLUE_KERNEL = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]], np.float32) / 4



def cfa_masks(shape: tuple[int, int], pattern: str) -> np.ndarray:
    """3 x H x W float32 indicator of which CFA colour each pixel samples."""
    masks = np.zeros((3, *shape), np.float32)
    for position, colour in enumerate(pattern):
        row, column = divmod(position, 2)
        masks[CFA_CHANNELS[colour], row::2, column::2] = 1.0
    return masks


def demosaic_bilinear(bayer: np.ndarray, pattern: str) -> np.ndarray:
    """H x W float Bayer -> H x W x 3 float32 camera RGB (each sample kept, the others interpolated)."""
    masks = cfa_masks(bayer.shape, pattern)
    rgb = np.empty((*bayer.shape, 3), np.float32)
    for channel in range(3):
        kernel = _GREEN_KERNEL if channel == 1 else _RED_BLUE_KERNEL
        rgb[..., channel] = cv2.filter2D(np.ascontiguousarray(bayer * masks[channel], np.float32), -1, kernel,
                                         borderType=cv2.BORDER_REFLECT_101)
    return rgb
