"""Pictures for people: log-scaled PSFs and colour-mapped height maps as 8-bit RGB arrays."""

from __future__ import annotations

import cv2
import numpy as np


def log_psf_rgb(psf: np.ndarray, decades: float = 5.0) -> np.ndarray:
    """(3, S, S) PSF -> S x S x 3 uint8, log10 scale over ``decades`` below the brightest value."""
    peak = float(np.max(psf))
    scaled = np.log10(np.maximum(np.asarray(psf, np.float64) / max(peak, 1e-300), 10.0 ** -decades))
    return np.round((scaled / decades + 1.0).clip(0, 1).transpose(1, 2, 0) * 255).astype(np.uint8)


def heightmap_rgb(heights_m: np.ndarray, h_max_m: float) -> np.ndarray:
    """Height map -> H x W x 3 uint8 (viridis, 0 .. h_max)."""
    grey = np.round((np.asarray(heights_m) / h_max_m).clip(0, 1) * 255).astype(np.uint8)
    return cv2.cvtColor(cv2.applyColorMap(grey, cv2.COLORMAP_VIRIDIS), cv2.COLOR_BGR2RGB)


def side_by_side(images: list[np.ndarray], height_px: int = 512, gap_px: int = 8) -> np.ndarray:
    """Scale RGB images to a common height (nearest neighbour, pixels stay visible) and join them."""
    panels = []
    for image in images:
        width = max(1, round(image.shape[1] * height_px / image.shape[0]))
        panels.append(cv2.resize(image, (width, height_px), interpolation=cv2.INTER_NEAREST))
        panels.append(np.full((height_px, gap_px, 3), 255, np.uint8))
    return np.concatenate(panels[:-1], axis=1)
