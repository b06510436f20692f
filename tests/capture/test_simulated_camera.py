"""The simulated A7: noise statistics against the Poisson-Gaussian model, energy, reproducibility, DNG metadata."""

from __future__ import annotations

import numpy as np
import pytest

from hdrcam.capture.notches import SHUTTER_NOTCHES, bracket_notches, nearest_shutter
from hdrcam.capture.scene import PointSource, Scene, load_scene
from hdrcam.capture.simulated import BASE_ISO, SimulatedCamera
from hdrcam.colorimetry import camera_from_srgb
from hdrcam.errors import InputError
from hdrcam.optics.analytic import dirac
from hdrcam.profiles import load_profile
from tests.capture.helpers import small_camera


def test_flat_field_mean_and_variance_follow_shot_plus_read_noise():
    profile = load_profile("simulated")
    spec = profile.camera
    level = 0.05
    scene = Scene(200, 200, np.full((200, 200, 3), level, np.float32))
    camera = SimulatedCamera(profile, scene, dirac(5), seed=4, hot_pixel_fraction=0.0, exposure_error=0.0)
    camera.set_exposure(1 / 60, iso=400)
    dn = camera.render_dn().astype(np.float64)
    gain_dn_per_e = (spec.white_level_dn - spec.black_level_dn) * (400 / BASE_ISO) / spec.full_well_e
    green = dn[0::2, 1::2]  # RGGB: G at (0, 1)
    fraction = level * camera_from_srgb()[1].sum() * camera.true_exposure_s() * 60
    electrons = fraction * spec.full_well_e
    assert green.mean() == pytest.approx(spec.black_level_dn + electrons * gain_dn_per_e, rel=2e-3)
    expected_variance = gain_dn_per_e ** 2 * (electrons + spec.read_noise_e ** 2) + 1 / 12  # + rounding
    assert green.var() == pytest.approx(expected_variance, rel=0.03)


def test_point_source_energy_lands_in_the_frame():
    profile = load_profile("simulated")
    power = 0.5
    radius2 = np.add.outer(np.arange(-7, 8) ** 2, np.arange(-7, 8) ** 2)
    gaussian = np.exp(-radius2 / (2 * 1.5 ** 2))
    psf = np.stack([gaussian / gaussian.sum()] * 3).astype(np.float32)
    scene = Scene(64, 64, None, (PointSource(31.3, 32.6, power),))
    camera = SimulatedCamera(profile, scene, psf, seed=0, hot_pixel_fraction=0.0, exposure_error=0.0)
    camera.set_exposure(1 / 60)
    spec = profile.camera
    frames = np.stack([camera.render_dn() for _ in range(16)]).astype(np.float64)  # read noise sums over 2048 px
    signal = (frames.mean(axis=0) - spec.black_level_dn) / (spec.white_level_dn - spec.black_level_dn)
    green = signal[0::2, 1::2].sum() + signal[1::2, 0::2].sum()  # half the pixels are green
    expected = power * camera_from_srgb()[1].sum() * camera.true_exposure_s() * 60 / 2
    assert green == pytest.approx(expected, rel=0.02)
    rows, columns = np.mgrid[0:64, 0:64]
    irradiance = camera._rate(False)
    weights = np.zeros_like(irradiance)
    weights[0::2, 1::2] = weights[1::2, 0::2] = 1  # green sites see a smooth PSF at half density
    green_rate = irradiance * weights
    assert (green_rate * columns).sum() / green_rate.sum() == pytest.approx(31.3, abs=0.02)
    assert (green_rate * rows).sum() / green_rate.sum() == pytest.approx(32.6, abs=0.02)


def test_shutter_true_times_are_powers_of_two_and_brackets_3_ev_apart():
    notches = bracket_notches(1 / 4000, 5, 3.0)
    assert [n.label for n in notches] == ["1/4000", "1/500", "1/60", "1/8", '1"']
    assert np.allclose(np.diff(np.log2([n.true_s for n in notches])), 3.0)
    assert nearest_shutter(1 / 125).true_s == 2.0 ** -7
    with pytest.raises(InputError, match="30 s"):
        bracket_notches(1.0, 5, 3.0)
    with pytest.raises(InputError, match="1/3 EV"):
        bracket_notches(1 / 4000, 3, 0.5)
    assert len(SHUTTER_NOTCHES) == 55


def test_same_seed_same_frames_other_seed_other_frames():
    frames = []
    for seed in (1, 1, 2):
        camera, _ = small_camera(seed=seed)
        frames.append(camera.render_dn())
    assert np.array_equal(frames[0], frames[1]) and not np.array_equal(frames[0], frames[2])


def test_exposure_error_is_bounded_and_fixed_per_notch():
    camera, _ = small_camera(exposure_error=0.07)
    for notch in SHUTTER_NOTCHES[::5]:
        ratio = camera.true_exposure_s(notch) / notch.true_s
        assert abs(ratio - 1) <= 0.07 and ratio == camera.true_exposure_s(notch) / notch.true_s


def test_hot_pixels_show_in_long_dark_frames():
    camera, _ = small_camera(hot_pixel_fraction=0.01)
    camera.set_exposure(1.0)
    dark = camera.render_dn(dark=True).astype(float)
    rows, columns = camera.defects.hot_pixel_rows, camera.defects.hot_pixel_columns
    assert len(rows) == round(0.01 * 48 * 64)
    assert dark[rows, columns].min() > 512 + 1000 and np.median(dark) == pytest.approx(512, abs=2)


def test_all_saturated_scene_clips_at_the_white_level_and_zero_scene_sits_at_black():
    bright, _ = small_camera(scene="flat:1e6")
    assert (bright.render_dn() == 16383).all()
    black, _ = small_camera(scene="flat:0", hot_pixel_fraction=0.0)
    assert abs(black.render_dn().astype(float).mean() - 512) < 0.5


def test_scene_specs():
    assert load_scene("point:3", 40, 50, seed=1).points[0].power == 3.0
    night = load_scene("night", 40, 50, seed=1)
    assert night.radiance.shape == (40, 50, 3) and night.radiance.max() <= 256 * 1.5
    with pytest.raises(Exception, match="unknown scene"):
        load_scene("moon", 4, 4)
    with pytest.raises(Exception, match="not a number"):
        load_scene("flat:x", 4, 4)


def test_a_scene_too_bright_for_float32_is_one_line_not_a_traceback():
    from hdrcam.capture.simulated import camera_irradiance

    assert np.isfinite(camera_irradiance(load_scene("flat:1e33", 400, 600, seed=0), dirac(9))).all()
    with pytest.raises(InputError, match="overflows the simulation's float32"):  # NaN reached rng.poisson: exit 3
        camera_irradiance(load_scene("flat:1e34", 400, 600, seed=0), dirac(9))


@pytest.mark.parametrize("settings", [{"hot_pixel_fraction": 1.0}, {"exposure_error": -0.1},
                                      {"exposure_error": np.nan}])
def test_the_simulated_camera_refuses_defect_settings_that_are_no_fractions(settings):
    scene = load_scene("flat:0.5", 32, 48, seed=0)
    with pytest.raises(InputError, match="expected a fraction from 0 up to"):  # built directly, it took them
        SimulatedCamera(load_profile("simulated"), scene, dirac(9), **settings)
