"""Sampling choices, height-map parameterisations and files, the energy regulariser."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import torch

from hdrcam.errors import InputError, SamplingError
from hdrcam.optics.energy import centre_energy_fraction, energy_regulariser
from hdrcam.optics.grid import SimulationGrid, is_fast_length
from hdrcam.optics.heightmap import (FreeFormHeightMap, Rank1HeightMap, feature_count, heightmap_for_doe,
                                     load_heightmap, save_heightmap)
from hdrcam.optics.psf import OpticalSetup
from hdrcam.profiles import load_profile


def test_a7_profile_grid_is_unaliased_and_a_pixel_pitch_fraction():
    """The Fresnel grid of the A7 profile (its default is the chirp-z model, which has no lens-phase grid)."""
    profile = load_profile("sony-a7-zeiss50-rank1")
    assert profile.simulation.propagation == "fraunhofer" and OpticalSetup.from_profile(profile).grid is None
    fresnel = dataclasses.replace(profile, simulation=dataclasses.replace(profile.simulation, propagation="fresnel"))
    setup = OpticalSetup.from_profile(fresnel)
    grid = setup.grid
    assert grid.upsample == 3 and grid.pitch_m == pytest.approx(1.99e-6)
    assert grid.pitch_m <= 450e-9 * 0.05 / 9.16e-3  # D <= lambda f / dx at the shortest wavelength
    assert grid.width_m >= 9.16e-3 and is_fast_length(grid.size) and grid.size % grid.upsample == 0
    assert setup.sensor_distance_m == pytest.approx(50.505e-3, rel=1e-4)


def test_an_aliasing_grid_is_refused_with_numbers_or_warned_when_allowed():
    arguments = dict(pixel_pitch_m=5.97e-6, aperture_m=9.16e-3, focal_length_m=0.05, shortest_wavelength_m=450e-9,
                     psf_size_px=15, upsample=2)
    with pytest.raises(SamplingError, match=r"2\.985 um aliases.*<= 2\.456 um.*upsample >= 3"):
        SimulationGrid.for_optics(**arguments)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        grid = SimulationGrid.for_optics(**arguments, allow_aliasing=True)
    assert grid.upsample == 2 and any("aliases" in str(w.message) for w in caught)
    assert grid.lens_phase_aliased and not SimulationGrid.for_optics(**{**arguments, "upsample": 3}).lens_phase_aliased


@pytest.mark.parametrize("upsample", [1, 2, 3, 4])
def test_optical_axis_is_the_centre_of_sensor_pixel_m_over_2(upsample):
    grid = SimulationGrid(pixel_pitch_m=6e-6, upsample=upsample, sensor_pixels=10)
    block = grid.coordinates_m().reshape(10, upsample)[5]
    assert block.mean() == pytest.approx(0.0, abs=1e-15)
    field = torch.randn(grid.size, grid.size, dtype=torch.complex128)
    intensity = field.real ** 2 + field.imag ** 2
    assert float(grid.integrate_pixels(field).sum()) == pytest.approx(float(intensity.sum()))


def test_rank1_heightmap_is_low_rank_in_logit_space_and_bounded():
    heightmap = Rank1HeightMap(40, 6e-6, 1.125e-6, rank=3, init_std=1.0, seed=0, dtype=torch.float64)
    heights = heightmap().detach()
    assert heights.shape == (40, 40) and 0 < float(heights.min()) and float(heights.max()) < 1.125e-6
    logits = torch.logit(heights / 1.125e-6)
    assert int(torch.linalg.matrix_rank(logits, rtol=1e-6)) == 3
    assert int(torch.linalg.matrix_rank((Rank1HeightMap(40, 6e-6, 1.125e-6, rank=1)().detach() / 1.125e-6).logit())) == 1
    assert sum(p.numel() for p in heightmap.parameters()) == 2 * 40 * 3
    assert sum(p.numel() for p in FreeFormHeightMap(40, 6e-6, 1.125e-6).parameters()) == 40 * 40


def test_heightmap_file_round_trip_and_refusals(tmp_path):
    doe = load_profile("simulated").doe
    features = feature_count(doe.aperture_m, doe.feature_size_m)
    heights = np.random.default_rng(0).uniform(0, doe.h_max_m, (features, features))
    path = save_heightmap(tmp_path / "h.exr", heights, doe.feature_size_m)
    loaded = heightmap_for_doe(doe, str(path))
    np.testing.assert_allclose(loaded().numpy(), heights, rtol=1e-6)
    assert loaded.feature_pitch_m == pytest.approx(doe.feature_size_m, rel=1e-6)
    small = save_heightmap(tmp_path / "small.exr", heights[:10, :10], doe.feature_size_m)
    with pytest.raises(InputError, match="must cover the aperture"):
        load_heightmap(small, doe.aperture_m)
    from hdrcam.io.exr import write_exr
    write_exr(tmp_path / "nopitch.exr", heights.astype(np.float32))
    with pytest.raises(InputError, match="pixel_pitch_m"):
        load_heightmap(tmp_path / "nopitch.exr", doe.aperture_m)


def test_energy_regulariser_on_known_psfs():
    dirac = torch.zeros(3, 9, 9)
    dirac[:, 4, 4] = 1
    torch.testing.assert_close(centre_energy_fraction(dirac, 1), torch.ones(3))
    uniform = torch.ones(3, 9, 9, requires_grad=True)
    fraction = centre_energy_fraction(uniform, 1)
    torch.testing.assert_close(fraction.detach(), torch.full((3,), 9 / 81))
    loss = energy_regulariser(fraction, 0.94)
    assert float(loss.detach()) == pytest.approx((9 / 81 - 0.94) ** 2, rel=1e-6)
    loss.backward()
    assert float(uniform.grad[:, 4, 4].mean()) < 0  # more energy at the centre lowers the loss
    assert float(energy_regulariser(torch.full((3,), 0.94), 0.94)) == 0.0


@pytest.mark.parametrize("pitch_m", [float("inf"), 1.0, 6.0, 3e-3, 1e-8])
def test_a_pitch_that_is_no_doe_feature_is_refused(pitch_m, tmp_path):
    """inf passed `pitch > 0` and 1 m gave a NaN chirp-z PSF; 6 is 6 um written in micrometres."""
    path = save_heightmap(tmp_path / "h.exr", np.zeros((64, 64)), pitch_m)
    with pytest.raises(InputError, match=r"h\.exr: 'pixel_pitch_m' .* outside 0\.1 um \.\. 1 mm.*metres"):
        load_heightmap(path, 2.048e-3)


@pytest.mark.parametrize("height_m", [0.5, 1.2, -1e-7])
def test_heights_in_the_wrong_unit_or_below_zero_are_refused(height_m, tmp_path):
    """0.5 m of relief everywhere (micrometres stored as metres) simulated silently."""
    path = save_heightmap(tmp_path / "h.exr", np.full((64, 64), height_m), 32e-6)
    with pytest.raises(InputError, match=r"h\.exr: heights span .* outside 0 \.\. 100 um.*1\.2e-6"):
        load_heightmap(path, 2.048e-3)


def test_a_multi_order_relief_above_h_max_loads_and_fabrication_still_refuses_it(tmp_path):
    """Heights above one wave are a physical (multi-order) DOE: the file loads and simulates; only the 2^k-level
    lithography export, whose levels span [0, h_max], refuses them."""
    from hdrcam.optics.fabrication import quantise_heightmap

    doe = load_profile("simulated").doe
    path = save_heightmap(tmp_path / "h.exr", np.full((64, 64), 3 * doe.h_max_m), doe.feature_size_m)
    heights = load_heightmap(path, doe.aperture_m)().numpy()
    np.testing.assert_allclose(heights, 3 * doe.h_max_m, rtol=1e-6)
    with pytest.raises(ValueError, match=r"outside \[0, h_max"):
        quantise_heightmap(heights.astype(np.float64), doe.h_max_m, doe.levels)
