"""Quantisation to lithography levels and masks."""

from __future__ import annotations

import numpy as np
import pytest

from hdrcam.optics.fabrication import (design_wavelength_m, ideal_multilevel_efficiency, quantisation_strehl,
                                       quantise_heightmap)
from hdrcam.optics.materials import refractive_index

H_MAX = 1.125e-6


def test_quantisation_rounds_to_levels_and_wraps_full_wave_to_zero():
    step = H_MAX / 16
    heights = np.array([[0.0, 0.49 * step, 0.51 * step, 7.2 * step], [15.4 * step, 15.6 * step, H_MAX, 3 * step]])
    quantised = quantise_heightmap(heights, H_MAX, 16)
    np.testing.assert_array_equal(quantised.level_index, [[0, 0, 1, 7], [15, 0, 0, 3]])
    np.testing.assert_allclose(quantised.heights_m, quantised.level_index * step)


def test_etch_masks_add_up_to_each_features_depth_below_the_top_surface():
    rng = np.random.default_rng(1)
    quantised = quantise_heightmap(rng.uniform(0, H_MAX, (40, 40)), H_MAX, 16)
    masks = quantised.masks()
    assert len(masks) == 4 and all(mask.dtype == bool for mask in masks)
    etched = sum((2 ** b) * m.astype(int) for b, m in enumerate(masks))
    np.testing.assert_array_equal(etched, 15 - quantised.level_index)  # the highest level is not etched at all
    np.testing.assert_allclose((15 - etched) * quantised.step_m, quantised.heights_m)  # relief = the height map


def test_out_of_range_or_non_finite_heights_are_refused():
    with pytest.raises(ValueError, match="outside"):
        quantise_heightmap(np.array([[0.0, 2 * H_MAX]]), H_MAX, 16)
    with pytest.raises(ValueError, match="NaN"):
        quantise_heightmap(np.array([[np.nan]]), H_MAX, 16)
    with pytest.raises(ValueError, match="power of two"):
        quantise_heightmap(np.zeros((2, 2)), H_MAX, 12)


def test_efficiency_estimates():
    assert ideal_multilevel_efficiency(16) == pytest.approx(0.9872, abs=1e-4)
    assert ideal_multilevel_efficiency(2) == pytest.approx(0.405, abs=1e-3)
    heights = np.random.default_rng(0).uniform(0, H_MAX, (200, 200))
    assert quantisation_strehl(heights, heights, 1e7) == pytest.approx(1.0)
    wavelength = design_wavelength_m(H_MAX, lambda w: refractive_index("fused_silica", w))
    assert H_MAX * (refractive_index("fused_silica", wavelength) - 1) == pytest.approx(wavelength, rel=1e-9)
    phase_per_height = 2 * np.pi / wavelength * (refractive_index("fused_silica", wavelength) - 1)
    quantised = quantise_heightmap(heights, H_MAX, 16)
    # uniform quantisation error over one step: Strehl = sinc^2(1/16), as for the ideal kinoform
    assert quantisation_strehl(heights, quantised.heights_m, phase_per_height) == pytest.approx(
        ideal_multilevel_efficiency(16), abs=2e-3)


def test_the_simulated_report_counts_the_light_quantisation_sends_out_of_the_psf_window(tmp_path):
    """A blazed grating of 32 features of 6 um (the A7 profile) at 550 nm, quantised to 16 levels: its first order
    falls from sinc^2(1/32) to sinc^2(1/16) of the light, the rest going to orders 1 +- 16 k far outside the 255 px
    window, so the window holds 0.96 % less light in the same shape. The report compared unit-sum crops and said
    an L1 of 0.0000 (1.2e-6); it compares shares of the aperture's light now."""
    import json

    import OpenEXR

    from hdrcam.cli import main

    design_m = 550e-9
    h_max = design_m / (refractive_index("fused_silica", design_m) - 1)
    heights = np.tile(((np.arange(1527) % 32) + 0.5) / 32 * h_max, (1527, 1)).astype(np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "pixel_pitch_m": 6e-6}
    with OpenEXR.File(header, {"height_m": heights}) as file:
        file.write(str(tmp_path / "blaze.exr"))
    assert main(["fabricate", str(tmp_path / "blaze.exr"), "--profile", "sony-a7-zeiss50-rank1", "--simulate",
                 "--out", str(tmp_path / "fab")]) == 0
    report = json.loads((tmp_path / "fab" / "report.json").read_text())
    lost = 1 - ideal_multilevel_efficiency(16) / ideal_multilevel_efficiency(32)
    green_in_window = report["crop_energy_fraction_continuous_rgb"][1]
    assert report["psf_l1_difference_rgb"][1] == pytest.approx(lost * green_in_window, rel=0.1)
    assert report["crop_energy_fraction_quantised_rgb"][1] == pytest.approx(green_in_window * (1 - lost), rel=2e-3)
