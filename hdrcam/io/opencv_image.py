"""Image files OpenCV decodes (PNG, TIFF and the other formats it knows), read with its own error lines silenced
and its refusals turned into one-line errors naming the file."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from hdrcam.errors import InputError
from hdrcam.io.c_stderr import c_stderr_silenced
from hdrcam.io.png import png_size_px
from hdrcam.limits import check_image_size

DECODED_BYTES_PER_PIXEL = 20  # OpenCV's image (up to four 16-bit samples) and the float32 RGB copy made of it


def opencv_image(path: Path, flags: int) -> np.ndarray | None:
    """``cv2.imread(path, flags)`` with OpenCV's own lines for a damaged file silenced: None where it reads no
    image, InputError naming ``path`` where it refuses to decode one (a header declaring more than the 2^30 pixels
    OpenCV decodes: damaged, or too large an image), which OpenCV raises as its own error, not as None. A PNG is
    sized from its header first: one declaring more pixels than memory holds is refused before decoding."""
    size = png_size_px(path)
    if size is not None:
        check_image_size(str(path), size[1], size[0], DECODED_BYTES_PER_PIXEL, "give a smaller image")
    try:
        with c_stderr_silenced():
            return cv2.imread(str(path), flags)
    except cv2.error as error:
        reason = ("its header declares more pixels than OpenCV decodes (2^30): a damaged file or too large an "
                  "image; use a smaller image" if "CV_IO_MAX_IMAGE_PIXELS" in str(error) else
                  f"OpenCV cannot decode it ({getattr(error, 'err', None) or 'an error of its own'})")
        raise InputError(f"{path}: {reason}") from None
