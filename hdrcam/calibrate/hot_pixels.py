"""Hot pixels: samples whose dark frame sits far above the read-noise floor.

Dark subtraction removes their mean charge but not its shot noise, so they are left out of the PSF fit
(which then fills them in from the model, the least-squares form of interpolating from neighbours).
"""

from __future__ import annotations

import numpy as np

from hdrcam.hdr.merge import black_subtracted
from hdrcam.io.raw import RawFrame

HOT_SIGMAS = 6.0  # of the read noise; a false alarm rate of ~1e-9 per sample under Gaussian read noise


def hot_pixel_map(darks: list[RawFrame], read_noise_dn: float) -> np.ndarray:
    """H x W bool: True where any dark frame exceeds its median by HOT_SIGMAS read-noise sigmas."""
    hot = np.zeros(darks[0].bayer_dn.shape, bool)
    for dark in darks:
        signal = black_subtracted(dark)
        hot |= signal > float(np.median(signal)) + HOT_SIGMAS * read_noise_dn
    return hot
