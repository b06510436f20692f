"""TIFF images as H x W x samples arrays in the file's sample order (R, G, B[, extra]), by tifffile.

OpenCV's TIFF decoder hands back the planes of a "per channel" file (PlanarConfiguration 2) as if they were
interleaved: such a frame came back scrambled with no error (a 16-bit planar TIFF reconstructed with unclipped
pixels up to 0.92 of white off). tifffile decodes both layouts and every TIFF compression in use.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import tifffile

from hdrcam.errors import InputError


def read_tiff_samples(path: Path) -> np.ndarray:
    """The first image of a TIFF file: H x W x samples in the stored type (a one-sample image is H x W);
    InputError naming the file when it cannot be decoded."""
    try:
        with tifffile.TiffFile(path) as tiff:
            page = tiff.pages[0]
            samples = page.asarray()
            axes = page.axes
    except (tifffile.TiffFileError, ValueError, OSError, NotImplementedError, KeyError, IndexError) as error:
        raise InputError(f"{path}: cannot decode as TIFF ({type(error).__name__}: {error})") from None
    if axes.startswith("S") and samples.ndim == 3:  # planar: one plane per sample
        samples = np.moveaxis(samples, 0, -1)
    return samples
