"""``hdrcam calibrate psf`` on brackets that cannot give a PSF: one-line refusals (exit 1) or a warning.

Small frames (256 x 192 px) and a 15 px PSF keep each case to a few seconds.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hdrcam.calibrate.effective_psf import fit_effective_psf
from hdrcam.calibrate.point_sources import SourceWindow
from hdrcam.cli import main
from hdrcam.io.exr import write_exr

SIZE = ["--size", "256x192"]


def _capture(folder, scene: str, stops: int = 2) -> None:
    assert main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--scene", scene,
                 "--stops", str(stops), "--seed", "0", *SIZE, "--out", str(folder)]) == 0


def _calibrate(bracket, out) -> int:
    return main(["calibrate", "psf", str(bracket), "--size", "15", "--profile", "simulated", "--out", str(out)])


def _assert_refused(code: int, capsys, out, words: str, recwarn) -> None:
    error = capsys.readouterr().err.strip()
    assert code == 1, error
    assert error.count("\n") == 0 and words in error, error
    assert not [str(w.message) for w in recwarn.list]
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("scene, words", [("flat", "sigma above the background"),
                                          ("night", "not a point source")])
def test_a_flat_field_or_an_extended_scene_is_refused(tmp_path, capsys, recwarn, scene, words):
    """Before: exit 3, 'could not broadcast input array' (noise peaks of a flat field, or extended night
    lights, taken as point sources and moved out of their windows by the fit)."""
    _capture(tmp_path / "bracket", scene)
    capsys.readouterr()
    recwarn.clear()
    _assert_refused(_calibrate(tmp_path / "bracket", tmp_path / "r"), capsys, tmp_path / "r", words, recwarn)


@pytest.mark.parametrize("power", [50.0, 2.0])
def test_a_single_point_source_is_refused(tmp_path, capsys, recwarn, power):
    """One source samples red and blue at a quarter of the PSF's pixels: fewer equations than unknowns.
    Before: exit 0 with a PSF off by ~100 % L1 (or exit 3 after a 'Matrix is exactly singular' warning)."""
    scene = np.zeros((192, 256, 3), np.float32)
    scene[96, 128] = power
    write_exr(tmp_path / "scene.exr", scene)
    _capture(tmp_path / "bracket", str(tmp_path / "scene.exr"), stops=4)  # 4 stops: the weak one is recorded
    capsys.readouterr()
    recwarn.clear()
    _assert_refused(_calibrate(tmp_path / "bracket", tmp_path / "r"), capsys, tmp_path / "r",
                    "too few point sources", recwarn)


def test_faint_pinholes_are_warned_about_and_bright_ones_pass_without_warning(tmp_path, capsys, recwarn):
    """24 pinholes 40 px apart: at power 0.5 the fit puts ~3.5 % of the red energy below zero (before: exit 0,
    silently); at the default power 50 it passes, with nothing on stderr."""
    _capture(tmp_path / "faint", "pinholes:0.5:40", stops=3)
    _capture(tmp_path / "bright", "pinholes::40", stops=3)
    recwarn.clear()
    with pytest.warns(UserWarning, match=r"poorly constrained: 3\.\d % of the fitted red energy is negative"):
        assert _calibrate(tmp_path / "faint", tmp_path / "faint-record") == 0
    recwarn.clear()
    capsys.readouterr()
    assert _calibrate(tmp_path / "bright", tmp_path / "r") == 0
    assert capsys.readouterr().err == ""
    assert not [str(w.message) for w in recwarn.list]


def test_a_source_on_a_pixel_centre_gives_a_finite_fit_without_warnings():
    """At zero sub-pixel fraction a single source leaves red PSF pixels with no sampled neighbour at all.
    Before: scipy's 'Matrix is exactly singular' warning, then NaN positions ('cannot convert float NaN')."""
    size, half = 7, 5
    width = 2 * half + 1
    channel = np.zeros((width, width), np.int8)
    channel[0::2, 1::2] = 1
    channel[1::2, 0::2] = 1
    channel[1::2, 1::2] = 2
    rate = np.zeros((width, width))
    rate[half - 1:half + 2, half - 1:half + 2] = 10.0  # some signal in every channel
    rate[half, half] = 100.0
    window = SourceWindow(0, 0, rate, np.ones((width, width)), channel, np.zeros(3), np.ones(3),
                          float(half), float(half))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = fit_effective_psf([window], size)
    assert np.isfinite(fit.psf).all() and np.isfinite(fit.positions_px).all()


def test_pinholes_clipped_whole_in_every_frame_are_named_as_clipped(tmp_path, capsys):
    """Without a DOE a bright pinhole is clipped whole and masked out before detection: the error blamed the
    frame's edge for the one noise peak it found."""
    assert main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--scene", "pinholes:1e9",
                 "--psf", "dirac", "--stops", "3", "--ev-step", "3", *SIZE, "--out", str(tmp_path / "b")]) == 0
    capsys.readouterr()
    assert _calibrate(tmp_path / "b", tmp_path / "r") == 1
    assert "spots clipped in every frame, not measurable (add a shorter exposure)" in capsys.readouterr().err
