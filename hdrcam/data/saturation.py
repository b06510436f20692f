"""Exposure scaling of HDR training and test images (paper Sec. 4.3).

An image is divided by the (1 - f) quantile of its per-pixel maximum channel, so that exactly a fraction
f of its pixels exceed 1.0 (the sensor's full well) in at least one channel, then clipped to [0, 2^8].
Training draws f from 1-3 %; testing uses exactly 1.5 %.
"""

from __future__ import annotations

import numpy as np

from hdrcam.errors import InputError

HIGHLIGHT_PEAK = 256.0
TEST_CLIPPED_FRACTION = 0.015
TRAIN_CLIPPED_RANGE = (0.01, 0.03)


def clipped_fraction(radiance: np.ndarray) -> float:
    """Fraction of pixels whose brightest channel exceeds 1."""
    return float(np.mean(np.max(radiance, axis=-1) > 1.0))


def fraction_shortfall(reached: float, asked: float, pixels: int, lit: int | None = None) -> str | None:
    """Why an image of ``pixels`` pixels scaled to leave ``asked`` of them above 1 left ``reached`` instead
    (outside half to twice the asked fraction: fewer pixels than one would make, fewer pixels holding light
    than asked - ``lit``, where given, is the count of pixels above 0 in any channel - or a plateau at its
    brightest), or None when it came close enough."""
    if asked / 2 <= reached <= 2 * asked:
        return None
    if asked * pixels < 1:
        why = f"{100 * asked:g} % of {pixels} pixels is less than one"
    elif lit is not None and lit < asked * pixels:
        why = f"too few lit pixels: only {lit} hold any light ({100 * lit / pixels:.3g} %) - a dark scene"
    else:
        why = "a plateau at its brightest - saturated at source, or uniform - or about as few lit pixels as asked"
    return f"{100 * reached:.3g} % of its pixels exceed 1, not the {100 * asked:g} % asked ({why})"


def saturation_scale(radiance: np.ndarray, fraction: float) -> float:
    """The divisor that leaves ``fraction`` of the pixels of an H x W x 3 image above 1."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"clipped fraction must lie in (0, 1), got {fraction}")
    brightest = np.max(radiance, axis=-1)
    level = float(np.quantile(brightest, 1.0 - fraction, method="higher"))
    if not np.isfinite(level):
        raise InputError("image has no light to scale (its bright pixels are not finite); it cannot be saturated")
    if not level > 0.0:
        lit = int(np.count_nonzero(brightest > 0.0))
        if not lit:
            raise InputError("image has no light to scale (every pixel is zero); it cannot be saturated")
        raise InputError(f"only {lit} of {brightest.size} pixels hold light ({100 * lit / brightest.size:.3g} %), "
                         f"fewer than the {100 * fraction:g} % asked to exceed white: ask for a smaller fraction")
    return level


def scale_to_clipped_fraction(radiance: np.ndarray, fraction: float, scale_region: np.ndarray | None = None
                              ) -> np.ndarray:
    """``radiance / saturation_scale(...)`` clipped to [0, 2^8]; the scale is measured on ``scale_region``
    (a view of the same image, e.g. the centre crop of a padded scene) when given."""
    scale = saturation_scale(radiance if scale_region is None else scale_region, fraction)
    with np.errstate(over="ignore"):  # a value near float32's top over a scale below 1 is inf: clipped to 2^8
        return np.clip(radiance / np.float32(scale), 0.0, HIGHLIGHT_PEAK).astype(np.float32)
