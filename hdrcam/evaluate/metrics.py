"""HDR image metrics on linear relative radiance (1.0 = sensor full well, highlights up to 2^8).

- Linear PSNR with peak 2^8 (the paper's Table 1 and 2 metric); estimates are clipped to [0, 2^8] first.
- PU21-PSNR: PSNR of the PU21 "banding + glare" perceptually uniform encoding (Mantiuk and Azimi, PCS 2021),
  applied per colour channel to absolute luminance under the fixed mapping 1.0 = 39.0625 cd/m^2 (2^8 ->
  10,000 cd/m^2); peak = PU21(10,000 cd/m^2).
- PSNR-mu: PSNR after mu-law compression T(x) = log(1 + mu x) / log(1 + mu) of x = H / 2^8, mu = 5000.
PSNR of identical images is reported as PSNR_CAP_DB rather than infinity.
"""

from __future__ import annotations

import math

import numpy as np

HARM_DB = 0.3  # an image more than this below its LDR capture was harmed (the generalisation issue's bar)

PEAK_RADIANCE = 256.0
CANDELA_PER_UNIT = 39.0625  # cd/m^2 of relative radiance 1.0
MU = 5000.0
PSNR_CAP_DB = 150.0
_PU21 = (0.353487901, 0.3734658629, 8.277049286e-05, 0.9062562627, 0.09150303166, 0.9099517204, 596.3148142)
_PU21_RANGE_CD = (0.005, 10000.0)


def psnr(estimate: np.ndarray, truth: np.ndarray, peak: float) -> float:
    """10 log10(peak^2 / MSE) in dB over all pixels and channels, capped at PSNR_CAP_DB; images of different
    shapes, or empty ones, are a ValueError (numpy would broadcast a 1 x 1 truth over any estimate)."""
    estimate, truth = np.asarray(estimate, np.float64), np.asarray(truth, np.float64)
    if estimate.shape != truth.shape or not truth.size:
        raise ValueError(f"PSNR of images of shapes {estimate.shape} and {truth.shape}: they must be equal and "
                         "not empty")
    error = estimate - truth
    mse = float(np.mean(error * error))
    if not math.isfinite(mse):
        raise ValueError("PSNR of an image with NaN or Inf values")
    return PSNR_CAP_DB if mse <= peak * peak * 10 ** (-PSNR_CAP_DB / 10) else 10.0 * math.log10(peak * peak / mse)


def psnr_linear(estimate: np.ndarray, truth: np.ndarray) -> float:
    """Linear-domain PSNR, peak 2^8."""
    return psnr(np.clip(estimate, 0.0, PEAK_RADIANCE), truth, PEAK_RADIANCE)


def pu21_encode(luminance_cd_m2: np.ndarray) -> np.ndarray:
    """PU21 banding+glare encoding of absolute luminance (cd/m^2), clamped to 0.005 .. 10,000 cd/m^2."""
    p = _PU21
    y = np.clip(np.asarray(luminance_cd_m2, np.float64), *_PU21_RANGE_CD)
    power = y ** p[3]
    return np.maximum(p[6] * (((p[0] + p[1] * power) / (1.0 + p[2] * power)) ** p[4] - p[5]), 0.0)


PU21_PEAK = float(pu21_encode(np.array(_PU21_RANGE_CD[1])))


def pu21_psnr(estimate: np.ndarray, truth: np.ndarray) -> float:
    """PSNR between the PU21 encodings of two relative-radiance images."""
    return psnr(pu21_encode(np.clip(estimate, 0.0, None) * CANDELA_PER_UNIT),
                pu21_encode(np.clip(truth, 0.0, None) * CANDELA_PER_UNIT), PU21_PEAK)


def mu_law(radiance: np.ndarray) -> np.ndarray:
    """T(H / 2^8) with T(x) = log(1 + mu x) / log(1 + mu), x clipped to [0, 1]."""
    x = np.clip(np.asarray(radiance, np.float64) / PEAK_RADIANCE, 0.0, 1.0)
    return np.log1p(MU * x) / math.log1p(MU)


def psnr_mu(estimate: np.ndarray, truth: np.ndarray) -> float:
    """PSNR of the mu-law compressed images, peak 1."""
    return psnr(mu_law(estimate), mu_law(truth), 1.0)


def all_metrics(estimate: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    return {"psnr_linear": psnr_linear(estimate, truth), "pu21_psnr": pu21_psnr(estimate, truth),
            "psnr_mu": psnr_mu(estimate, truth)}
