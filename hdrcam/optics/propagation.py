"""Free-space propagation between parallel planes on a periodic sampled grid.

Both kernels are transfer functions (multiplications in the frequency domain), unit-modulus for
propagating waves, so energy is conserved (Parseval). The constant phase exp(j k L) is dropped: it
does not change intensities.

- Fresnel (paper Sec. 3): H(fx, fy) = exp(-j pi lambda L (fx^2 + fy^2)); separable, stored per axis.
- Angular spectrum (exact scalar): H = exp(j 2 pi L (sqrt(1/lambda^2 - f^2) - 1/lambda)), zero for
  evanescent frequencies.
"""

from __future__ import annotations

import numpy as np
import torch


def fresnel_transfer_axis(size: int, pitch_m: float, wavelength_m: float, distance_m: float) -> np.ndarray:
    """One axis of the separable Fresnel transfer function, complex128, FFT frequency order."""
    frequencies = np.fft.fftfreq(size, d=pitch_m)
    return np.exp(-1j * np.pi * wavelength_m * distance_m * frequencies ** 2)


def angular_spectrum_transfer(size: int, pitch_m: float, wavelength_m: float, distance_m: float) -> np.ndarray:
    """Exact angular-spectrum transfer function (size x size, complex128), piston removed stably."""
    frequencies = np.fft.fftfreq(size, d=pitch_m)
    squared = frequencies[:, None] ** 2 + frequencies[None, :] ** 2
    inverse_wavelength = 1.0 / wavelength_m
    propagating = squared < inverse_wavelength ** 2
    root = np.sqrt(np.where(propagating, inverse_wavelength ** 2 - squared, 0.0))
    phase = -2.0 * np.pi * distance_m * squared / (root + inverse_wavelength)  # = 2 pi L (root - 1/lambda)
    return np.where(propagating, np.exp(1j * phase), 0.0)


def propagate(field: torch.Tensor, transfer: torch.Tensor | tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
    """Propagate a complex field (..., N, N) with a 2-D transfer function or a (rows, columns) pair."""
    spectrum = torch.fft.fft2(field)
    if isinstance(transfer, tuple):
        rows, columns = transfer
        spectrum = spectrum * rows[:, None] * columns[None, :]
    else:
        spectrum = spectrum * transfer
    return torch.fft.ifft2(spectrum)
