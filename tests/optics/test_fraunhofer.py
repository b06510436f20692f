"""The chirp-z focal-plane model against analytic optics and against the Fresnel grid simulation."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.special
import torch

from hdrcam.optics.fraunhofer import FraunhoferPsf
from hdrcam.optics.heightmap import Rank1HeightMap
from hdrcam.optics.materials import refractive_index
from hdrcam.optics.psf import PsfSimulator
from hdrcam.profiles import image_distance_m
from tests.optics.helpers import single_wavelength_setup

WAVELENGTH_M = 550e-9
FOCAL_M = 50e-3
SENSOR_M = image_distance_m(FOCAL_M, 5.0)
PHASE_PER_HEIGHT = 2 * np.pi / WAVELENGTH_M * (float(refractive_index("fused_silica", WAVELENGTH_M)) - 1)


def _model(*, aperture_m, feature_m, features, psf_size_px, subpixels=1, samples_per_feature=1,
           source_distance_m=5.0, pixel_pitch_m=5.97e-6):
    return FraunhoferPsf(aperture_m=aperture_m, feature_pitch_m=feature_m, features=features,
                         pixel_pitch_m=pixel_pitch_m, sensor_distance_m=SENSOR_M, focal_length_m=FOCAL_M,
                         source_distance_m=source_distance_m, material="fused_silica",
                         band_wavelengths_m=((WAVELENGTH_M,),) * 3, psf_size_px=psf_size_px,
                         samples_per_feature=samples_per_feature, subpixels=subpixels, dtype=torch.float64)


def test_clear_aperture_first_dark_ring_at_airy_radius():
    aperture_m, feature_m = 1e-3, 10e-6
    features = 100
    model = _model(aperture_m=aperture_m, feature_m=feature_m, features=features, psf_size_px=61, subpixels=4)
    with torch.no_grad():
        fine = model.wavelength_intensity(0, torch.zeros(features, features, dtype=torch.float64)).numpy()
    centre = (61 // 2) * 4 + 1.5  # sub-pixel sample grid: the axis lies between samples 121 and 122
    row = fine[int(centre)]  # 0.5 sample off the axis: the ring radius is measured along this row
    index = next(i for i in range(int(centre) + 2, len(row) - 1) if row[i] <= row[i - 1] and row[i] < row[i + 1])
    left, middle, right = row[index - 1:index + 2]
    minimum = index + 0.5 * (left - right) / (left - 2 * middle + right)
    sample_m = 5.97e-6 / 4
    radius_m = np.hypot(minimum - centre, 0.5) * sample_m
    assert radius_m == pytest.approx(1.22 * WAVELENGTH_M * SENSOR_M / aperture_m, rel=0.01)


@pytest.mark.parametrize("phase_rad", [np.pi / 2, np.pi])
def test_binary_phase_grating_orders_at_the_paper_scale(phase_rad):
    """A 0 / phi grating of period 8 features (48 um) on the paper's 9.16 mm aperture: order m lands at
    m lambda L / period with efficiency cos^2(phi/2) (m = 0), (2 / m pi)^2 sin^2(phi/2) (odd m), 0 (even m)."""
    aperture_m, feature_m = 9.16e-3, 6e-6
    features = 1527
    period_features = 8
    x = np.arange(features)
    column_heights = np.where((x % period_features) < period_features // 2, 0.0, phase_rad / PHASE_PER_HEIGHT)
    heights = torch.from_numpy(np.repeat(column_heights[None, :], features, axis=0))
    psf_size = 511
    model = _model(aperture_m=aperture_m, feature_m=feature_m, features=features, psf_size_px=psf_size,
                   subpixels=7)  # the Airy core (3.7 um) is smaller than a pixel: integrate, do not point-sample
    with torch.no_grad():
        psf = model(heights)[1].numpy()
        clear = model(torch.zeros_like(heights))[1].numpy()
    spacing_px = WAVELENGTH_M * SENSOR_M / (period_features * feature_m) / 5.97e-6  # 96.7 px
    centre = psf_size // 2
    in_window = clear[centre - 6:centre + 7, centre - 6:centre + 7].sum()  # the aperture's spot, ~98 % of it
    for order in range(-2, 3):
        column = centre + order * spacing_px
        window = psf[centre - 6:centre + 7, int(round(column)) - 6:int(round(column)) + 7]
        expected = np.cos(phase_rad / 2) ** 2 if order == 0 else (
            0.0 if order % 2 == 0 else (2 / (order * np.pi)) ** 2 * np.sin(phase_rad / 2) ** 2)
        assert window.sum() == pytest.approx(expected * in_window, abs=0.003), order
        if expected > 0.01:
            peak = np.unravel_index(np.argmax(window), window.shape)
            assert peak[0] == 6 and abs(int(round(column)) - 6 + peak[1] - column) <= 0.6


def test_energy_is_conserved_over_a_wide_crop():
    """A clear 1 mm aperture: a crop of +-32 Airy radii holds all but the rings' tail, ~2 / (pi^2 32) = 0.6 %."""
    model = _model(aperture_m=1e-3, feature_m=25e-6, features=40, psf_size_px=301, subpixels=3)
    with torch.no_grad():
        crop = model(torch.zeros(40, 40, dtype=torch.float64))
    assert 0.99 < float(crop[1].sum()) <= 1.0


def test_agrees_with_the_fresnel_grid_simulation():
    """A 2 mm rank-1 DOE of 10 um features: the same PSF from a 4 mm Fresnel grid of 2 um samples (3 per pixel,
    integrated exactly over each pixel, wide enough that nothing wraps) and from chirp-z transforms of 2 um pupil
    cells (9 x 9 points per pixel: close to the exact integral)."""
    setup = single_wavelength_setup(aperture_m=2e-3, focal_length_m=FOCAL_M, pixel_pitch_m=6e-6, upsample=3,
                                    window_m=4e-3, psf_size_px=101)
    heightmap = Rank1HeightMap(200, 10e-6, 1.2e-6, seed=1, init_std=0.3, dtype=torch.float64)
    with torch.no_grad():
        fresnel = PsfSimulator(setup, heightmap, dtype=torch.float64)()
    model = FraunhoferPsf(aperture_m=2e-3, feature_pitch_m=10e-6, features=200, pixel_pitch_m=6e-6,
                          sensor_distance_m=setup.sensor_distance_m, focal_length_m=FOCAL_M, source_distance_m=5.0,
                          material="fused_silica", band_wavelengths_m=setup.band_wavelengths_m, psf_size_px=101,
                          samples_per_feature=5, subpixels=9, dtype=torch.float64)
    with torch.no_grad():
        chirp_z = model(heightmap())
    reference = fresnel.psf * fresnel.crop_energy_fraction[:, None, None]
    assert float(chirp_z.sum()) == pytest.approx(float(reference.sum()), rel=1e-3)
    assert float((chirp_z - reference).abs().max()) < 5e-3 * float(reference.max())


def test_defocus_that_aliases_is_refused():
    """With samples_per_feature given: the message names what a user can change (no option sets the cells)."""
    from hdrcam.errors import SamplingError
    with pytest.raises(SamplingError, match=r"defocus .* bring the source \(--depth\) nearer the focus distance, "
                                            r"or use --propagation fresnel$"):
        _model(aperture_m=9.16e-3, feature_m=6e-6, features=1527, psf_size_px=11, source_distance_m=0.06)


def test_samples_per_pixel_are_refused_for_chirp_z_rather_than_ignored():
    """`hdrcam psf --upsample N` on a chirp-z profile used to run with its fixed points per pixel instead."""
    from hdrcam.errors import InputError
    from hdrcam.optics.fraunhofer import FRAUNHOFER_SUBPIXELS
    from hdrcam.optics.psf import OpticalSetup
    from hdrcam.profiles import load_profile

    chirp_z = load_profile("sony-a7-zeiss50-rank1")
    assert chirp_z.simulation.propagation == "fraunhofer"
    with pytest.raises(InputError, match=f"{FRAUNHOFER_SUBPIXELS} points per pixel"):
        OpticalSetup.from_profile(chirp_z, upsample=3)
    assert OpticalSetup.from_profile(chirp_z).grid is None
    assert OpticalSetup.from_profile(load_profile("simulated"), upsample=3).grid.upsample == 3


def _simulated_chirp_z(**setup_options):
    import dataclasses

    from hdrcam.optics.psf import OpticalSetup
    from hdrcam.profiles import load_profile

    profile = load_profile("simulated")
    profile = dataclasses.replace(profile, simulation=dataclasses.replace(profile.simulation, propagation="fraunhofer"))
    return profile, OpticalSetup.from_profile(profile, **setup_options)


def _airy_pixels(setup, wavelength_m: float, points_per_pixel: int) -> np.ndarray:
    """Airy pattern of the setup's aperture, summed over points_per_pixel^2 points of each pixel, unit sum."""
    size, pitch = setup.psf_size_px, setup.pixel_pitch_m
    offsets = (np.arange(size * points_per_pixel) - (size // 2 * points_per_pixel + (points_per_pixel - 1) / 2)) \
        * pitch / points_per_pixel
    radius_m = np.hypot(offsets[:, None], offsets[None, :])
    v = np.pi * setup.aperture_m * radius_m / (wavelength_m * setup.sensor_distance_m)
    with np.errstate(invalid="ignore", divide="ignore"):
        intensity = np.where(v == 0, 1.0, (2 * scipy.special.j1(v) / v) ** 2)
    pixels = intensity.reshape(size, points_per_pixel, size, points_per_pixel).sum(axis=(1, 3))
    return pixels / pixels.sum()


@pytest.mark.parametrize("features", [1, 4])
def test_a_coarse_map_still_images_a_circular_aperture(features):
    """A clear map of 1 x 1 or 4 x 4 features on the simulated profile's 2.048 mm aperture. On one cell per
    feature the aperture was a square (1 x 1: green centre pixel 0.673) or a staircase (4 x 4: 0.582) against the
    Airy pattern's 0.606; features are now split into >= MIN_APERTURE_CELLS cells across the aperture."""
    from hdrcam.optics.fraunhofer import FRAUNHOFER_SUBPIXELS
    from hdrcam.optics.heightmap import FixedHeightMap

    _, setup = _simulated_chirp_z(psf_size_px=31)
    heightmap = FixedHeightMap(np.zeros((features, features)), setup.aperture_m / features, dtype=torch.float64)
    simulator = PsfSimulator(setup, heightmap, dtype=torch.float64)
    with torch.no_grad():
        psf = simulator().psf.numpy()
    for channel, band in enumerate(setup.band_wavelengths_m):
        airy = _airy_pixels(setup, band[0], FRAUNHOFER_SUBPIXELS)  # the same points per pixel: only the pupil differs
        assert psf[channel, 15, 15] == pytest.approx(airy[15, 15], rel=0.003), channel
        assert np.abs(psf[channel] - airy).sum() < 0.01, channel
    from hdrcam.optics.fraunhofer import MIN_APERTURE_CELLS
    assert features * simulator.fraunhofer.samples_per_feature == MIN_APERTURE_CELLS


def _defocused_energy_within(radii_m, *, aperture_m, wavelength_m, sensor_distance_m, curvature_per_m):
    """Fraction of the light of a clear circular pupil with phase pi c r^2 / lambda within each sensor radius:
    the Fresnel-Hankel transform u(rho) = 2 pi / (lambda L) int_0^R exp(j pi c r^2 / lambda) J0(2 pi r rho /
    (lambda L)) r dr, integrated by Simpson's rule (no pupil cells)."""
    def simpson(points):
        weights = np.full(points.size, 2.0)
        weights[1:-1:2], weights[0], weights[-1] = 4.0, 1.0, 1.0
        return weights * (points[1] - points[0]) / 3

    scale = wavelength_m * sensor_distance_m
    r = np.linspace(0.0, aperture_m / 2, 2001)
    pupil = np.exp(1j * np.pi * curvature_per_m * r ** 2 / wavelength_m) * r * simpson(r)
    energies = []
    for radius_m in radii_m:
        rho = np.linspace(0.0, radius_m, 3001)
        field = 2 * np.pi / scale * (scipy.special.j0(2 * np.pi * np.outer(rho, r) / scale) @ pupil)
        energies.append(float((np.abs(field) ** 2 * 2 * np.pi * rho) @ simpson(rho)) / (np.pi * (aperture_m / 2) ** 2))
    return energies


def test_a_defocused_source_puts_no_ghost_ring_around_its_blur():
    """Simulated profile, source at 0.25 m (focus at 5 m): on one 32 um cell per feature the defocus phase was a
    staircase and 4.9 % of the green light formed a ring at 40-75 px (replicas lambda L / 32 um = 58 px apart),
    leaving 0.912 within 25 px. The Fresnel-Hankel integral gives 0.990 within 25 px and 0.27 % in the ring."""
    from hdrcam.optics.heightmap import flat_heightmap

    profile, setup = _simulated_chirp_z(source_distance_m=0.25, psf_size_px=161)
    simulator = PsfSimulator(setup, flat_heightmap(setup.aperture_m, profile.doe.feature_size_m, torch.float64),
                             dtype=torch.float64)
    curvature = 1 / 0.25 - 1 / setup.focal_length_m + 1 / setup.sensor_distance_m
    with torch.no_grad():
        result = simulator()
    green = (result.psf * result.crop_energy_fraction[:, None, None])[1].numpy()
    offsets = np.arange(161) - 80
    radius_px = np.hypot(offsets[:, None], offsets[None, :])
    pitch = setup.pixel_pitch_m
    within_25, within_40, within_75 = _defocused_energy_within(
        [25 * pitch, 40 * pitch, 75 * pitch], aperture_m=setup.aperture_m, wavelength_m=550e-9,
        sensor_distance_m=setup.sensor_distance_m, curvature_per_m=curvature)
    assert green[radius_px < 25].sum() == pytest.approx(within_25, abs=0.005)  # <= MAX_DEFOCUS_STEP_RAD^2 / 24
    assert green[(radius_px > 40) & (radius_px < 75)].sum() == pytest.approx(within_75 - within_40, abs=0.001)
    from hdrcam.optics.fraunhofer import MAX_DEFOCUS_STEP_RAD, defocus_edge_step_rad
    cell_m = profile.doe.feature_size_m / simulator.fraunhofer.samples_per_feature
    assert defocus_edge_step_rad(curvature, setup.aperture_m, cell_m, 450e-9) <= MAX_DEFOCUS_STEP_RAD


def test_the_a7_profile_in_focus_keeps_one_cell_per_feature():
    """Its 1527 features of 6 um already span the aperture and the defocus phase is zero: the PSF the shipped
    networks were trained behind is unchanged."""
    from hdrcam.optics.fraunhofer import defocus_curvature_per_m, samples_per_feature_for
    from hdrcam.optics.psf import OpticalSetup
    from hdrcam.profiles import load_profile

    profile = load_profile("sony-a7-zeiss50-rank1")
    setup = OpticalSetup.from_profile(profile)
    curvature = defocus_curvature_per_m(setup.source_distance_m, setup.focal_length_m, setup.sensor_distance_m)
    assert samples_per_feature_for(aperture_m=setup.aperture_m, feature_pitch_m=profile.doe.feature_size_m,
                                   curvature_per_m=curvature, shortest_wavelength_m=450e-9) == 1
    assert samples_per_feature_for(aperture_m=setup.aperture_m, feature_pitch_m=profile.doe.feature_size_m,
                                   curvature_per_m=defocus_curvature_per_m(0.5, setup.focal_length_m,
                                                                           setup.sensor_distance_m),
                                   shortest_wavelength_m=450e-9) == 2  # 0.69 rad per 6 um cell at 450 nm


def test_memory_is_checked_for_every_wavelength_before_allocating(monkeypatch):
    """`hdrcam psf --wavelengths-per-band 30` passed a check of one wavelength's crop and failed at 4.3 GB: each
    wavelength holds a cells^2 defocus and a crop^2 envelope. A defocus that needs a huge pupil is refused the same
    way (A7 at 0.06 m: 17 cells per feature, 25959^2 cells)."""
    from hdrcam import limits
    from hdrcam.errors import TooLargeError
    from hdrcam.optics.heightmap import flat_heightmap
    from hdrcam.optics.psf import OpticalSetup
    from hdrcam.profiles import load_profile

    profile, many = _simulated_chirp_z(wavelengths_per_band=30)
    heightmap = flat_heightmap(many.aperture_m, profile.doe.feature_size_m)
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 60e6)  # room for 30 wavelengths, not 90
    with pytest.raises(TooLargeError, match="90 wavelengths .* --wavelengths-per-band") as refused:
        PsfSimulator(many, heightmap)
    assert "\n" not in str(refused.value)
    a7 = load_profile("sony-a7-zeiss50-rank1")
    with pytest.raises(TooLargeError, match=r"25959 x 25959 pupil cells \(17 per 6 um feature\).* --depth"):
        PsfSimulator(OpticalSetup.from_profile(a7, source_distance_m=0.06), flat_heightmap(9.16e-3, 6e-6))

    from hdrcam.optics.fraunhofer import fraunhofer_memory_bytes
    monkeypatch.undo()
    _, setup = _simulated_chirp_z(wavelengths_per_band=10)
    model = PsfSimulator(setup, heightmap).fraunhofer
    held = sum(buffer.numel() * buffer.element_size() for buffer in model.buffers())
    cells, crop = 64 * model.samples_per_feature, setup.psf_size_px * model.subpixels
    estimate = fraunhofer_memory_bytes(cells, crop, 30, torch.float32)
    assert held < estimate < 60e6 < fraunhofer_memory_bytes(cells, crop, 90, torch.float32)
    assert estimate < 2 * held + fraunhofer_memory_bytes(cells, crop, 1, torch.float32)
