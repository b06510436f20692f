"""The threaded, strip-wise fuse gives what one strip on one thread gives, for any strip size (strips that start
on a G/B row included), on a small simulated bracket with hot pixels and clipped lamps.

(Against the code before the speed work the outputs agreed to 1e-6, checked on that branch with stored
outputs; the clip levels measured per CFA position since then changed the reference, not the threading.)"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hdrcam.hdr.merge as merge
from hdrcam.hdr.fuse import fuse
from hdrcam.profiles import load_profile

DATA = Path(__file__).parent / "data"


def _fused(monkeypatch, strip_rows: int):
    monkeypatch.setattr(merge, "STRIP_ROWS", strip_rows)
    return fuse([DATA / "bracket-96x64"], load_profile("simulated").camera, camera_rgb=False, with_variance=True)


@pytest.mark.parametrize("strip_rows", [16, 5])
def test_fuse_does_not_depend_on_the_strips(monkeypatch, strip_rows):
    whole = _fused(monkeypatch, 1000)  # one strip
    image = _fused(monkeypatch, strip_rows)  # 4 and 13 strips
    for name in ("rate", "variance", "exposures_s"):
        np.testing.assert_allclose(getattr(image.merge, name), getattr(whole.merge, name), rtol=1e-6, atol=0,
                                   err_msg=name)
    np.testing.assert_allclose(image.rgb, whole.rgb, rtol=1e-6, atol=0)
    for name in ("clipped_everywhere", "usable_frames"):
        np.testing.assert_array_equal(getattr(image.merge, name), getattr(whole.merge, name), err_msg=name)
    np.testing.assert_array_equal(image.clipped, whole.clipped)
    assert whole.merge.clipped_everywhere.any() and not whole.merge.clipped_everywhere.all()


def test_the_colour_transform_is_the_matrix_product_on_every_strip():
    """Strip by strip in place (a height that no strip size divides), to float32 rounding of the float64 product."""
    from hdrcam.hdr.fuse import transformed

    pixels = np.random.default_rng(0).random((157, 33, 3), dtype=np.float32) * 100
    matrix = np.array([[1.8, -0.7, -0.1], [-0.2, 1.5, -0.3], [0.05, -0.5, 1.45]], np.float32)
    exact = pixels.astype(np.float64) @ matrix.T.astype(np.float64)
    result = transformed(pixels, matrix)
    assert result is pixels
    np.testing.assert_allclose(result, exact, rtol=0, atol=2e-6 * np.abs(exact).max())


def test_variance_is_positive_wherever_a_sample_was_measured_whatever_the_demosaic():
    """--variance --camera-rgb --demosaic menon2007 wrote variance 0 (a value claimed exact) at thousands of
    measured pixels: Menon's edge-directed interpolation of a variance plane. The variance is demosaiced
    bilinearly whatever the image's method, so it equals the bilinear fuse's."""
    camera = load_profile("simulated").camera
    menon = fuse([DATA / "bracket-96x64"], camera, camera_rgb=True, with_variance=True,
                 demosaic_method="menon2007")
    bilinear = fuse([DATA / "bracket-96x64"], camera, camera_rgb=True, with_variance=True)
    assert (menon.variance > 0).all()
    np.testing.assert_array_equal(menon.variance, bilinear.variance)
