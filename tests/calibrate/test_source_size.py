"""``calibrate psf --source-diameter-mm``: a point source whose geometric image is wider than a pixel.

The data then show the true PSF blurred by the source's image, a disc, and the fit matches them (discs of 1.5-8 px
put the PSF 35-158 % off in L1, reduced chi2 fine, no warning). Given the source's diameter, its thin-lens image
d * f / (z - f) is computed, recorded, warned about over 1 px and refused over the PSF --size.
"""

from __future__ import annotations

import json
import math

import pytest

from hdrcam.cli import main
from hdrcam.errors import InputError
from hdrcam.profiles import load_profile

PITCH_M = 5.97e-6  # both profiles' pixel pitch


@pytest.fixture(scope="module")
def bracket(tmp_path_factory):
    """24 pinholes 40.6 px apart on a 256 x 192 px frame (simulated profile: f = 20 mm, source at 5 m)."""
    folder = tmp_path_factory.mktemp("source-size") / "bracket"
    assert main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--scene", "pinholes::40.6",
                 "--stops", "3", "--seed", "0", "--size", "256x192", "--out", str(folder)]) == 0
    return folder


def _calibrate(bracket, out, *options: str) -> int:
    return main(["calibrate", "psf", str(bracket), "--size", "15", "--profile", "simulated", "--out", str(out),
                 *options])


def test_the_image_size_is_the_thin_lens_image_of_the_source_in_pixels():
    """The lab's rule (REFERENCE): a source under ~0.59 mm at 5 m images within one 5.97 um pixel through a
    50 mm lens. By hand: 0.59 mm * 50 mm / 4950 mm = 5.9596 um = 0.99826 px; 1 mm gives 10.101 um = 1.6920 px;
    one pixel at 5 m is 5.97 um * 4950 / 50 = 0.59103 mm."""
    from hdrcam.calibrate.psf_calibration import source_size

    a7 = load_profile("sony-a7-zeiss50-rank1")
    assert a7.camera.pixel_pitch_m == PITCH_M and a7.lens.focal_length_m == 0.05
    at_profile = source_size(0.59e-3, None, a7)
    assert at_profile.distance_m == 5.0 and not at_profile.distance_given  # the profile's source distance
    assert at_profile.image_px == pytest.approx(0.99826, abs=1e-5)
    assert at_profile.largest_within_pixel_m == pytest.approx(0.59103e-3, rel=1e-5)
    assert source_size(1e-3, 5.0, a7).image_px == pytest.approx(1.6920, abs=1e-4)
    assert source_size(1e-3, 0.55, a7).image_px == pytest.approx(1e-3 * 0.05 / 0.5 / PITCH_M)  # 16.75 px, near
    assert source_size(None, None, a7) is None


def test_a_source_wider_than_a_pixel_is_warned_about_and_recorded(bracket, tmp_path, capsys):
    """5 mm at 5 m through the simulated profile's 20 mm lens: 5 mm * 20 / 4980 = 20.080 um = 3.3635 px; one pixel
    is 5.97 um * 4980 / 20 = 1.4865 mm. 1 mm at 0.5 m: 1 mm * 20 / 480 = 41.667 um = 6.9793 px."""
    with pytest.warns(UserWarning, match=r"blurred by a disc about 3\.4 px wide.*up to 1\.48 mm wide at 5 m"):
        assert _calibrate(bracket, tmp_path / "r", "--source-diameter-mm", "5") == 0
    source = json.loads((tmp_path / "r" / "record.json").read_text())["source"]
    assert source["given"] and source["diameter_m"] == 0.005 and source["distance_m"] == 5.0
    assert source["distance_from"] == "profile calibration.point_source_distance_m"
    assert source["image_px"] == pytest.approx(3.3635, abs=1e-4)
    assert source["largest_within_one_pixel_m"] == pytest.approx(1.4865e-3, rel=1e-4)

    with pytest.warns(UserWarning, match=r"about 7\.0 px wide"):
        assert _calibrate(bracket, tmp_path / "near", "--source-diameter-mm", "1", "--source-distance-m", "0.5") == 0
    source = json.loads((tmp_path / "near" / "record.json").read_text())["source"]
    assert source["distance_from"] == "given" and source["image_px"] == pytest.approx(6.9793, abs=1e-4)


def test_a_source_within_a_pixel_passes_without_a_warning(bracket, tmp_path, capsys, recwarn):
    """1 mm at 5 m, simulated profile: 0.6727 px."""
    recwarn.clear()
    assert _calibrate(bracket, tmp_path / "r", "--source-diameter-mm", "1") == 0
    assert capsys.readouterr().err == "" and not [str(w.message) for w in recwarn.list]
    source = json.loads((tmp_path / "r" / "record.json").read_text())["source"]
    assert source["image_px"] == pytest.approx(1e-3 * 0.02 / 4.98 / PITCH_M) == pytest.approx(0.6727, abs=1e-4)


def test_without_the_diameter_the_record_says_the_size_was_not_given(bracket, tmp_path):
    assert _calibrate(bracket, tmp_path / "r") == 0
    source = json.loads((tmp_path / "r" / "record.json").read_text())["source"]
    assert source["given"] is False and source["image_px"] is None and "not given" in source["note"]


def test_a_source_imaged_wider_than_the_psf_is_refused_and_nothing_is_written(bracket, tmp_path, capsys, recwarn):
    """25 mm at 5 m: 25 mm * 20 / 4980 / 5.97 um = 16.82 px, over the 15 px PSF."""
    recwarn.clear()
    assert _calibrate(bracket, tmp_path / "r", "--source-diameter-mm", "25") == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "16.8 px wide, wider than the 15 px PSF" in error, error
    assert not [str(w.message) for w in recwarn.list]
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf", "abc"])
@pytest.mark.parametrize("option", ["--source-diameter-mm", "--source-distance-m"])
def test_a_value_that_is_not_a_positive_finite_number_is_a_usage_error(bracket, tmp_path, capsys, option, value):
    with pytest.raises(SystemExit) as stop:
        _calibrate(bracket, tmp_path / "r", "--source-diameter-mm", "1", option, value)
    error = capsys.readouterr().err.strip()
    assert stop.value.code == 2 and error.count("\n") == 0 and f"argument {option}: " in error, error  # its value
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("options, words", [(["--source-diameter-mm", "1", "--source-distance-m", "0.02"],
                                             "inside the lens's focal length 0.02 m"),
                                            (["--source-distance-m", "5"], "without the source's diameter")])
def test_a_distance_inside_the_focal_length_or_without_a_diameter_is_refused(bracket, tmp_path, capsys, options,
                                                                             words):
    assert _calibrate(bracket, tmp_path / "r", *options) == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and words in error, error
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("diameter_m, distance_m", [(-1e-3, None), (0.0, None), (math.nan, None), (math.inf, None),
                                                    (True, None), (1e-3, math.nan), (1e-3, 0.01), (None, 5.0)])
def test_the_library_refuses_bad_values_before_reading_the_bracket(tmp_path, diameter_m, distance_m):
    import hdrcam

    with pytest.raises(InputError) as error:  # the bracket does not exist: the values are checked first
        hdrcam.calibrate_psf(tmp_path / "missing", profile="simulated", size_px=15, source_diameter_m=diameter_m,
                             source_distance_m=distance_m)
    assert "source" in str(error.value) and "\n" not in str(error.value)


def test_the_library_returns_the_source_size(bracket):
    import hdrcam

    with pytest.warns(UserWarning, match="3.4 px wide"):
        calibration = hdrcam.calibrate_psf(bracket, profile="simulated", size_px=15, source_diameter_m=5e-3)
    assert calibration.source.image_px == pytest.approx(3.3635, abs=1e-4)


def test_a_pinhole_imaged_many_pixels_wide_is_refused_with_a_pointer_to_the_diameter_option(tmp_path, capsys):
    """Without its diameter, a pinhole imaged 14 px wide (the design PSF blurred by a 14 px disc) is refused by the
    fit as moved out of its window; the message named only extended objects and moved frames."""
    import numpy as np
    import scipy.signal

    from hdrcam.io.exr import write_exr
    from hdrcam.train.checkpoint import load_model

    offsets = np.arange(-7, 8)
    disc = (offsets[:, None] ** 2 + offsets[None, :] ** 2 <= 7 ** 2).astype(np.float32)
    blurred = np.stack([scipy.signal.fftconvolve(channel, disc, mode="same") for channel in load_model().psf])
    blurred = np.clip(blurred, 0.0, None) / np.clip(blurred, 0.0, None).sum(axis=(1, 2), keepdims=True)
    psf = write_exr(tmp_path / "disc-psf.exr", blurred.transpose(1, 2, 0).astype(np.float32),
                    channel_names=("R", "G", "B"))
    assert main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--scene", "pinholes::40.6",
                 "--psf", str(psf), "--stops", "3", "--seed", "0", "--size", "256x192",
                 "--out", str(tmp_path / "bracket")]) == 0
    capsys.readouterr()
    assert _calibrate(tmp_path / "bracket", tmp_path / "out") == 1
    error = capsys.readouterr().err
    assert "not a point source" in error and "--source-diameter-mm" in error
    assert not (tmp_path / "out").exists()
