"""Captured LDR frames for reconstruction, as H x W x 3 float32 camera RGB relative to white (0 .. 1).

- RAW (.arw, .dng, ...): black level subtracted per CFA position and clipped to [0, white - black] in digital
  numbers, demosaiced (hdrcam.io.demosaic; OpenCV's bilinear by default, on the integers when the black
  levels are whole numbers), divided by (white - black). No white balance or colour matrix: the network works in camera RGB, the
  space in which the PSF is measured.
- EXR: linear RGB taken as is (1.0 = white).
- 16-bit TIFF / PNG: linear values / 65535. 8-bit files are refused (they are gamma-encoded, not linear).
Frames with NaN/Inf or values above 1 (an HDR image, not a capture) are one-line errors.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from hdrcam.errors import InputError
from hdrcam.io.demosaic import CFA_CHANNELS, DEFAULT_METHOD, demosaic
from hdrcam.io.exr import read_exr
from hdrcam.io.raw import RAW_SUFFIXES, RawFrame, read_raw

IMAGE_SUFFIXES = (".tif", ".tiff", ".png")
LDR_TOLERANCE = 1.001  # values up to this are rounding; above it the file is not an LDR capture


def read_ldr_frame(path: Path, demosaic_method: str = DEFAULT_METHOD) -> np.ndarray:
    """H x W x 3 float32 camera RGB relative to white (0 .. 1) of a RAW, EXR or 16-bit TIFF/PNG frame;
    ``demosaic_method`` (RAW only): one of ``hdrcam.io.demosaic.METHODS``."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path} does not exist")
    suffix = path.suffix.lower()
    if suffix in RAW_SUFFIXES:
        rgb = _raw_relative_rgb(read_raw(path), demosaic_method)
    elif suffix == ".exr":
        rgb = read_exr(path).rgb()
    elif suffix in IMAGE_SUFFIXES:
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image is None or image.ndim != 3 or image.shape[2] < 3:
            raise InputError(f"{path}: cannot read as an RGB image")
        if image.dtype != np.uint16:
            raise InputError(f"{path}: {image.dtype} pixels are gamma-encoded, not linear; give a 16-bit TIFF/PNG, "
                             "an EXR or a RAW file")
        rgb = cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 65535.0
    else:
        raise InputError(f"{path}: unknown frame type {suffix!r} (RAW, EXR, 16-bit TIFF or PNG)")
    if not np.isfinite(rgb).all():
        raise InputError(f"{path}: frame has NaN or Inf pixels")
    if float(rgb.max()) > LDR_TOLERANCE:
        raise InputError(f"{path}: values reach {float(rgb.max()):.4g}, above white (1.0): this is not an LDR "
                         "capture (give the camera frame, not an HDR image)")
    return np.clip(rgb, 0.0, 1.0).astype(np.float32)


def _raw_relative_rgb(frame: RawFrame, demosaic_method: str) -> np.ndarray:
    """Black-subtracted, demosaiced RAW data over (white - black): 1.0 = white."""
    height, width = frame.bayer_dn.shape
    tile = frame.metadata.black_level_tile()
    black = np.tile(tile, (height // 2 + 1, width // 2 + 1))[:height, :width]
    range_dn = frame.metadata.white_level_dn - black
    signal_dn = np.clip(frame.bayer_dn.astype(np.float32) - black, 0.0, range_dn)
    if np.all(tile == np.round(tile)) and range_dn.max() < 65536:
        signal_dn = signal_dn.astype(np.uint16)  # exact: OpenCV's integer demosaicing
    rgb = demosaic(signal_dn, frame.metadata.cfa_pattern, demosaic_method)
    channel_range = [np.mean([frame.metadata.white_level_dn - tile.flat[position]
                              for position, colour in enumerate(frame.metadata.cfa_pattern) if colour == name])
                     for name in sorted(CFA_CHANNELS, key=CFA_CHANNELS.get)]  # mean over the two greens
    return rgb / np.asarray(channel_range, np.float32)
