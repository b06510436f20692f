"""Hand-designed PSFs of Table 2 are imaged through the profile's bare lens (a DOE cannot beat diffraction)."""

import numpy as np
import pytest
import torch

from hdrcam.optics.analytic import dual_peak
from hdrcam.optics.heightmap import heightmap_for_doe
from hdrcam.optics.psf import OpticalSetup, PsfSimulator
from hdrcam.profiles import load_profile
from hdrcam.train.optical_capture import DOE_PATTERNS, fixed_psf

PROFILE = load_profile("simulated")


@pytest.fixture(scope="module")
def bare_lens_psf() -> np.ndarray:
    simulator = PsfSimulator(OpticalSetup.from_profile(PROFILE), heightmap_for_doe(PROFILE.doe, "none"))
    with torch.no_grad():
        return simulator().psf.numpy()


def test_dirac_is_the_camera_without_a_doe(bare_lens_psf):
    """delta * L = L: the Dirac comparison is the bare lens, not a diffraction-free camera."""
    assert np.abs(fixed_psf("dirac", PROFILE) - bare_lens_psf).max() < 1e-6
    assert bare_lens_psf[:, 31, 31].max() < 0.85  # the f/9.8 lens spreads a point well beyond its pixel


def test_dual_peak_is_two_shifted_copies_of_the_lens_psf(bare_lens_psf):
    """(1 - f) delta + f delta(x - 8) convolved with L is (1 - f) L + f L shifted 8 px, cropped and renormalised."""
    secondary = 0.06
    shifted = np.zeros_like(bare_lens_psf)
    shifted[..., 8:] = bare_lens_psf[..., :-8]
    expected = (1 - secondary) * bare_lens_psf + secondary * shifted
    expected /= expected.sum(axis=(1, 2), keepdims=True)
    assert np.allclose(dual_peak(63, secondary_fraction=secondary)[0].sum(), 1.0)
    assert np.abs(fixed_psf("dual-peak", PROFILE) - expected).max() < 1e-6


@pytest.mark.parametrize("name", sorted(DOE_PATTERNS))
def test_fixed_psfs_are_unit_sum_intensities_of_the_profile_size(name):
    psf = fixed_psf(name, PROFILE)
    size = PROFILE.simulation.psf_size_px
    assert psf.shape == (3, size, size) and psf.dtype == np.float32
    assert psf.min() >= 0 and np.allclose(psf.sum(axis=(1, 2)), 1.0, atol=1e-5)


def test_a_psf_file_of_another_pixel_pitch_is_refused_and_one_without_a_pitch_is_taken(tmp_path):
    from hdrcam.errors import InputError
    from hdrcam.io.exr import write_exr

    profile = load_profile("simulated")
    psf = np.ones((15, 15, 3), np.float32)
    write_exr(tmp_path / "other.exr", psf, attributes={"pixel_pitch_m": 3e-6})
    write_exr(tmp_path / "same.exr", psf, attributes={"pixel_pitch_m": profile.camera.pixel_pitch_m})
    write_exr(tmp_path / "bare.exr", psf)
    with pytest.raises(InputError, match="a PSF of 3 um pixels, but the camera's are 5.97"):
        fixed_psf(str(tmp_path / "other.exr"), profile)
    for name in ("same.exr", "bare.exr"):
        assert np.allclose(fixed_psf(str(tmp_path / name), profile), 1 / 225)
