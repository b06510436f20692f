"""PSF of the DOE camera: point source -> DOE -> thin lens -> sensor (paper Sec. 3, Eqs. 1, 2, 4, 5).

For each wavelength lambda (k = 2 pi / lambda):
  u-  = A0 exp(j k sqrt(r^2 + z^2))                 spherical wave from a point at distance z (Eq. 1)
  u+  = A(x, y) u- exp(j k (n(lambda) - 1) h(x, y))  DOE of height h, circular aperture A (Eq. 2)
  u_l = u+ exp(j k (f - sqrt(r^2 + f^2)))            thin lens (Eq. 4)
  u_s = F^-1{ F{u_l} H }                              propagation to the sensor at L (Eq. 5)
  p   = |u_s|^2                                       (Eq. 5), summed over pixel blocks, averaged per band.

The sensor sits at L = 1 / (1/f - 1/z_focus), where the profile's focus distance is sharp, so a source at
another depth is defocused. Model "fresnel" (the paper's) uses the paraxial forms of the source and lens
phases, k r^2 / (2 z) and -k r^2 / (2 f), with the Fresnel transfer function: the sqrt forms under a
paraxial propagator would add about one wave of spurious spherical aberration at the A7's f/5.5.
Model "angular_spectrum" uses the exact sqrt forms with the exact angular-spectrum propagator. Phases
are formed in float64 with the constant pistons k z and k f removed, then cast to the working dtype.

Model "fraunhofer" evaluates the same paraxial model as a scaled Fourier transform of the pupil by chirp-z
transforms (:mod:`hdrcam.optics.fraunhofer`): no grid fine enough for the lens phase, so the paper's 9.16 mm
aperture at 50 mm costs a second on a CPU instead of 4608^2 FFTs.

Accuracy. The grid models integrate each pixel exactly (:meth:`SimulationGrid.integrate_pixels`: the
band-limited field's intensity box-filtered by the pixel), within 1e-4 of the pixel-integrated Airy pattern on
the coarsest unaliased grid (tests/optics/test_psf_physics.py); the chirp-z model sums 7 x 7 point samples per
pixel (+0.7 % on the f/9.8 centre pixel of profile ``simulated``). Measured before the grid models integrated
pixels, when they too summed point samples: at the same 3 points per pixel the chirp-z model and the A7
profile's 4608^2 Fresnel grid agreed to 9e-6 per pixel of the light through the aperture for a clear aperture
and 8e-5 for the seeded rank1 map (``python tools/bench_fraunhofer.py --heightmap none`` or ``rank1``; 5e-5 on
the trained map of tools/results/table2); at the defaults the centre pixel of a clear aperture (R/G/B, of the
31 px crop; ``hdrcam psf --doe none --psf-size 31`` with and without ``--propagation fresnel``, pixel (15, 15)
of psf.exr, float32) was chirp-z 0.8145/0.8405/0.8463 in 1.2 s, Fresnel grid (3 point samples per pixel)
0.8387/0.8470/0.8255 in 8.4 s, the Airy pattern integrated over the pixel (61 x 61 points) 0.8090/0.8376/0.8477:
the grid's point samples were off by +0.030/+0.009/-0.022, the chirp-z's 7 by +0.006/+0.003/-0.001 (profile
``simulated``: :mod:`hdrcam.optics.grid`).

Intensities are normalised so the light through the aperture carries unit energy.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch
from torch import nn

from hdrcam.optics.energy import centre_energy_fraction
from hdrcam.optics.fraunhofer import FRAUNHOFER_SUBPIXELS, fraunhofer_for
from hdrcam.optics.grid import SimulationGrid
from hdrcam.optics.heightmap import HeightMap, feature_indices, sample_heightmap
from hdrcam.optics.materials import refractive_index
from hdrcam.optics.propagation import angular_spectrum_transfer, fresnel_transfer_axis, propagate
from hdrcam.optics.spectrum import band_wavelengths_m
from hdrcam.errors import InputError, SamplingError, TooLargeError
from hdrcam.limits import check_memory
from hdrcam.profiles import Profile, image_distance_m

_COMPLEX = {torch.float32: torch.complex64, torch.float64: torch.complex128}
WAVE_BYTES_PER_SAMPLE = 450  # fields, phases and FFT buffers of one wavelength, per grid sample: the exact pixel
# integrals work on a grid twice as fine (SimulationGrid.integrate_pixels). Peak RSS over the set-up for a 1024^2
# grid (profile simulated, --psf-size 511): 344 float64 forward (hdrcam psf), 386 float32 with gradients (design);
# float64 with gradients, which no command runs, 755
MIN_WAVELENGTH_STEP_M = 0.1e-9


@dataclasses.dataclass
class PsfResult:
    """Sensor-pitch PSF (3 x S x S, each channel sums to 1, axis at pixel S // 2) and energy bookkeeping."""

    psf: torch.Tensor
    centre_energy_fraction: torch.Tensor  # (3,) energy in the centre box / all energy reaching the sensor
    crop_energy_fraction: torch.Tensor  # (3,) energy in the S x S crop / all energy reaching the sensor


@dataclasses.dataclass(frozen=True)
class OpticalSetup:
    """Geometry and sampling of one simulation (metres). ``grid`` is None for the "fraunhofer" model, which
    samples the pupil on cells of the DOE's features (:func:`hdrcam.optics.fraunhofer.samples_per_feature_for`)
    instead of a lens-phase grid."""

    grid: SimulationGrid | None
    pixel_pitch_m: float
    aperture_m: float
    focal_length_m: float
    sensor_distance_m: float
    source_distance_m: float
    material: str
    propagation: str
    band_wavelengths_m: tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]
    psf_size_px: int
    energy_centre_radius_px: int

    @classmethod
    def from_profile(cls, profile: Profile, *, source_distance_m: float | None = None,
                     wavelengths_per_band: int | None = None, psf_size_px: int | None = None,
                     upsample: int | None = None, allow_aliasing: bool = False) -> "OpticalSetup":
        simulation = profile.simulation
        samples = wavelengths_per_band or simulation.wavelengths_per_band
        check_wavelength_samples(samples, simulation.band_edges_m)
        bands = tuple(tuple(float(w) for w in band_wavelengths_m(edges, samples)) for edges in simulation.band_edges_m)
        size = psf_size_px or simulation.psf_size_px
        if size < 2 * simulation.energy_centre_radius_px + 1:
            raise InputError(f"PSF size {size} px: smaller than the {2 * simulation.energy_centre_radius_px + 1} px "
                             f"centre whose energy {profile.name} reports and constrains (energy_centre_radius_px "
                             f"{simulation.energy_centre_radius_px}); use a larger --psf-size")
        if simulation.propagation == "fraunhofer" and upsample is not None:
            raise InputError(f"upsample {upsample}: samples per pixel set the grid of the fresnel and "
                             f"angular_spectrum propagations; {profile.name}'s chirp-z (fraunhofer) propagation "
                             f"always takes {FRAUNHOFER_SUBPIXELS} points per pixel (`hdrcam psf --propagation "
                             "fresnel` sets them)")
        grid = None if simulation.propagation == "fraunhofer" else SimulationGrid.for_optics(
            pixel_pitch_m=profile.camera.pixel_pitch_m, aperture_m=profile.doe.aperture_m,
            focal_length_m=profile.lens.focal_length_m, shortest_wavelength_m=min(min(b) for b in bands),
            psf_size_px=size, upsample=upsample, allow_aliasing=allow_aliasing)
        if grid is not None:  # the chirp-z model checks its own buffers, which depend on the height map's cells
            check_memory(f"a {grid.size} x {grid.size} wave simulation ({size} px PSF, {grid.upsample} samples per "
                         "pixel)", grid.size ** 2 * WAVE_BYTES_PER_SAMPLE,
                         "use a smaller --psf-size or --upsample, or a machine with more memory")
        return cls(grid=grid, pixel_pitch_m=profile.camera.pixel_pitch_m, aperture_m=profile.doe.aperture_m,
                   focal_length_m=profile.lens.focal_length_m,
                   sensor_distance_m=profile.sensor_distance_m,
                   source_distance_m=source_distance_m or profile.calibration.point_source_distance_m,
                   material=profile.doe.material, propagation=simulation.propagation, band_wavelengths_m=bands,
                   psf_size_px=size, energy_centre_radius_px=simulation.energy_centre_radius_px)

    @property
    def in_focus_distance_m(self) -> float:
        """Where the source itself would focus (thin lens); equals sensor_distance_m when in focus."""
        return image_distance_m(self.focal_length_m, self.source_distance_m)


def check_wavelength_samples(samples: int, band_edges_m) -> None:
    """Refuse more wavelengths per band than one per ``MIN_WAVELENGTH_STEP_M`` of the widest band: finer
    sampling changes nothing a 3-channel sensor sees, and each sample is a full wave simulation."""
    widest_m = max(longest - shortest for shortest, longest in band_edges_m)
    most = max(1, round(widest_m / MIN_WAVELENGTH_STEP_M))
    if samples > most:
        raise TooLargeError(f"{samples} wavelengths per band: at most {most} (one per "
                            f"{MIN_WAVELENGTH_STEP_M * 1e9:g} nm of the {widest_m * 1e9:g} nm band); each one is a "
                            "full wave simulation")


def check_features_resolved(feature_pitch_m: float, grid: SimulationGrid, propagation: str) -> None:
    """Refuse height-map features finer than the grid pitch: the grid picks one feature per sample (nearest
    neighbour), so finer relief would alias into false orders. A relative 1e-6 tolerates float32 pitches."""
    if feature_pitch_m < grid.pitch_m * (1.0 - 1e-6):
        needed = math.ceil(grid.pixel_pitch_m / feature_pitch_m * (1.0 - 1e-6))
        raise SamplingError(f"height-map features of {feature_pitch_m * 1e6:.4g} um are finer than the "
                            f"{grid.pitch_m * 1e6:.4g} um grid of the {propagation} propagation "
                            f"({grid.upsample} samples per {grid.pixel_pitch_m * 1e6:.4g} um pixel) and would alias; "
                            f"simulate it with `hdrcam psf --upsample {needed}` or more, or with the chirp-z model "
                            "(--propagation fraunhofer, or propagation = \"fraunhofer\" in the profile)")


def source_lens_phase_rad(radius2_m2: np.ndarray, wavelength_m: float, source_distance_m: float,
                          focal_length_m: float, exact: bool) -> np.ndarray:
    """Phase of the source wave times the lens (float64, pistons removed), at squared radius r^2."""
    k = 2.0 * np.pi / wavelength_m
    if exact:  # k (sqrt(r^2 + z^2) - z) - k (sqrt(r^2 + f^2) - f), written without cancellation
        source = 0.0 if math.isinf(source_distance_m) else radius2_m2 / (
            np.sqrt(radius2_m2 + source_distance_m ** 2) + source_distance_m)
        lens = radius2_m2 / (np.sqrt(radius2_m2 + focal_length_m ** 2) + focal_length_m)
        return k * (source - lens)
    curvature = (0.0 if math.isinf(source_distance_m) else 1.0 / source_distance_m) - 1.0 / focal_length_m
    return k * radius2_m2 * curvature / 2.0


class PsfSimulator(nn.Module):
    """Differentiable PSF of ``heightmap`` in ``setup``; ``forward()`` returns a :class:`PsfResult`."""

    def __init__(self, setup: OpticalSetup, heightmap: HeightMap, dtype: torch.dtype = torch.float32):
        super().__init__()
        self.setup, self.heightmap, self.dtype = setup, heightmap, dtype
        if setup.propagation == "fraunhofer":
            self.fraunhofer = fraunhofer_for(setup, heightmap, dtype=dtype)
            return
        grid = setup.grid
        check_features_resolved(heightmap.feature_pitch_m, grid, setup.propagation)
        coordinates = grid.coordinates_m()
        self._coordinates_m = coordinates
        radius2 = coordinates[:, None] ** 2 + coordinates[None, :] ** 2
        aperture = (radius2 <= (setup.aperture_m / 2.0) ** 2).astype(np.float64)
        self.register_buffer("aperture", torch.from_numpy(aperture).to(dtype))
        self.input_energy = float(aperture.sum())
        features = heightmap().shape[0]
        self.register_buffer("feature_index", feature_indices(coordinates, features, heightmap.feature_pitch_m))
        self.wavelengths_m = [w for band in setup.band_wavelengths_m for w in band]
        self.band_of_wavelength = [b for b, band in enumerate(setup.band_wavelengths_m) for _ in band]
        complex_dtype = _COMPLEX[dtype]
        phase_per_height = [2 * np.pi / w * (float(refractive_index(setup.material, w)) - 1.0)
                            for w in self.wavelengths_m]
        self.register_buffer("phase_per_height", torch.tensor(phase_per_height, dtype=dtype))
        if setup.propagation == "fresnel":  # separable pupil phase and transfer function, one axis each
            pupil = [np.exp(1j * source_lens_phase_rad(coordinates ** 2, w, setup.source_distance_m,
                                                       setup.focal_length_m, exact=False))
                     for w in self.wavelengths_m]
            transfer = [fresnel_transfer_axis(grid.size, grid.pitch_m, w, setup.sensor_distance_m)
                        for w in self.wavelengths_m]
            self.register_buffer("pupil_axis", torch.from_numpy(np.stack(pupil)).to(complex_dtype))
            self.register_buffer("transfer_axis", torch.from_numpy(np.stack(transfer)).to(complex_dtype))
        elif setup.propagation != "angular_spectrum":
            raise ValueError(f"unknown propagation model {setup.propagation!r}")

    def _pupil_and_transfer(self, index: int):
        if self.setup.propagation == "fresnel":
            pupil = self.pupil_axis[index]
            transfer = self.transfer_axis[index]
            return pupil[:, None] * pupil[None, :], (transfer, transfer)
        wavelength, grid = self.wavelengths_m[index], self.setup.grid
        radius2 = self._coordinates_m[:, None] ** 2 + self._coordinates_m[None, :] ** 2
        phase = source_lens_phase_rad(radius2, wavelength, self.setup.source_distance_m,
                                      self.setup.focal_length_m, exact=True)
        device, complex_dtype = self.aperture.device, _COMPLEX[self.dtype]
        pupil = torch.from_numpy(np.exp(1j * phase)).to(device=device, dtype=complex_dtype)
        transfer = angular_spectrum_transfer(grid.size, grid.pitch_m, wavelength, self.setup.sensor_distance_m)
        return pupil, torch.from_numpy(transfer).to(device=device, dtype=complex_dtype)

    def doe_field(self, index: int, heights_m: torch.Tensor | None = None) -> torch.Tensor:
        """Complex field right behind the lens for wavelength ``index`` (N x N)."""
        pupil, _ = self._pupil_and_transfer(index)
        return self._field_behind_lens(index, heights_m, pupil)

    def _field_behind_lens(self, index: int, heights_m: torch.Tensor | None, pupil: torch.Tensor) -> torch.Tensor:
        heights = self.heightmap() if heights_m is None else heights_m
        fine_heights = sample_heightmap(heights.to(self.dtype), self.feature_index)
        return torch.polar(self.aperture, fine_heights * self.phase_per_height[index]) * pupil

    def sensor_field(self, index: int, heights_m: torch.Tensor | None = None) -> torch.Tensor:
        """Complex field u_s on the fine grid for wavelength ``index``, unnormalised."""
        pupil, transfer = self._pupil_and_transfer(index)
        return propagate(self._field_behind_lens(index, heights_m, pupil), transfer)

    def fine_intensity(self, index: int, heights_m: torch.Tensor | None = None) -> torch.Tensor:
        """|u_s|^2 on the fine grid for wavelength ``index``; sums to 1 when nothing is evanescent."""
        field = self.sensor_field(index, heights_m)
        return (field.real ** 2 + field.imag ** 2) / self.input_energy

    def sensor_psf_uncropped(self, heights_m: torch.Tensor | None = None) -> torch.Tensor:
        """Band-averaged PSF summed to the sensor pitch over the whole grid (3 x M x M), unnormalised."""
        heights = self.heightmap() if heights_m is None else heights_m
        grid = self.setup.grid
        bands = [None, None, None]
        counts = [len(band) for band in self.setup.band_wavelengths_m]
        for index, band in enumerate(self.band_of_wavelength):
            # exact pixel integrals of the intensity, not upsample x upsample point samples per pixel
            binned = grid.integrate_pixels(self.sensor_field(index, heights)) / (self.input_energy * counts[band])
            bands[band] = binned if bands[band] is None else bands[band] + binned
        return torch.stack(bands)

    def forward(self, heights_m: torch.Tensor | None = None) -> PsfResult:
        """The PSF of the module's height map, or of ``heights_m`` on the same feature grid."""
        if self.setup.propagation == "fraunhofer":  # the crop, in fractions of the light through the aperture
            crop = self.fraunhofer(self.heightmap() if heights_m is None else heights_m)
            crop_energy = crop.sum(dim=(-2, -1))
            centre = centre_energy_fraction(crop, self.setup.energy_centre_radius_px) * crop_energy
            return PsfResult(psf=crop / crop_energy[:, None, None], centre_energy_fraction=centre,
                             crop_energy_fraction=crop_energy)
        full = self.sensor_psf_uncropped(heights_m)
        total = full.sum(dim=(-2, -1))
        grid, size = self.setup.grid, self.setup.psf_size_px
        crop = grid.crop_sensor(full, size)
        crop_energy = crop.sum(dim=(-2, -1))
        return PsfResult(psf=crop / crop_energy[:, None, None],
                         centre_energy_fraction=centre_energy_fraction(full, self.setup.energy_centre_radius_px),
                         crop_energy_fraction=crop_energy / total)
