"""PSF files: float EXRs with channels R, G, B (camera RGB), any odd or even square size, axis at S // 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hdrcam.errors import InputError
from hdrcam.io.exr import read_exr


PSF_UNITS = "unit sum per channel"  # the "units" attribute of a PSF EXR hdrcam writes (calibrate psf)


PITCH_TOLERANCE = 0.01  # relative: a PSF measured at another pixel pitch than the camera's is another PSF


def load_psf(path: Path, *, pixel_pitch_m: float | None = None) -> np.ndarray:
    """A PSF EXR as 3 x k x k float32, each channel normalised to unit sum.

    Tiny negative values (noise left by a measured calibration, down to -1e-3 of the channel's peak) are
    set to zero; larger ones, NaN or Inf, a non-square image, an all-zero channel, or an EXR whose "units"
    attribute says it holds something else (a frame, an HDR image) are errors. With ``pixel_pitch_m`` (the
    camera's, metres), a file whose "pixel_pitch_m" attribute differs by more than 1 % is an error too: its
    pixels are another size than the camera's.
    """
    image = read_exr(Path(path))
    units = image.attributes.get("units")
    if units is not None and units != PSF_UNITS:  # hdrcam's frames and HDR images say what they hold
        raise InputError(f"{path}: not a PSF - an image of {units!r} (a PSF EXR holds {PSF_UNITS!r} or no units)")
    file_pitch_m = image.attributes.get("pixel_pitch_m")
    if pixel_pitch_m is not None and isinstance(file_pitch_m, (int, float)) and \
            not abs(file_pitch_m / pixel_pitch_m - 1.0) <= PITCH_TOLERANCE:
        raise InputError(f"{path}: a PSF of {file_pitch_m * 1e6:.4g} um pixels, but the camera's are "
                         f"{pixel_pitch_m * 1e6:.4g} um; measure or simulate the PSF with this camera's profile")
    return unit_sum_psf(image.rgb().transpose(2, 0, 1), source=str(path))


def unit_sum_psf(psf, *, source: str = "psf") -> np.ndarray:
    """A (3, k, k) PSF (a file's or an array a caller gives) as float32 with each channel summing to 1; InputError
    naming ``source`` for one that is not an intensity: another shape, NaN or Inf, an all-zero channel, negative
    values below -1e-3 of the channel's peak (tinier ones, a measured calibration's noise, are set to zero)."""
    psf = np.asarray(psf, np.float64)
    if psf.ndim != 3 or psf.shape[0] != 3 or psf.shape[1] != psf.shape[2] or psf.shape[1] == 0:
        raise InputError(f"{source}: a PSF is square with a channel each for R, G, B (3 x k x k), got shape "
                         f"{psf.shape}")
    if not np.isfinite(psf).all():
        raise InputError(f"{source}: PSF has NaN or Inf values")
    peaks = psf.max(axis=(1, 2), keepdims=True)
    if not (peaks > 0).all() or (psf < -1e-3 * peaks).any():
        raise InputError(f"{source}: PSF is not an intensity: a channel is all zero or has values below -1e-3 of "
                         "its peak")
    psf = np.clip(psf, 0.0, None)
    return (psf / psf.sum(axis=(1, 2), keepdims=True)).astype(np.float32)
