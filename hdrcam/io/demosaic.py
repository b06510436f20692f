"""Demosaicing Bayer data into camera RGB, by OpenCV (default, fast) or colour-demosaicing (accurate).

Methods (speed and accuracy measured by ``tools/bench_demosaic.py`` on a real A7R III frame and on simulated
frames with known truth; table in the README):

- ``bilinear`` (default): OpenCV's bilinear Bayer conversion. OpenCV converts 8/16-bit data only, so float
  data (a merged HDR rate) goes through the same interpolation as ``cv2.filter2D`` with OpenCV's bilinear
  weights (equal to ``cv2.cvtColor`` on integer data; checked by the tests).
- ``edge-aware``: OpenCV's edge-aware conversion (``COLOR_Bayer*2RGB_EA``); integer data only.
- ``menon2007``: colour-demosaicing's DDFAPD with refinement (Menon, Andriani and Calvagno 2007), float or
  integer data; several times slower, and its import (colour-science) costs about a second. Its ringing at
  sharp edges is clipped to the range of the measured samples (nothing below the lowest - for non-negative data
  no negative light - and nothing above the brightest).

Each sample is kept where it was measured; the output is float32 in the input's units. OpenCV and
colour-demosaicing (and numpy) are imported on first use: the command line reads METHODS without them.
"""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

CFA_CHANNELS = {"R": 0, "G": 1, "B": 2}  # RGB channel index of each CFA colour
METHODS = ("bilinear", "edge-aware", "menon2007")
FLOAT_METHODS = ("bilinear", "menon2007")  # those that take float (HDR) data
DEFAULT_METHOD = "bilinear"
# OpenCV names a Bayer layout by the 2 x 2 tile that starts at its second row and column
_OPENCV_LAYOUT = {"RGGB": "BG", "BGGR": "RG", "GRBG": "GB", "GBRG": "GR"}
_GREEN_WEIGHTS = ((0, 1, 0), (1, 4, 1), (0, 1, 0))  # / 4: OpenCV's bilinear interpolation
_RED_BLUE_WEIGHTS = ((1, 2, 1), (2, 4, 2), (1, 2, 1))
FLOAT_STRIP_ROWS = 32


def cfa_masks(shape: tuple[int, int], pattern: str) -> np.ndarray:
    """3 x H x W float32 indicator of which CFA colour each pixel samples (``pattern``: the 2 x 2 tile at the
    top-left pixel, row-major, e.g. "RGGB")."""
    import numpy as np

    masks = np.zeros((3, *shape), np.float32)
    for position, colour in enumerate(pattern):
        row, column = divmod(position, 2)
        masks[CFA_CHANNELS[colour], row::2, column::2] = 1.0
    return masks


def demosaic(bayer: np.ndarray, pattern: str, method: str = DEFAULT_METHOD) -> np.ndarray:
    """H x W Bayer samples -> H x W x 3 float32 camera RGB in the same units.

    ``pattern``: the CFA's 2 x 2 tile at the top-left pixel ("RGGB", "BGGR", "GRBG" or "GBRG"). ``method``:
    one of METHODS (module docstring); ``edge-aware`` needs integer (uint8/uint16) data.
    """
    if pattern not in _OPENCV_LAYOUT:
        raise ValueError(f"unknown CFA pattern {pattern!r}; expected one of {', '.join(_OPENCV_LAYOUT)}")
    if method not in METHODS:
        raise ValueError(f"unknown demosaicing method {method!r}; choose from {', '.join(METHODS)}")
    import cv2
    import numpy as np

    integer = bayer.dtype in (np.uint8, np.uint16)
    if method == "menon2007":
        with warnings.catch_warnings():  # colour-science warns that matplotlib is absent; plots are not used
            warnings.simplefilter("ignore")
            from colour_demosaicing import demosaicing_CFA_Bayer_Menon2007

        samples = bayer.astype(np.float32)
        rgb = demosaicing_CFA_Bayer_Menon2007(samples, pattern).astype(np.float32)
        # its refinement rings at edges (below zero beside a clipped light, above the brightest sample): an
        # interpolated value is kept within the range of the samples measured
        return np.clip(rgb, samples.min(initial=0.0), samples.max(initial=0.0), out=rgb)
    if integer:
        suffix = "_EA" if method == "edge-aware" else ""
        code = getattr(cv2, f"COLOR_Bayer{_OPENCV_LAYOUT[pattern]}2RGB{suffix}")
        return cv2.cvtColor(np.ascontiguousarray(bayer), code).astype(np.float32)
    if method != "bilinear":
        raise ValueError(f"{method} demosaicing takes 8/16-bit data; float data: {', '.join(FLOAT_METHODS)}")
    return _float_bilinear(np.asarray(bayer, np.float32), pattern)


def _float_bilinear(bayer: np.ndarray, pattern: str) -> np.ndarray:
    """OpenCV's bilinear weights applied by cv2.filter2D to each colour's samples (zeros elsewhere), on strips
    of FLOAT_STRIP_ROWS rows (plus one row of context each side) in a thread pool: every output pixel depends
    only on its 3 x 3 neighbourhood, so the strips give what the whole image gives, and the temporaries stay
    small instead of six full-size planes."""
    import cv2
    import numpy as np

    from hdrcam.parallel import strips, worker_threads

    height, width = bayer.shape
    rgb = np.empty((height, width, 3), np.float32)
    kernels = [np.array(_GREEN_WEIGHTS if channel == 1 else _RED_BLUE_WEIGHTS, np.float32) / 4 for channel in range(3)]

    def strip(rows: slice) -> None:
        top, bottom = max(rows.start - 1, 0), min(rows.stop + 1, height)
        samples = bayer[top:bottom]
        planes = np.zeros((3, bottom - top, width), np.float32)
        for position, colour in enumerate(pattern):
            row, column = (position // 2 + top) % 2, position % 2  # the tile position's phase within the strip
            planes[CFA_CHANNELS[colour], row::2, column::2] = samples[row::2, column::2]
        for channel in range(3):
            filtered = cv2.filter2D(planes[channel], -1, kernels[channel], borderType=cv2.BORDER_REFLECT_101)
            rgb[rows, :, channel] = filtered[rows.start - top:rows.stop - top]

    with ThreadPoolExecutor(worker_threads()) as pool:
        list(pool.map(strip, strips(height, FLOAT_STRIP_ROWS)))
    return rgb
