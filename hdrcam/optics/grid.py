"""The simulation grid: sample pitch and size chosen so the wave field is not aliased.

The grid pitch is the sensor pixel pitch divided by an integer ``upsample`` so PSFs reach the sensor by
summing ``upsample x upsample`` blocks (REFERENCE.md Sec. 2). The thin-lens phase k r^2 / (2 f) is sampled
without aliasing only when its local frequency at the aperture edge, D / (2 lambda f), stays below the
Nyquist frequency 1 / (2 dx), i.e. D <= lambda f / dx at the shortest simulated wavelength.

Coordinates: sensor pixel j (0..M-1) is centred at (j - M // 2) * pitch, so the optical axis is the centre
of pixel M // 2; the fine samples of a pixel are spread symmetrically about its centre.

The coarsest unaliased grid integrates each pixel with only ``upsample`` x ``upsample`` point samples, which
overstates the centre pixel when the diffraction spot is about a pixel wide. Profile ``simulated`` (f/9.8,
5.97 um pixels), clear aperture, centre pixel of the 31 px crop (R/G/B), against the Airy pattern integrated over
the pixel (61 x 61 points) 0.4925/0.6023/0.7238, and the time of one 63 px PSF (float32, 3 wavelengths, 2 CPU
cores shared with other work, fastest of 3 runs):

  upsample     centre pixel R/G/B    against the Airy pattern   time per PSF
  2 (default)  0.5290/0.6583/0.8008  +7.4/+9.3/+10.6 %          0.48 s
  3            0.5079/0.6257/0.7560  +3.1/+3.9/+4.4 %           0.51 s
  4            0.5010/0.6152/0.7415  +1.7/+2.1/+2.4 %           0.65 s
  6            0.4962/0.6079/0.7315  +0.8/+0.9/+1.1 %           0.86 s
  8            0.4945/0.6054/0.7280  +0.4/+0.5/+0.6 %           1.58 s

Measured with ``hdrcam psf --profile simulated --doe none --psf-size 31 --upsample N`` (pixel (15, 15) of
psf.exr; float64 gives the same four digits) and, for the times, ``--psf-size`` left at 63 (single runs under
load took up to 1.6 times longer). The default stays at the coarsest grid: the shipped networks were trained
behind it.
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
        return cls(pixel_pitch_m=pixel_pitch_m, upsample=chosen, sensor_pixels=pixels)

    def bin_to_sensor(self, fine):
        """Sum upsample x upsample blocks of the last two axes (energy preserving). Works on torch tensors."""
        m, pixels = self.upsample, self.sensor_pixels
        leading = fine.shape[:-2]
        return fine.reshape(*leading, pixels, m, pixels, m).sum(dim=(-3, -1))

    def crop_sensor(self, sensor, size_px: int):
        """Crop ``size_px`` pixels about the optical axis; the axis lands on pixel size_px // 2."""
        if size_px > self.sensor_pixels:
            raise ValueError(f"PSF crop {size_px} px exceeds the simulated field of {self.sensor_pixels} px")
        start = self.sensor_pixels // 2 - size_px // 2
        return sensor[..., start:start + size_px, start:start + size_px]
