"""Capture profiles: the shipped ones load; mistakes are reported with file, section and key."""

from __future__ import annotations

import pytest

from hdrcam.errors import ProfileError
from hdrcam.profiles import PROFILE_DIRECTORY, load_profile


def test_sony_a7_profile_holds_the_papers_prototype():
    profile = load_profile("sony-a7-zeiss50-rank1")
    assert profile.camera.pixel_pitch_m == 5.97e-6 and profile.camera.bit_depth == 14
    assert profile.camera.black_level_dn == 512 and profile.camera.cfa_pattern == "RGGB"
    assert profile.lens.focal_length_m == 0.05 and profile.lens.f_number == 1.4
    assert profile.doe.aperture_m == 9.16e-3 and profile.doe.feature_size_m == 6e-6
    assert profile.doe.levels == 16 and profile.doe.rank == 3
    assert profile.doe.design_wavelength_m == 550e-9 and profile.doe.h_max_m == pytest.approx(1.1959e-6, rel=1e-4)
    assert profile.calibration.point_source_distance_m == 5.0 and profile.calibration.stops == 5
    assert profile.sensor_distance_m == pytest.approx(1 / (1 / 0.05 - 1 / 5.0))


def _variant(tmp_path, old: str, new: str):
    text = (PROFILE_DIRECTORY / "simulated.toml").read_text().replace(old, new, 1)
    path = tmp_path / "variant.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("old, new, message", [
    ("aperture_m = 2.048e-3", "aperture_m = -2.0e-3", r"\[doe\] aperture_m: must be positive"),
    ("aperture_m = 2.048e-3", "aperture_m = \"wide\"", r"\[doe\] aperture_m: expected a number"),
    ("aperture_m = 2.048e-3", "aperture_m = 2.048e-3\naperture_mm = 2.048", r"\[doe\] aperture_mm: unknown key"),
    ("aperture_m = 2.048e-3", "", r"\[doe\] aperture_m: is required"),
    ("levels = 16", "levels = 12", "power of two"),
    ("cfa_pattern = \"RGGB\"", "cfa_pattern = \"RGBW\"", "must be one of"),
    ("black_level_dn = 512", "black_level_dn = 20000", "black_level_dn < white_level_dn"),
    ("aperture_m = 2.048e-3", "aperture_m = 20e-3", "wider than the lens pupil"),
    ("[lens]", "[lense]", r"\[top level\] lense: unknown key"),
    ("psf_size_px = 63", "psf_size_px = 63.5", "expected an integer"),
    ("name = \"simulated\"", "name = [", "not valid TOML"),
    ("design_wavelength_m = 550e-9", "design_wavelength_m = 550e-9\nh_max_m = 1.2e-6", "exactly one of"),
    ("design_wavelength_m = 550e-9", "", "exactly one of"),
    ("design_wavelength_m = 550e-9", "design_wavelength_m = 550", "must be at most"),
    ("pixel_pitch_m = 5.97e-6", "pixel_pitch_m = inf", r"\[camera\] pixel_pitch_m: must be a finite number"),
    ("full_well_e = 25000.0", "full_well_e = nan", r"\[camera\] full_well_e: must be a finite number"),
    ("pixel_pitch_m = 5.97e-6", "pixel_pitch_m = 5.97", r"\[camera\] pixel_pitch_m: must be at most"),
    ("width_px = 1024", "width_px = 10000000", r"\[camera\] width_px: must be at most 100000"),
    ("feature_size_m = 32.0e-6", "feature_size_m = 1.0e-6", r"\[doe\] feature_size_m: .* below the simulation pitch"),
    ("feature_size_m = 32.0e-6", "feature_size_m = 4.0e-3", r"\[doe\] feature_size_m: .* larger than the DOE"),
    ("blue_band_m = [410e-9, 490e-9]", "blue_band_m = [710e-9, 790e-9]", "from long \\(red\\) to short"),
    ("red_band_m = [610e-9, 690e-9]", "red_band_m = [610, 690]", r"\[simulation\] red_band_m: expected"),
    ("psf_size_px = 63", "psf_size_px = 64", r"\[simulation\] psf_size_px: must be odd"),
    ("energy_centre_radius_px = 3", "energy_centre_radius_px = 40", "does not fit"),
    ("point_source_distance_m = 5.0", "point_source_distance_m = 0.01", "not beyond the focal length"),
    ("point_source_distance_m = 5.0", "point_source_distance_m = -inf", "must be a finite number"),
    ("levels = 16", "levels = 1099511627776", r"\[doe\] levels: must be at most 65536"),
])
def test_schema_errors_name_the_key(tmp_path, old, new, message):
    with pytest.raises(ProfileError, match=message):
        load_profile(_variant(tmp_path, old, new))


def test_a_source_at_infinity_is_allowed(tmp_path):
    profile = load_profile(_variant(tmp_path, "point_source_distance_m = 5.0", "point_source_distance_m = inf"))
    assert profile.calibration.point_source_distance_m == float("inf")


def test_unknown_profile_lists_the_known_ones():
    with pytest.raises(ProfileError, match="simulated, sony-a7-zeiss50-rank1"):
        load_profile("no-such-camera")


def test_h_max_is_one_wave_at_the_design_wavelength_and_back(tmp_path):
    """lambda / (n(lambda) - 1) with Malitson's fused silica: n(550 nm) = 1.45991 -> 1.1959 um; the paper's
    1.125 um, given as h_max_m, is one wave at ~519 nm."""
    assert load_profile("simulated").doe.h_max_m == pytest.approx(550e-9 / 0.459910, rel=1e-5)
    explicit = load_profile(_variant(tmp_path, "design_wavelength_m = 550e-9", "h_max_m = 1.125e-6"))
    assert explicit.doe.h_max_m == 1.125e-6
    assert explicit.doe.design_wavelength_m == pytest.approx(519e-9, abs=1e-9)
