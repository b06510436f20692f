"""Image formation on the sensor (paper Eq. 6): I_s = clip_[0,1](I * p + eta), then ADC and CFA.

Units: image values are relative exposures, 1.0 = the sensor's full well (the white level above black).
Noise follows the Poisson-Gaussian model in electrons: shot noise of the collected charge plus Gaussian
read noise. Everything is torch, batched (N, C, H, W), differentiable where training needs it, and seeded
through an explicit ``torch.Generator``.
"""

from __future__ import annotations

import dataclasses

import scipy.fft
import torch

from hdrcam.io.demosaic import CFA_CHANNELS
from hdrcam.profiles import CameraSpec

_VARIANCE_FLOOR_E2 = 1e-6  # keeps d sqrt(variance) finite at zero signal and zero read noise


def fft_convolve(image: torch.Tensor, psf: torch.Tensor, *, spectrum: torch.Tensor | None = None) -> torch.Tensor:
    """Linear (zero-padded, not circular) convolution of (..., C, H, W) with a (C, kh, kw) PSF.

    Output has the input's size: out[y, x] = sum_ij image[y - i + kh // 2, x - j + kw // 2] psf[i, j], so the
    PSF's centre is pixel (kh // 2, kw // 2) for odd and even sizes alike. FFT lengths are padded to fast
    sizes of at least H + kh - 1 (:func:`fft_shape`). ``spectrum``: the PSF's :func:`psf_spectrum` at this image's
    FFT shape, where many images of one size meet one PSF (two transforms a convolution instead of three).
    """
    if psf.shape[-3] != image.shape[-3]:
        raise ValueError(f"PSF has {psf.shape[-3]} channels, image has {image.shape[-3]}")
    shape = fft_shape(image.shape[-2:], psf.shape[-2:])
    if spectrum is None:
        spectrum = psf_spectrum(psf.to(image.dtype), shape)
    full = torch.fft.irfft2(torch.fft.rfft2(image, s=shape) * spectrum, s=shape)
    top, left = psf.shape[-2] // 2, psf.shape[-1] // 2
    return full[..., top:top + image.shape[-2], left:left + image.shape[-1]]


def fft_shape(image_shape: tuple[int, int], psf_shape: tuple[int, int]) -> tuple[int, int]:
    """The FFT lengths of a linear convolution of an image (H, W) with a PSF (kh, kw): fast sizes of at least
    H + kh - 1 and W + kw - 1."""
    return tuple(scipy.fft.next_fast_len(int(image) + int(kernel) - 1, real=True)
                 for image, kernel in zip(image_shape, psf_shape))


def psf_spectrum(psf: torch.Tensor, shape: tuple[int, int]) -> torch.Tensor:
    """The (C, kh, kw) PSF's real 2-D FFT at ``shape`` (:func:`fft_shape`), for :func:`fft_convolve`."""
    return torch.fft.rfft2(psf, s=shape)


FFT_ROUND_OFF = 1e-6  # of a float32 FFT convolution's largest value: below it, round-off (measured 8e-8 of the
# peak over 96 px, 6.5e-7 over 2048-4096 px), not light; the shipped PSFs hold at most 5e-6 of their light there


def without_fft_round_off(planes: torch.Tensor) -> torch.Tensor:
    """A float32 :func:`fft_convolve` result (..., C, H, W) with its round-off - values within FFT_ROUND_OFF of
    their plane's largest magnitude - set to 0: where the PSF sends no light (a Dirac pattern's tails, beyond a
    streak's end) the FFT leaves noise of about 1e-8 of the peak, which counted as pixels the light reaches. Each
    plane is its own FFT, with round-off of its own size."""
    floor = FFT_ROUND_OFF * planes.abs().amax(dim=(-2, -1), keepdim=True)
    return planes.masked_fill(planes.abs() <= floor, 0.0)


def add_noise(signal: torch.Tensor, full_well_e: float, read_noise_e: float, generator: torch.Generator | None = None,
              differentiable: bool = True) -> torch.Tensor:
    """Poisson-Gaussian noise on a relative signal (1.0 = full well).

    ``differentiable``: Gaussian approximation with variance (electrons + read^2), reparameterised so
    gradients flow. Otherwise exact Poisson shot noise plus Gaussian read noise (for simulated RAW).
    """
    electrons = signal.clamp(min=0.0) * full_well_e
    read = torch.randn(signal.shape, generator=generator, dtype=signal.dtype, device=signal.device)
    if differentiable:
        noisy = electrons + torch.sqrt(electrons + read_noise_e ** 2 + _VARIANCE_FLOOR_E2) * read
    else:
        noisy = torch.poisson(electrons.detach(), generator=generator) + read_noise_e * read
    return noisy / full_well_e


def quantise(signal: torch.Tensor, levels: int) -> torch.Tensor:
    """Round to ``levels`` steps per unit (ADC); straight-through gradient."""
    return signal + (torch.round(signal * levels) / levels - signal).detach()


def bayer_mosaic(image: torch.Tensor, pattern: str = "RGGB") -> torch.Tensor:
    """Sample (..., 3, H, W) through a 2 x 2 colour filter array; returns (..., H, W)."""
    if len(pattern) != 4 or set(pattern) - set(CFA_CHANNELS):
        raise ValueError(f"unknown CFA pattern {pattern!r}")
    mosaic = torch.zeros(image.shape[:-3] + image.shape[-2:], dtype=image.dtype, device=image.device)
    for position, colour in enumerate(pattern):
        row, column = divmod(position, 2)
        mosaic[..., row::2, column::2] = image[..., CFA_CHANNELS[colour], row::2, column::2]
    return mosaic


@dataclasses.dataclass(frozen=True)
class Sensor:
    """Noise and ADC of one camera at one ISO gain (gain 1 = base ISO)."""

    full_well_e: float
    read_noise_e: float
    adc_levels: int | None  # steps between black and white level; None leaves the signal continuous
    cfa_pattern: str = "RGGB"

    @classmethod
    def from_camera(cls, camera: CameraSpec, iso_gain: float = 1.0) -> "Sensor":
        """A camera's sensor; analog gain divides the full well, read noise stays in input electrons."""
        return cls(full_well_e=camera.full_well_e / iso_gain, read_noise_e=camera.read_noise_e,
                   adc_levels=camera.white_level_dn - camera.black_level_dn, cfa_pattern=camera.cfa_pattern)

    def capture(self, irradiance: torch.Tensor, psf: torch.Tensor | None, *, exposure: float = 1.0,
                generator: torch.Generator | None = None, differentiable: bool = True,
                mosaic: bool = False) -> torch.Tensor:
        """Blur (``psf`` None = no optics), expose, mosaic (optional), add noise, clip to [0, 1], quantise."""
        signal = irradiance if psf is None else fft_convolve(irradiance, psf)
        signal = (signal * exposure).clamp(min=0.0)
        if mosaic:
            signal = bayer_mosaic(signal, self.cfa_pattern)
        signal = add_noise(signal, self.full_well_e, self.read_noise_e, generator, differentiable)
        signal = signal.clamp(0.0, 1.0)
        return quantise(signal, self.adc_levels) if self.adc_levels else signal
