"""A measured PSF against a design: per-channel L1, the design as designed or moved as calibration places it.

Calibration fixes the measured PSF's green centroid on its centre pixel (hdrcam.calibrate.effective_psf); a
design whose centroid lies a fraction of a pixel off differs from it by that shift alone. ``centred_on_green``
moves the design there by the box model (hdrcam.optics.subpixel), as a perfect calibration would place it up
to the box model's own error (its shifts do not compose, so neither comparison is the exact truth).
Units: PSFs are 3 x k x k, each channel's energy summing to 1; L1 is a fraction of that energy.
"""

from __future__ import annotations

import numpy as np

from hdrcam.calibrate.effective_psf import green_centroid_offset
from hdrcam.optics.subpixel import box_shift, split_position


def centred_on_green(psf: np.ndarray) -> np.ndarray:
    """``psf`` (3 x k x k) moved by the box model so its green centroid sits on pixel k // 2, as calibration
    places a measured one; same size."""
    offset_y, offset_x = green_centroid_offset(psf)
    index_y, fraction_y = split_position(-offset_y)
    index_x, fraction_x = split_position(-offset_x)
    size = psf.shape[-1]
    return box_shift(psf, fraction_y, fraction_x)[:, -index_y:-index_y + size, -index_x:-index_x + size]


def psf_l1(measured: np.ndarray, design: np.ndarray) -> list[float]:
    """Per-channel L1 between two PSFs, the larger cropped to the smaller about its centre and each channel
    renormalised to unit energy there (fractions of the energy)."""
    size = min(measured.shape[-1], design.shape[-1])

    def cropped(psf: np.ndarray) -> np.ndarray:
        start = (psf.shape[-1] - size) // 2
        crop = np.asarray(psf, np.float64)[:, start:start + size, start:start + size]
        return crop / crop.sum(axis=(1, 2), keepdims=True)

    return [float(v) for v in np.abs(cropped(measured) - cropped(design)).sum(axis=(1, 2))]
