"""PSF files: float EXRs with channels R, G, B (camera RGB), any odd or even square size, axis at S // 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hdrcam.errors import InputError
from hdrcam.io.exr import read_exr


PSF_UNITS = "unit sum per channel"  # the "units" attribute of a PSF EXR hdrcam writes (calibrate psf)


def load_psf(path: Path) -> np.ndarray:
    """A PSF EXR as 3 x k x k float32, each channel normalised to unit sum.

    Tiny negative values (noise left by a measured calibration, down to -1e-3 of the channel's peak) are
    set to zero; larger ones, NaN or Inf, a non-square image, an all-zero channel, or an EXR whose "units"
    attribute says it holds something else (a frame, an HDR image) are errors.
    """
    image = read_exr(Path(path))
    units = image.attributes.get("units")
    if units is not None and units != PSF_UNITS:  # hdrcam's frames and HDR images say what they hold
        raise InputError(f"{path}: not a PSF - an image of {units!r} (a PSF EXR holds {PSF_UNITS!r} or no units)")
    psf = image.rgb().transpose(2, 0, 1).astype(np.float64)
    if psf.shape[1] != psf.shape[2]:
        raise InputError(f"{path}: a PSF must be square, got {psf.shape[1]} x {psf.shape[2]}")
    if not np.isfinite(psf).all():
        raise InputError(f"{path}: PSF has NaN or Inf values")
    peaks = psf.max(axis=(1, 2), keepdims=True)
    if not (peaks > 0).all():
        raise InputError(f"{path}: a PSF channel is all zero")
    if (psf < -1e-3 * peaks).any():
        raise InputError(f"{path}: PSF has negative values below -1e-3 of its peak; it is not an intensity")
    psf = np.clip(psf, 0.0, None)
    return (psf / psf.sum(axis=(1, 2), keepdims=True)).astype(np.float32)
