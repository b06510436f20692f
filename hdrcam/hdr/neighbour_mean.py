"""Each Bayer sample's prediction from its same-colour neighbours, free of its own noise.

A sample's eight nearest samples of its own CFA colour lie two rows or columns away; their mean predicts the
sample's value with noise independent of its own - what a selection or a weight must be drawn from so as not to
favour samples that happened to read high or low (the exposure ratios' bound, hdrcam.hdr.exposure_ratios; the
PSF fit's weights, hdrcam.calibrate.psf_calibration).
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

NEIGHBOUR_ROWS = 2  # a sample's same-colour neighbours lie two rows away
_SAME_COLOUR_NEIGHBOURS = np.array([[1, 0, 1, 0, 1], [0, 0, 0, 0, 0], [1, 0, 0, 0, 1], [0, 0, 0, 0, 0],
                                    [1, 0, 1, 0, 1]], np.float32)  # the centre sample itself left out


def neighbour_mean(bayer: np.ndarray) -> np.ndarray:
    """Mean of each sample's nearest samples of its own CFA colour (two rows or columns away: eight inside the
    array, fewer at its edges), without the sample itself: a prediction of its value whose noise is independent
    of its own. Outside the array counts as missing (a normalised convolution), so no edge mirrors a sample onto
    itself; inside, a strip given NEIGHBOUR_ROWS rows either side gets what the whole frame would."""
    sums = cv2.filter2D(bayer, cv2.CV_32F, _SAME_COLOUR_NEIGHBOURS, borderType=cv2.BORDER_CONSTANT)
    return cv2.divide(sums, _neighbour_counts(bayer.shape), dst=sums)


@functools.lru_cache(maxsize=8)
def _neighbour_counts(shape: tuple[int, int]) -> np.ndarray:
    """How many same-colour neighbours each sample of an array of ``shape`` has inside it (8, fewer at the edges);
    one array per strip shape, read only."""
    counts = cv2.filter2D(np.ones(shape, np.float32), cv2.CV_32F, _SAME_COLOUR_NEIGHBOURS,
                          borderType=cv2.BORDER_CONSTANT)
    counts.flags.writeable = False
    return counts
