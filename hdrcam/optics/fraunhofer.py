"""Focal-plane PSF by chirp-z transforms: the paper's optics at the A7's scale, at training speed.

With the sensor at distance L behind a thin lens of focal length f and a point source at distance z, the
paraxial phases of paper Sec. 3 (spherical source wave, thin lens, Fresnel transfer-function propagation)
combine into one quadratic pupil phase k r^2 / 2 (1/z - 1/f + 1/L) and a factor exp(j k x^2 / 2L) on the
sensor that intensities do not see. The sensor field is the scaled Fourier transform of the pupil field:

  u_s(x, y) = 1 / (j lambda L) * integral of U(xi, eta) exp(-j 2 pi (x xi + y eta) / (lambda L)) dxi deta,
  U = A exp(j k (n(lambda) - 1) h) exp(j k r^2 / 2 (1/z - 1/f + 1/L)),

exactly the Fresnel model of :mod:`hdrcam.optics.psf` (which evaluates it with two FFTs on a grid fine enough
for the lens phase), without sampling the lens phase: at focus (L = the image distance of z) the quadratic
phase vanishes. The pupil is sampled on cells of side dx = feature size / ``samples_per_feature``; a field
constant over each cell has the exact transform "discrete-time Fourier transform of the cells times
sinc(x dx / lambda L) sinc(y dx / lambda L)", so the height map's features are imaged without aliasing and
without a periodic wrap-around. The transform is evaluated on ``subpixels`` x ``subpixels`` points per sensor
pixel, exactly at the pixel pitch for every wavelength, by a separable chirp-z (Bluestein) transform
(O((N + S) log(N + S)) per row), then summed to pixels.

Simplifications against the full Fresnel simulation (measured by tools/bench_fraunhofer.py): the circular
aperture edge is staircased at dx; the PSF is computed only over the S x S crop (light beyond it is counted
as lost, not wrapped); a defocused source's quadratic phase is sampled at dx and must stay below Nyquist.
Intensities are fractions of the light through the aperture (Parseval), so a crop sums to <= 1.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from scipy import fft as scipy_fft
from torch import nn

from hdrcam.errors import SamplingError
from hdrcam.optics.heightmap import HeightMap
from hdrcam.optics.materials import refractive_index

FRAUNHOFER_SUBPIXELS = 7  # points per pixel and axis: the f/5.5 centre pixel's energy within 0.3 % of 9 points


class ChirpZ(nn.Module):
    """X[k] = sum_n x[n] exp(-j 2 pi alpha (n - n0)(k - k0)), k = 0..M-1, along the last axis (Bluestein).

    With (n - n0)(k - k0) = nk - n k0 - k n0 + n0 k0 and nk = (n^2 + k^2 - (k - n)^2) / 2 the sum is a
    linear convolution with the chirp exp(j pi alpha m^2), done by FFTs of a fast length >= N + M - 1.
    Chirps are formed in float64 and stored in ``dtype``.
    """

    def __init__(self, input_length: int, output_length: int, alpha: float, input_centre: float,
                 output_centre: float, dtype: torch.dtype = torch.complex64):
        super().__init__()
        n = np.arange(input_length, dtype=np.float64)
        k = np.arange(output_length, dtype=np.float64)
        self.fft_length = scipy_fft.next_fast_len(input_length + output_length - 1)
        self.input_length, self.output_length = input_length, output_length
        pre = np.exp(2j * np.pi * alpha * (n * output_centre - n * n / 2.0))
        post = np.exp(2j * np.pi * alpha * (k * input_centre - input_centre * output_centre - k * k / 2.0))
        lags = np.arange(self.fft_length, dtype=np.float64)
        lags[lags > output_length - 1] -= self.fft_length  # m = -(N - 1) .. M - 1, stored cyclically
        chirp_spectrum = np.fft.fft(np.exp(1j * np.pi * alpha * lags * lags))
        self.register_buffer("pre", torch.from_numpy(pre).to(dtype))
        self.register_buffer("post", torch.from_numpy(post).to(dtype))
        self.register_buffer("chirp_spectrum", torch.from_numpy(chirp_spectrum).to(dtype))

    def forward(self, signal: torch.Tensor) -> torch.Tensor:
        spectrum = torch.fft.fft(signal * self.pre, n=self.fft_length, dim=-1)
        return torch.fft.ifft(spectrum * self.chirp_spectrum, dim=-1)[..., :self.output_length] * self.post


class FraunhoferPsf(nn.Module):
    """Sensor-pitch PSF crop (3, S, S) of a height map, as fractions of the light through the aperture.

    ``forward(heights_m)`` returns the band-averaged crop, the optical axis at pixel S // 2 (the convention of
    :mod:`hdrcam.optics.grid`). Geometry in metres; ``band_wavelengths_m`` one tuple of wavelengths per channel.
    """

    def __init__(self, *, aperture_m: float, feature_pitch_m: float, features: int, pixel_pitch_m: float,
                 sensor_distance_m: float, focal_length_m: float, source_distance_m: float, material: str,
                 band_wavelengths_m, psf_size_px: int, samples_per_feature: int = 1,
                 subpixels: int = FRAUNHOFER_SUBPIXELS,
                 dtype: torch.dtype = torch.float32):
        super().__init__()
        complex_dtype = {torch.float32: torch.complex64, torch.float64: torch.complex128}[dtype]
        self.dtype, self.samples_per_feature, self.subpixels = dtype, samples_per_feature, subpixels
        self.psf_size_px, self.features = psf_size_px, features
        cell_m = feature_pitch_m / samples_per_feature
        cells = features * samples_per_feature
        centre_cell = (cells - 1) / 2.0
        coordinates_m = (np.arange(cells) - centre_cell) * cell_m
        radius2_m2 = coordinates_m[:, None] ** 2 + coordinates_m[None, :] ** 2
        aperture = radius2_m2 <= (aperture_m / 2.0) ** 2
        self.register_buffer("aperture", torch.from_numpy(aperture.astype(np.float64)).to(dtype))
        self.aperture_cells = float(aperture.sum())
        curvature_per_m = (0.0 if math.isinf(source_distance_m) else 1.0 / source_distance_m) \
            - 1.0 / focal_length_m + 1.0 / sensor_distance_m
        sample_m = pixel_pitch_m / subpixels
        output_length = psf_size_px * subpixels
        output_centre = (psf_size_px // 2) * subpixels + (subpixels - 1) / 2.0
        offsets_m = (np.arange(output_length) - output_centre) * sample_m
        self.wavelengths_m = [float(w) for band in band_wavelengths_m for w in band]
        self.band_of_wavelength = [b for b, band in enumerate(band_wavelengths_m) for _ in band]
        self.band_sizes = [len(band) for band in band_wavelengths_m]
        transforms, defocus, envelopes, phase_per_height = [], [], [], []
        for wavelength_m in self.wavelengths_m:
            scale_m = wavelength_m * sensor_distance_m
            _check_defocus_sampling(curvature_per_m, aperture_m, cell_m, wavelength_m)
            transforms.append(ChirpZ(cells, output_length, cell_m * sample_m / scale_m, centre_cell,
                                     output_centre, complex_dtype))
            phase = np.pi / wavelength_m * curvature_per_m * radius2_m2
            defocus.append(np.exp(1j * phase))
            # |sinc|^2 of the cell (exact transform of a piecewise-constant field) times the Parseval scale,
            # so sum |transform|^2 * envelope over all sensor points equals the energy through the aperture.
            sinc = np.sinc(offsets_m * cell_m / scale_m)
            envelopes.append((sinc[:, None] * sinc[None, :]) ** 2 * (cell_m * sample_m / scale_m) ** 2)
            phase_per_height.append(2.0 * np.pi / wavelength_m * (float(refractive_index(material, wavelength_m)) - 1.0))
        self.transforms = nn.ModuleList(transforms)
        self.register_buffer("defocus", torch.from_numpy(np.stack(defocus)).to(complex_dtype))
        self.register_buffer("envelope", torch.from_numpy(np.stack(envelopes)).to(dtype))
        self.register_buffer("phase_per_height", torch.tensor(phase_per_height, dtype=dtype))

    def _cells(self, heights_m: torch.Tensor) -> torch.Tensor:
        if heights_m.shape != (self.features, self.features):
            raise ValueError(f"height map {tuple(heights_m.shape)} does not match {self.features} features")
        repeat = self.samples_per_feature
        return heights_m.to(self.dtype).repeat_interleave(repeat, 0).repeat_interleave(repeat, 1)

    def wavelength_intensity(self, index: int, heights_m: torch.Tensor) -> torch.Tensor:
        """|u_s|^2 on the sub-pixel grid (S k x S k) for wavelength ``index``, fraction of the aperture's light."""
        field = torch.polar(self.aperture, self._cells(heights_m) * self.phase_per_height[index])
        field = field * self.defocus[index]
        transform = self.transforms[index]
        rows = transform(field)  # transform along x for every row
        both = transform(rows.transpose(0, 1)).transpose(0, 1)  # then along y
        return (both.real ** 2 + both.imag ** 2) * self.envelope[index] / self.aperture_cells

    def forward(self, heights_m: torch.Tensor) -> torch.Tensor:
        bands = [None, None, None]
        k, size = self.subpixels, self.psf_size_px
        for index, band in enumerate(self.band_of_wavelength):
            fine = self.wavelength_intensity(index, heights_m)
            binned = fine.reshape(size, k, size, k).sum(dim=(1, 3)) / self.band_sizes[band]
            bands[band] = binned if bands[band] is None else bands[band] + binned
        return torch.stack(bands)


def _check_defocus_sampling(curvature_per_m: float, aperture_m: float, cell_m: float, wavelength_m: float) -> None:
    """Refuse a defocus phase k r^2 c / 2 whose local frequency at the aperture edge exceeds Nyquist."""
    edge_frequency = abs(curvature_per_m) * (aperture_m / 2.0) / wavelength_m  # cycles per metre
    if edge_frequency > 1.0 / (2.0 * cell_m):
        raise SamplingError(
            f"defocus of {curvature_per_m:.4g} 1/m aliases on {cell_m * 1e6:.3g} um pupil cells at "
            f"{wavelength_m * 1e9:.0f} nm; bring the source nearer the focus distance or use more samples per feature")


def fraunhofer_for(setup, heightmap: HeightMap, *, samples_per_feature: int = 1, subpixels: int = FRAUNHOFER_SUBPIXELS,
                   dtype: torch.dtype = torch.float32) -> FraunhoferPsf:
    """The focal-plane PSF model of an :class:`hdrcam.optics.psf.OpticalSetup` and its height map's grid."""
    features = heightmap().shape[0]
    return FraunhoferPsf(aperture_m=setup.aperture_m, feature_pitch_m=heightmap.feature_pitch_m, features=features,
                         pixel_pitch_m=setup.pixel_pitch_m, sensor_distance_m=setup.sensor_distance_m,
                         focal_length_m=setup.focal_length_m, source_distance_m=setup.source_distance_m,
                         material=setup.material, band_wavelengths_m=setup.band_wavelengths_m,
                         psf_size_px=setup.psf_size_px, samples_per_feature=samples_per_feature,
                         subpixels=subpixels, dtype=dtype)
