"""Wavelength samples of the sensor's R, G, B bands."""

from __future__ import annotations

import numpy as np


def band_wavelengths_m(band_edges_m: tuple[float, float], samples: int) -> np.ndarray:
    """Centres of ``samples`` equal sub-bands of [shortest, longest]; one sample is the band centre."""
    if samples < 1:
        raise ValueError("need at least one wavelength sample per band")
    shortest, longest = band_edges_m
    width = (longest - shortest) / samples
    return shortest + width * (np.arange(samples) + 0.5)
