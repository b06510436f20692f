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
without a periodic wrap-around. The circular aperture and a defocus phase are not constant over a cell:
:func:`samples_per_feature_for` splits features until the aperture spans ``MIN_APERTURE_CELLS`` cells and the
defocus phase steps by at most ``MAX_DEFOCUS_STEP_RAD`` from cell to cell at the aperture edge. The transform
is evaluated on ``subpixels`` x ``subpixels`` points per sensor pixel, exactly at the pixel pitch for every
wavelength, by a separable chirp-z (Bluestein) transform (O((N + S) log(N + S)) per row), then summed to pixels.

Simplifications against the full Fresnel simulation (measured by tools/bench_fraunhofer.py): the circular
aperture edge is staircased at dx; the PSF is computed only over the S x S crop (light beyond it is counted
as lost, not wrapped); a defocused source's quadratic phase is held constant over each cell, which moves a
fraction of about (edge step)^2 / 24 of the light into replicas lambda L / dx apart.
Intensities are fractions of the light through the aperture (Parseval), so a crop sums to <= 1.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from scipy import fft as scipy_fft
from torch import nn

from hdrcam.errors import SamplingError
from hdrcam.limits import check_memory
from hdrcam.optics.heightmap import HeightMap
from hdrcam.optics.materials import refractive_index

FRAUNHOFER_SUBPIXELS = 7  # points per pixel and axis: the f/5.5 centre pixel's energy within 0.3 % of 9 points
# Cells across the aperture diameter. A clear aperture on the simulated profile (2.048 mm, f/9.8), green centre
# pixel at 7 points per pixel: 0.6114 on 32 cells, 0.6086 on 64, 0.6074 on 128, 0.6065 on 256, 0.6064 on 512
# (= the Airy pattern at the same 7 points); a 1 x 1-feature map on its own single cell gave 0.673.
MIN_APERTURE_CELLS = 128
# Defocus phase step from cell to cell at the aperture edge (radians, at the shortest wavelength). A step of phi
# moves about phi^2 / 24 of the light into replicas. Simulated profile, source at 0.25 m, green (550 nm) energy
# within 25 px: 0.9124 at a 1.42 rad step (one cell per 32 um feature), 0.9806 at 0.47 rad, 0.9865 at 0.28 rad
# (5 cells per feature, what this bound picks), 0.9895 at 0.09 rad; the Fresnel grid at 4 and 8 samples per pixel
# and the Fresnel-Hankel integral give 0.9898. At the bound the shortest wavelength loses <= 0.6 %.
MAX_DEFOCUS_STEP_RAD = math.pi / 8


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
        output_length = psf_size_px * subpixels
        self.wavelengths_m = [float(w) for band in band_wavelengths_m for w in band]
        curvature_per_m = defocus_curvature_per_m(source_distance_m, focal_length_m, sensor_distance_m)
        _check_defocus_sampling(curvature_per_m, aperture_m, cell_m, min(self.wavelengths_m))
        check_memory(f"a chirp-z PSF of {len(self.wavelengths_m)} wavelengths on {cells} x {cells} pupil cells "
                     f"({samples_per_feature} per {feature_pitch_m * 1e6:.3g} um feature) and {psf_size_px} px at "
                     f"{subpixels} points per pixel",
                     fraunhofer_memory_bytes(cells, output_length, len(self.wavelengths_m), dtype),
                     "use fewer --wavelengths-per-band or a smaller --psf-size, bring --depth nearer the focus "
                     "distance (a defocused source needs finer cells), or use a machine with more memory")
        centre_cell = (cells - 1) / 2.0
        coordinates_m = (np.arange(cells) - centre_cell) * cell_m
        radius2_m2 = coordinates_m[:, None] ** 2 + coordinates_m[None, :] ** 2
        aperture = radius2_m2 <= (aperture_m / 2.0) ** 2
        self.register_buffer("aperture", torch.from_numpy(aperture.astype(np.float64)).to(dtype))
        self.aperture_cells = float(aperture.sum())
        sample_m = pixel_pitch_m / subpixels
        output_centre = (psf_size_px // 2) * subpixels + (subpixels - 1) / 2.0
        offsets_m = (np.arange(output_length) - output_centre) * sample_m
        self.band_of_wavelength = [b for b, band in enumerate(band_wavelengths_m) for _ in band]
        self.band_sizes = [len(band) for band in band_wavelengths_m]
        # filled one wavelength at a time: float64 intermediates of one wavelength, never of all
        defocus = torch.empty((len(self.wavelengths_m), cells, cells), dtype=complex_dtype)
        envelope = torch.empty((len(self.wavelengths_m), output_length, output_length), dtype=dtype)
        transforms, phase_per_height = [], []
        for index, wavelength_m in enumerate(self.wavelengths_m):
            scale_m = wavelength_m * sensor_distance_m
            transforms.append(ChirpZ(cells, output_length, cell_m * sample_m / scale_m, centre_cell,
                                     output_centre, complex_dtype))
            phase = np.pi / wavelength_m * curvature_per_m * radius2_m2
            defocus[index] = torch.from_numpy(np.exp(1j * phase))
            # |sinc|^2 of the cell (exact transform of a piecewise-constant field) times the Parseval scale,
            # so sum |transform|^2 * envelope over all sensor points equals the energy through the aperture.
            sinc = np.sinc(offsets_m * cell_m / scale_m)
            envelope[index] = torch.from_numpy((sinc[:, None] * sinc[None, :]) ** 2
                                               * (cell_m * sample_m / scale_m) ** 2)
            index_minus_one = float(refractive_index(material, wavelength_m)) - 1.0
            phase_per_height.append(2.0 * np.pi / wavelength_m * index_minus_one)
        self.transforms = nn.ModuleList(transforms)
        self.register_buffer("defocus", defocus)
        self.register_buffer("envelope", envelope)
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


def defocus_curvature_per_m(source_distance_m: float, focal_length_m: float, sensor_distance_m: float) -> float:
    """c = 1/z - 1/f + 1/L (1/m): the pupil phase is k r^2 c / 2; zero when the source is in focus."""
    return (0.0 if math.isinf(source_distance_m) else 1.0 / source_distance_m) \
        - 1.0 / focal_length_m + 1.0 / sensor_distance_m


def defocus_edge_step_rad(curvature_per_m: float, aperture_m: float, cell_m: float, wavelength_m: float) -> float:
    """Change of the defocus phase k r^2 c / 2 across one cell of ``cell_m`` at the aperture edge (radians)."""
    return 2.0 * math.pi / wavelength_m * abs(curvature_per_m) * (aperture_m / 2.0) * cell_m


def samples_per_feature_for(*, aperture_m: float, feature_pitch_m: float, curvature_per_m: float,
                            shortest_wavelength_m: float) -> int:
    """Cells per feature (and axis) so that the aperture spans at least ``MIN_APERTURE_CELLS`` cells and the
    defocus phase steps by at most ``MAX_DEFOCUS_STEP_RAD`` per cell at the aperture edge; 1 for the paper's
    DOE in focus (1527 features of 6 um)."""
    for_aperture = math.ceil(MIN_APERTURE_CELLS * feature_pitch_m / aperture_m - 1e-9)
    step_rad = defocus_edge_step_rad(curvature_per_m, aperture_m, feature_pitch_m, shortest_wavelength_m)
    return max(1, for_aperture, math.ceil(step_rad / MAX_DEFOCUS_STEP_RAD - 1e-9))


def fraunhofer_memory_bytes(cells: int, output_length: int, wavelengths: int, dtype: torch.dtype) -> int:
    """Peak bytes of a :class:`FraunhoferPsf` of ``cells`` pupil cells and ``output_length`` points per axis,
    built and evaluated without gradients: the buffers of every wavelength (defocus cells^2 complex, envelope
    output^2 real, three chirps), plus the larger of the float64 arrays of construction (radii, phase, its
    complex128 exponential, the envelope's outer products) and one wavelength's transform (the field twice,
    three cells x FFT-length spectra per axis, the output planes). Training keeps the transform's arrays of
    every wavelength for the backward pass, a few times more."""
    real = torch.finfo(dtype).bits // 8
    complex_ = 2 * real
    length = cells + output_length - 1
    fft = scipy_fft.next_fast_len(length) if length < 2 ** 62 else length  # past a C ssize_t: refused on any machine
    buffers = wavelengths * (complex_ * (cells ** 2 + cells + output_length + fft) + real * output_length ** 2) \
        + real * cells ** 2
    building = 49 * cells ** 2 + 24 * output_length ** 2
    transform = complex_ * (2 * cells ** 2 + cells * output_length + 3 * (cells + output_length) * fft) \
        + 4 * real * output_length ** 2
    return buffers + max(building, transform)


def _check_defocus_sampling(curvature_per_m: float, aperture_m: float, cell_m: float, wavelength_m: float) -> None:
    """Refuse a defocus phase k r^2 c / 2 whose local frequency at the aperture edge exceeds Nyquist (a step
    of pi per cell); :func:`samples_per_feature_for` keeps well below it."""
    if defocus_edge_step_rad(curvature_per_m, aperture_m, cell_m, wavelength_m) > math.pi:
        raise SamplingError(
            f"defocus of {curvature_per_m:.4g} 1/m aliases on {cell_m * 1e6:.3g} um pupil cells at "
            f"{wavelength_m * 1e9:.0f} nm; bring the source (--depth) nearer the focus distance, or use "
            "--propagation fresnel")


def fraunhofer_for(setup, heightmap: HeightMap, *, samples_per_feature: int | None = None,
                   subpixels: int = FRAUNHOFER_SUBPIXELS, dtype: torch.dtype = torch.float32) -> FraunhoferPsf:
    """The focal-plane PSF model of an :class:`hdrcam.optics.psf.OpticalSetup` and its height map's grid;
    ``samples_per_feature`` defaults to :func:`samples_per_feature_for` of the setup and the map."""
    features = heightmap().shape[0]
    if samples_per_feature is None:
        curvature_per_m = defocus_curvature_per_m(setup.source_distance_m, setup.focal_length_m,
                                                  setup.sensor_distance_m)
        samples_per_feature = samples_per_feature_for(
            aperture_m=setup.aperture_m, feature_pitch_m=heightmap.feature_pitch_m, curvature_per_m=curvature_per_m,
            shortest_wavelength_m=min(min(band) for band in setup.band_wavelengths_m))
    return FraunhoferPsf(aperture_m=setup.aperture_m, feature_pitch_m=heightmap.feature_pitch_m, features=features,
                         pixel_pitch_m=setup.pixel_pitch_m, sensor_distance_m=setup.sensor_distance_m,
                         focal_length_m=setup.focal_length_m, source_distance_m=setup.source_distance_m,
                         material=setup.material, band_wavelengths_m=setup.band_wavelengths_m,
                         psf_size_px=setup.psf_size_px, samples_per_feature=samples_per_feature,
                         subpixels=subpixels, dtype=dtype)
