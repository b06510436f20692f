"""Sub-pixel placement of a pixel-integrated PSF (the image of an unresolved source between pixel centres).

Model: a PSF at the sensor pitch holds the energy each pixel integrates; within a pixel the intensity is
taken as uniform (a box). Moving the source by a fraction (f_y, f_x) of a pixel then splits each pixel's
energy over the 2 x 2 pixels it now overlaps, in proportion to the overlap areas (1 - f) and f per axis.
Unlike a Fourier (band-limited) shift this never rings: values stay >= 0, energy is exact, and the first
moment moves by exactly f. The simulated camera renders point sources with it and PSF calibration
inverts it (hdrcam.calibrate.effective_psf), so the two share one definition.
"""

from __future__ import annotations

import numpy as np


def split_position(position_px: float) -> tuple[int, float]:
    """Pixel index and fraction in [0, 1): position = index + fraction (pixel centres at integers)."""
    index = int(np.floor(position_px))
    return index, float(position_px - index)


def box_shift(psf: np.ndarray, fraction_y: float, fraction_x: float) -> np.ndarray:
    """(..., k, k) PSF moved down/right by fractions in [0, 1): (..., k + 1, k + 1), same energy.

    Output pixel (u, v) = sum over the four source pixels (u - a, v - b), a, b in {0, 1}, weighted
    (1 - f_y or f_y) x (1 - f_x or f_x). Pixel (u, v) of the output lies at offset (u, v) from the
    source's integer pixel minus k // 2, exactly as the input did at zero fraction.
    """
    *leading, size_y, size_x = psf.shape
    out = np.zeros((*leading, size_y + 1, size_x + 1), np.result_type(psf, np.float32))
    for a, weight_y in ((0, 1.0 - fraction_y), (1, fraction_y)):
        for b, weight_x in ((0, 1.0 - fraction_x), (1, fraction_x)):
            out[..., a:a + size_y, b:b + size_x] += weight_y * weight_x * psf
    return out
