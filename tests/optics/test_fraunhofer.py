"""The chirp-z focal-plane model against analytic optics and against the Fresnel grid simulation."""

from __future__ import annotations

import numpy as np
import pytest
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
    wide enough that nothing wraps) and from chirp-z transforms of 2 um pupil cells."""
    setup = single_wavelength_setup(aperture_m=2e-3, focal_length_m=FOCAL_M, pixel_pitch_m=6e-6, upsample=3,
                                    window_m=4e-3, psf_size_px=101)
    heightmap = Rank1HeightMap(200, 10e-6, 1.2e-6, seed=1, init_std=0.3, dtype=torch.float64)
    with torch.no_grad():
        fresnel = PsfSimulator(setup, heightmap, dtype=torch.float64)()
    model = FraunhoferPsf(aperture_m=2e-3, feature_pitch_m=10e-6, features=200, pixel_pitch_m=6e-6,
                          sensor_distance_m=setup.sensor_distance_m, focal_length_m=FOCAL_M, source_distance_m=5.0,
                          material="fused_silica", band_wavelengths_m=setup.band_wavelengths_m, psf_size_px=101,
                          samples_per_feature=5, subpixels=3, dtype=torch.float64)
    with torch.no_grad():
        chirp_z = model(heightmap())
    reference = fresnel.psf * fresnel.crop_energy_fraction[:, None, None]
    assert float(chirp_z.sum()) == pytest.approx(float(reference.sum()), rel=1e-3)
    assert float((chirp_z - reference).abs().max()) < 5e-3 * float(reference.max())


def test_defocus_that_aliases_is_refused():
    from hdrcam.errors import SamplingError
    with pytest.raises(SamplingError, match="defocus"):
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
