"""The wave model against analytic optics: Airy pattern, phase-grating orders, defocus, energy."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.special
import torch

from hdrcam.optics.heightmap import FixedHeightMap, Rank1HeightMap, flat_heightmap
from hdrcam.optics.materials import refractive_index
from hdrcam.optics.psf import PsfSimulator
from tests.optics.helpers import single_wavelength_setup


def _axis_index(grid) -> int:
    return int(np.argmin(np.abs(grid.coordinates_m())))


def _first_dark_ring_m(intensity: np.ndarray, grid) -> float:
    """First minimum of the profile along +x through the axis, refined by a parabola."""
    centre = _axis_index(grid)
    profile = intensity[centre, centre:].astype(np.float64)
    index = next(i for i in range(1, len(profile) - 1) if profile[i] <= profile[i - 1] and profile[i] < profile[i + 1])
    left, middle, right = profile[index - 1:index + 2]
    offset = 0.5 * (left - right) / (left - 2 * middle + right)
    return (index + offset) * grid.pitch_m


@pytest.mark.parametrize("propagation", ["fresnel", "angular_spectrum"])
def test_clear_aperture_first_dark_ring_at_airy_radius(propagation):
    setup = single_wavelength_setup(aperture_m=1e-3, focal_length_m=50e-3, propagation=propagation)
    simulator = PsfSimulator(setup, flat_heightmap(setup.aperture_m, 10e-6), dtype=torch.float64)
    with torch.no_grad():
        intensity = simulator.fine_intensity(0).numpy()
    expected = 1.22 * 550e-9 * setup.sensor_distance_m / setup.aperture_m
    assert _first_dark_ring_m(intensity, setup.grid) == pytest.approx(expected, rel=0.02)
    # the peak sits on the optical axis
    assert np.unravel_index(np.argmax(intensity), intensity.shape) == (_axis_index(setup.grid),) * 2


def test_sinusoidal_phase_grating_orders_follow_bessel_functions():
    wavelength, period, phase_amplitude = 550e-9, 50e-6, 1.2
    setup = single_wavelength_setup(aperture_m=1e-3, focal_length_m=50e-3, upsample=3, window_m=2.5e-3)
    feature_pitch = setup.grid.pitch_m
    features = int(np.ceil(setup.aperture_m / feature_pitch)) + 2
    x = (np.arange(features) - features / 2) * feature_pitch
    phase_per_height = 2 * np.pi / wavelength * (float(refractive_index("fused_silica", wavelength)) - 1)
    amplitude_m = phase_amplitude / phase_per_height
    heights = np.repeat((amplitude_m * (1 + np.sin(2 * np.pi * x / period)))[None, :], features, axis=0)
    simulator = PsfSimulator(setup, FixedHeightMap(heights, feature_pitch, dtype=torch.float64), dtype=torch.float64)
    with torch.no_grad():
        intensity = simulator.fine_intensity(0).numpy()
    coordinates = setup.grid.coordinates_m()
    spacing = wavelength * setup.sensor_distance_m / period
    centre = _axis_index(setup.grid)
    half_window = int(spacing / setup.grid.pitch_m / 2)
    for order in (-1, 0, 1):
        column = int(np.argmin(np.abs(coordinates - order * spacing)))
        window = intensity[centre - half_window:centre + half_window, column - half_window:column + half_window]
        energy = window.sum() / intensity.sum()
        assert energy == pytest.approx(scipy.special.jv(order, phase_amplitude) ** 2, rel=0.05)
        peak_row, peak_column = np.unravel_index(np.argmax(window), window.shape)
        peak_x = coordinates[column - half_window + peak_column]
        assert peak_x == pytest.approx(order * spacing, abs=setup.grid.pitch_m)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_propagation_conserves_energy_and_pixel_integration_preserves_it(dtype):
    setup = single_wavelength_setup(aperture_m=1e-3, focal_length_m=50e-3)
    heightmap = Rank1HeightMap(50, 20e-6, 1.125e-6, seed=3, init_std=1.0, dtype=dtype)
    simulator = PsfSimulator(setup, heightmap, dtype=dtype)
    with torch.no_grad():
        field_energy = (simulator.doe_field(0).abs() ** 2).sum() / simulator.input_energy
        intensity = simulator.fine_intensity(0)
        pixels = setup.grid.integrate_pixels(simulator.sensor_field(0)) / simulator.input_energy
    assert float(field_energy) == pytest.approx(1.0, rel=1e-6)
    assert float(intensity.sum()) == pytest.approx(1.0, rel=1e-5)
    assert float(pixels.sum()) == pytest.approx(float(intensity.sum()), rel=1e-5)


def test_gradients_reach_rank1_factors_gradcheck():
    setup = single_wavelength_setup(aperture_m=80e-6, focal_length_m=5e-3, pixel_pitch_m=6e-6, upsample=2,
                                    psf_size_px=5)
    heightmap = Rank1HeightMap(7, 12e-6, 1.125e-6, rank=3, seed=1, dtype=torch.float64)
    simulator = PsfSimulator(setup, heightmap, dtype=torch.float64)
    assert setup.grid.size <= 32

    def psf_of(v, q):
        return simulator.sensor_psf_uncropped(heightmap.h_max_m * torch.sigmoid(v @ q.T))

    v = heightmap.v.detach().clone().requires_grad_(True)
    q = heightmap.q.detach().clone().requires_grad_(True)
    assert torch.autograd.gradcheck(psf_of, (v, q), eps=1e-6, atol=1e-6, rtol=1e-4)


def test_forward_gradients_are_finite_and_nonzero_for_both_factors():
    setup = single_wavelength_setup(aperture_m=0.5e-3, focal_length_m=20e-3)
    heightmap = Rank1HeightMap(25, 20e-6, 1.125e-6, seed=0)
    result = PsfSimulator(setup, heightmap)()
    (result.centre_energy_fraction.mean() + result.psf[:, 0, 0].sum()).backward()
    for parameter in (heightmap.v, heightmap.q):
        assert torch.isfinite(parameter.grad).all() and parameter.grad.abs().max() > 0


def _radius_enclosing_m(intensity: np.ndarray, grid, fraction: float) -> float:
    coordinates = grid.coordinates_m()
    radius = np.hypot(coordinates[:, None], coordinates[None, :]).ravel()
    order = np.argsort(radius)
    cumulative = np.cumsum(intensity.ravel()[order])
    return float(radius[order][np.searchsorted(cumulative, fraction * cumulative[-1])])


def test_defocus_from_5m_to_1m_matches_geometric_blur_circle():
    # D = 6 mm: 6.5 waves of defocus at 550 nm, so the blur is geometric (a 3 mm pupil gives only 1.6)
    common = dict(aperture_m=6e-3, focal_length_m=50e-3, upsample=2, focus_distance_m=5.0)
    in_focus = single_wavelength_setup(source_distance_m=5.0, **common)
    near = single_wavelength_setup(source_distance_m=1.0, **common)
    radii = {}
    for name, setup in (("focus", in_focus), ("near", near)):
        simulator = PsfSimulator(setup, flat_heightmap(setup.aperture_m, 10e-6), dtype=torch.float64)
        with torch.no_grad():
            radii[name] = _radius_enclosing_m(simulator.fine_intensity(0).numpy(), setup.grid, 0.5)
    image_distance = near.in_focus_distance_m
    blur_radius = setup.aperture_m / 2 * (image_distance - near.sensor_distance_m) / image_distance
    # a uniform disk of radius R holds half its energy within R / sqrt(2)
    assert radii["near"] == pytest.approx(blur_radius / np.sqrt(2), rel=0.03)
    assert radii["focus"] < radii["near"] / 4


def test_band_psf_is_the_mean_of_its_wavelength_samples():
    import dataclasses

    from hdrcam.profiles import load_profile
    from hdrcam.optics.psf import OpticalSetup

    setup = OpticalSetup.from_profile(load_profile("simulated"), wavelengths_per_band=3)
    assert [len(band) for band in setup.band_wavelengths_m] == [3, 3, 3]
    assert setup.band_wavelengths_m[2][0] == pytest.approx(410e-9 + 80e-9 / 6)
    heightmap = Rank1HeightMap(64, 32e-6, 1.125e-6, seed=0)
    simulator = PsfSimulator(setup, heightmap)
    with torch.no_grad():
        banded = simulator.sensor_psf_uncropped()
        green = torch.stack([setup.grid.integrate_pixels(simulator.sensor_field(i)) / simulator.input_energy
                                 for i in (3, 4, 5)]).mean(0)
        one_sample = PsfSimulator(dataclasses.replace(setup, band_wavelengths_m=((650e-9,), (550e-9,), (450e-9,))),
                                  heightmap).sensor_psf_uncropped()
    torch.testing.assert_close(banded[1], green)
    assert float((banded - one_sample).abs().sum()) > 1e-3  # the band integral differs from the narrow-band model


@pytest.mark.parametrize("propagation", ["fresnel", "angular_spectrum"])
def test_features_finer_than_the_grid_are_refused_with_the_remedies(propagation):
    """A map of 1 um features on a 2 um grid: nearest-neighbour sampling kept every other feature, and a 4 um
    blazed grating put a false order 157 px off axis on the simulated profile. --upsample 6 (1 um) is accepted,
    as is a map on exactly the grid pitch read back from a float32 EXR attribute."""
    from hdrcam.errors import SamplingError

    setup = single_wavelength_setup(aperture_m=0.2e-3, focal_length_m=5e-3, upsample=3, propagation=propagation)
    heightmap = flat_heightmap(setup.aperture_m, 1e-6)
    with pytest.raises(SamplingError, match=r"features of 1 um .* 2 um grid .* --upsample 6` or more, or .*"
                                            r"--propagation fraunhofer"):
        PsfSimulator(setup, heightmap)
    PsfSimulator(setup, flat_heightmap(setup.aperture_m, float(np.float32(setup.grid.pitch_m))))
    PsfSimulator(single_wavelength_setup(aperture_m=0.2e-3, focal_length_m=5e-3, upsample=6, propagation=propagation),
                 heightmap)


def test_the_chirp_z_remedy_images_features_finer_than_a_pixel_grid_exactly():
    """--propagation fraunhofer on the map above: a 4-level blaze of period 4 um on 1 um features, one wave deep at
    550 nm, puts sinc^2(1/4) = 0.811 of the light at x = lambda L / 4 um (688 um, 115 px), none at the axis."""
    wavelength, period_features, feature_m = 550e-9, 4, 1e-6
    setup = single_wavelength_setup(aperture_m=0.2e-3, focal_length_m=5e-3, propagation="fraunhofer",
                                    psf_size_px=301)
    phase_per_height = 2 * np.pi / wavelength * (float(refractive_index("fused_silica", wavelength)) - 1)
    features = 200
    levels = np.arange(features) % period_features
    heights = np.repeat((levels / period_features * 2 * np.pi / phase_per_height)[None, :], features, axis=0)
    with torch.no_grad():
        blazed = PsfSimulator(setup, FixedHeightMap(heights, feature_m, dtype=torch.float64), dtype=torch.float64)()
        clear = PsfSimulator(setup, flat_heightmap(setup.aperture_m, feature_m, dtype=torch.float64),
                             dtype=torch.float64)()
    grating = (blazed.psf * blazed.crop_energy_fraction[:, None, None])[1].numpy()
    lens = (clear.psf * clear.crop_energy_fraction[:, None, None])[1].numpy()
    centre = 301 // 2
    column = centre + int(round(wavelength * setup.sensor_distance_m / (period_features * feature_m) / 6e-6))
    half = 12  # +-12 px: four Airy radii (17 um each)
    in_order = grating[centre - half:centre + half + 1, column - half:column + half + 1].sum()
    in_spot = lens[centre - half:centre + half + 1, centre - half:centre + half + 1].sum()
    assert in_order / in_spot == pytest.approx(np.sinc(1 / period_features) ** 2, abs=0.002)
    assert grating[centre - half:centre + half + 1, centre - half:centre + half + 1].sum() < 1e-3


def test_a_psf_smaller_than_its_energy_centre_is_refused_not_misreported(tmp_path, capsys):
    from hdrcam.cli import main
    from hdrcam.optics.energy import centre_energy_fraction

    assert float(centre_energy_fraction(torch.ones(1, 5, 5), 2)) == 1.0
    with pytest.raises(ValueError, match="no 5 px centre box"):
        centre_energy_fraction(torch.ones(1, 3, 3) / 9, 2)  # it gave 0.111: a negative start sliced the far edge
    assert main(["psf", "--doe", "none", "--psf-size", "3", "--out", str(tmp_path / "p3")]) == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "smaller than the 5 px centre" in error  # psf.json said 0.0093 in the centre
    assert not (tmp_path / "p3").exists()


def _airy_pixel(pitch_m: float, wavelength_m: float, aperture_m: float, distance_m: float, dx: int, dy: int,
                nodes: int = 24, panels: int = 3) -> float:
    """Share of the light through a circular aperture that lands on sensor pixel (dx, dy) from the axis: the Airy
    pattern (scipy's J1) integrated over the pixel by Gauss-Legendre, ``panels`` panels of ``nodes`` per axis."""
    points, weights = np.polynomial.legendre.leggauss(nodes)
    edges = np.linspace(-0.5, 0.5, panels + 1)
    x = np.concatenate([(a + b) / 2 + (b - a) / 2 * points for a, b in zip(edges[:-1], edges[1:])]) * pitch_m
    w = np.concatenate([(b - a) / 2 * weights for a, b in zip(edges[:-1], edges[1:])]) * pitch_m
    radius = np.hypot((x + dy * pitch_m)[:, None], (x + dx * pitch_m)[None, :])
    v = np.pi * aperture_m * radius / (wavelength_m * distance_m)
    amplitude = np.where(v == 0, 1.0, 2 * scipy.special.j1(v) / np.where(v == 0, 1.0, v))
    peak = np.pi * aperture_m ** 2 / (4 * wavelength_m ** 2 * distance_m ** 2)  # per m^2, of the aperture's light
    return float((peak * amplitude ** 2 * w[:, None] * w[None, :]).sum())


@pytest.mark.parametrize("propagation", ["fresnel", "angular_spectrum"])
def test_a_sensor_pixel_records_the_airy_pattern_integrated_over_its_area(propagation):
    """Profile `simulated`, bare lens, the coarsest unaliased grid (2 samples per pixel): the centre pixel and
    its neighbours hold the Airy pattern integrated over each pixel, within 1 % (or 1e-3 of the light). Summing
    the 2 x 2 point samples per pixel had put the centre pixel 7.4 / 9.3 / 10.7 % (R / G / B) too high."""
    import dataclasses

    from hdrcam.optics.heightmap import heightmap_for_doe
    from hdrcam.optics.psf import OpticalSetup
    from hdrcam.profiles import load_profile

    profile = load_profile("simulated")
    profile = dataclasses.replace(profile, simulation=dataclasses.replace(profile.simulation, propagation=propagation))
    setup = OpticalSetup.from_profile(profile, psf_size_px=31)
    assert setup.grid.upsample == 2
    simulator = PsfSimulator(setup, heightmap_for_doe(profile.doe, "none", dtype=torch.float64), dtype=torch.float64)
    with torch.no_grad():
        result = simulator()
    light = (result.psf * result.crop_energy_fraction[:, None, None]).numpy()  # shares of the aperture's light
    for channel, (wavelength_m,) in enumerate(setup.band_wavelengths_m):
        for dy, dx in ((0, 0), (0, 1), (1, 1), (0, 2)):
            expected = _airy_pixel(setup.pixel_pitch_m, wavelength_m, profile.doe.aperture_m,
                                   setup.sensor_distance_m, dx, dy)
            assert light[channel, 15 + dy, 15 + dx] == pytest.approx(expected, rel=0.01, abs=1e-3)
