"""The simulation grid: sample pitch and size chosen so the wave field is not aliased.

The grid pitch is the sensor pixel pitch divided by an integer ``upsample`` (REFERENCE.md Sec. 2). The thin-lens
phase k r^2 / (2 f) is sampled without aliasing only when its local frequency at the aperture edge,
D / (2 lambda f), stays below the Nyquist frequency 1 / (2 dx), i.e. D <= lambda f / dx at the shortest
simulated wavelength.

Coordinates: sensor pixel j (0..M-1) is centred at (j - M // 2) * pitch, so the optical axis is the centre
of pixel M // 2; the fine samples of a pixel are spread symmetrically about its centre.

A PSF reaches the sensor by :meth:`SimulationGrid.integrate_pixels`, the exact area integral of the field's
intensity over each pixel. Summing the ``upsample`` x ``upsample`` point samples of a pixel instead (as this
module did until 2026-11-26) overstates the centre pixel when the diffraction spot is about a pixel wide.
Profile ``simulated`` (f/9.8, 5.97 um pixels), clear aperture, centre pixel of the 31 px crop (R/G/B, pixel
(15, 15) of ``hdrcam psf --profile simulated --doe none --psf-size 31 --upsample N``), against the Airy
pattern integrated over the pixel, 0.4925/0.6023/0.7238 (61 x 61 points):

  upsample     point samples: centre pixel, against Airy    exact integral: centre pixel
  2 (default)  0.5290/0.6583/0.8008  +7.4/+9.3/+10.6 %      0.4924/0.6023/0.7237
  4            0.5010/0.6152/0.7415  +1.7/+2.1/+2.4 %       the same to 1e-4

The exact integral costs a grid twice as fine in each direction for the intensity (four times the memory of
a field): one 63 px PSF (3 wavelengths, float32, 2 cores) 0.10-0.11 s with point samples, 0.31-0.41 s now.
The networks shipped before that date were trained behind PSFs of point samples; each carries its own PSF.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from hdrcam.errors import SamplingError


def is_fast_length(n: int) -> bool:
    """True when n has no prime factor above 5 (fast for every FFT backend)."""
    for prime in (2, 3, 5):
        while n % prime == 0:
            n //= prime
    return n == 1


def max_unaliased_pitch_m(aperture_m: float, focal_length_m: float, wavelength_m: float) -> float:
    """Largest grid pitch that samples the lens phase of aperture D without aliasing: lambda f / D."""
    return wavelength_m * focal_length_m / aperture_m


@dataclasses.dataclass(frozen=True)
class SimulationGrid:
    """A square grid of ``size`` samples at ``pitch_m``, ``upsample`` samples per sensor pixel."""

    pixel_pitch_m: float
    upsample: int
    sensor_pixels: int  # M: the grid covers M x M sensor pixels
    lens_phase_aliased: bool = False  # chosen coarser than the lens phase needs (allow_aliasing)

    @property
    def pitch_m(self) -> float:
        return self.pixel_pitch_m / self.upsample

    @property
    def size(self) -> int:
        return self.sensor_pixels * self.upsample

    @property
    def width_m(self) -> float:
        return self.size * self.pitch_m

    def coordinates_m(self) -> np.ndarray:
        """Sample positions along one axis (float64, metres); the optical axis is the centre of pixel M // 2."""
        axis_index = (self.sensor_pixels // 2) * self.upsample + (self.upsample - 1) / 2.0
        return (np.arange(self.size) - axis_index) * self.pitch_m

    @classmethod
    def for_optics(cls, *, pixel_pitch_m: float, aperture_m: float, focal_length_m: float,
                   shortest_wavelength_m: float, psf_size_px: int, upsample: int | None = None,
                   allow_aliasing: bool = False) -> "SimulationGrid":
        """Choose the coarsest unaliased grid that holds the aperture and the PSF crop.

        ``upsample`` forces the samples per pixel; a value that aliases the lens phase raises
        SamplingError (or warns, with ``allow_aliasing``) and names the numbers.
        """
        limit_m = max_unaliased_pitch_m(aperture_m, focal_length_m, shortest_wavelength_m)
        needed = max(1, math.ceil(pixel_pitch_m / limit_m - 1e-9))
        chosen = needed if upsample is None else int(upsample)
        if chosen < needed:
            message = (f"grid pitch {pixel_pitch_m / chosen * 1e6:.3f} um aliases the lens phase: an aperture of "
                       f"{aperture_m * 1e3:.3f} mm at f = {focal_length_m * 1e3:.2f} mm and "
                       f"{shortest_wavelength_m * 1e9:.0f} nm needs a pitch <= {limit_m * 1e6:.3f} um "
                       f"(upsample >= {needed}), or an aperture <= "
                       f"{shortest_wavelength_m * focal_length_m * chosen / pixel_pitch_m * 1e3:.3f} mm")
            if not allow_aliasing:
                raise SamplingError(message)
            warnings.warn(message, stacklevel=2)
        pitch_m = pixel_pitch_m / chosen
        pixels = max(psf_size_px, math.ceil(aperture_m / pitch_m / chosen - 1e-9))
        while not is_fast_length(pixels * chosen):
            pixels += 1
        return cls(pixel_pitch_m=pixel_pitch_m, upsample=chosen, sensor_pixels=pixels,
                   lens_phase_aliased=chosen < needed)

    def integrate_pixels(self, field):
        """Exact pixel integrals of |u|^2 (..., M, M) for a complex field (..., N, N) on this grid, in units of |u|^2
        summed over grid samples (the totals agree: Parseval). The field is taken as its band-limited
        (trigonometric) interpolant, the one the FFT propagation computes; its intensity has twice the field's
        bandwidth, so it is formed on a grid twice as fine (zero-padded spectrum), box-filtered by the pixel
        (sinc(pixel pitch x f) per axis) and read at the pixel centres: what a sensor pixel records, the area
        integral. Summing the ``upsample`` x ``upsample`` point samples in each pixel instead (a midpoint rule)
        overstated a diffraction-limited centre pixel by 7-11 % at upsample 2 (profile ``simulated``); this agrees
        with the Airy pattern integrated over the pixel to 1e-4. Memory: four arrays of 4 N^2 complex samples.
        Works on torch tensors (and through autograd)."""
        import torch

        n, m, pixels = self.size, self.upsample, self.sensor_pixels
        spectrum = torch.fft.fft2(field)
        positive, negative = (n + 1) // 2, n // 2  # FFT order: bins 0..positive-1 >= 0, the rest < 0
        padded = spectrum.new_zeros(*spectrum.shape[:-2], 2 * n, 2 * n)
        for rows_from, rows_to, rows in ((0, 0, positive), (positive, 2 * n - negative, negative)):
            for cols_from, cols_to, cols in ((0, 0, positive), (positive, 2 * n - negative, negative)):
                padded[..., rows_to:rows_to + rows, cols_to:cols_to + cols] = \
                    spectrum[..., rows_from:rows_from + rows, cols_from:cols_from + cols]
        if n % 2 == 0:  # the Nyquist bin, shared by +n/2 and -n/2 alike (a symmetric pupil keeps a symmetric PSF),
            half = n // 2  # each with 1/sqrt(2) of it, so the intensity keeps the grid's energy (Parseval)
            padded[..., 2 * n - half, :] *= 0.5 ** 0.5
            padded[..., half, :] = padded[..., 2 * n - half, :]
            padded[..., :, 2 * n - half] *= 0.5 ** 0.5
            padded[..., :, half] = padded[..., :, 2 * n - half]
        del spectrum
        fine = torch.fft.ifft2(padded) * 4.0  # the interpolant at pitch / 2
        del padded
        intensity = fine.real ** 2 + fine.imag ** 2
        del fine
        frequencies = torch.fft.fftfreq(2 * n, d=self.pitch_m / 2.0, dtype=intensity.dtype, device=intensity.device)
        box = torch.sinc(frequencies * self.pixel_pitch_m)  # mean over a pixel-wide box, per axis
        mean = torch.fft.ifft2(torch.fft.fft2(intensity) * box[:, None] * box[None, :]).real
        centres = torch.arange(pixels, device=intensity.device) * (2 * m) + (m - 1)  # pixel centres at pitch / 2
        return mean[..., centres[:, None], centres[None, :]] * float(m * m)

    def crop_sensor(self, sensor, size_px: int):
        """Crop ``size_px`` pixels about the optical axis; the axis lands on pixel size_px // 2."""
        if size_px > self.sensor_pixels:
            raise ValueError(f"PSF crop {size_px} px exceeds the simulated field of {self.sensor_pixels} px")
        start = self.sensor_pixels // 2 - size_px // 2
        return sensor[..., start:start + size_px, start:start + size_px]
