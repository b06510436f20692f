"""Previews (hdrcam.preview): the reduction a large image gets before it is tone-mapped, and the tone map."""

from __future__ import annotations

import warnings

import numpy as np

from hdrcam.preview import reduced_for_preview, tonemap_rgb


def test_a_large_image_is_reduced_by_a_whole_factor_to_block_means_in_linear_light():
    image = np.random.default_rng(0).random((100, 70, 3), np.float32) * 1e4
    small = reduced_for_preview(image, 40)  # factor 3: 33 x 23, the last row and column left out
    assert small.shape == (33, 23, 3) and small.dtype == np.float32
    blocks = image[:99, :69].reshape(33, 3, 23, 3, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(small, blocks, rtol=1e-5)
    assert reduced_for_preview(image, 100) is image


def reference_tonemap(hdr_rgb: np.ndarray, key: float, log_average: float) -> np.ndarray:
    """The preview's formula written out in float64: Reinhard on Rec. 709 luminance, then the sRGB curve."""
    rgb = np.nan_to_num(np.clip(np.asarray(hdr_rgb, np.float64), 0.0, None), posinf=0.0)
    luminance = rgb @ np.array([0.2126, 0.7152, 0.0722])
    scaled = luminance * key / log_average
    display = np.clip(rgb * (scaled / (1 + scaled) / np.maximum(luminance, 1e-12))[..., None], 0.0, 1.0)
    encoded = np.where(display <= 0.0031308, 12.92 * display,
                       1.055 * np.maximum(display, 0.0031308) ** (1 / 2.4) - 0.055)
    return np.round(encoded * 255).astype(np.uint8)


def assert_within_one_code_and_mostly_exact(hdr_rgb: np.ndarray, key: float, log_average: float,
                                            max_differing_fraction: float) -> None:
    """At most one code from the reference anywhere, and off by one in at most that fraction of the samples."""
    preview = tonemap_rgb(hdr_rgb, key=key, log_average=log_average).astype(int)
    difference = np.abs(preview - reference_tonemap(hdr_rgb, key, log_average))
    assert difference.max() <= 1
    assert np.mean(difference > 0) < max_differing_fraction


def test_tonemap_matches_the_float64_formula_to_one_code_from_1e_minus_6_to_1e3():
    rng = np.random.default_rng(1)
    level = np.geomspace(1e-6, 1e3, 200_000)
    grey = np.repeat(level[:, None], 3, axis=1)
    coloured = level[:, None] * rng.uniform(0.0, 3.0, (level.size, 3))  # saturated colours clip in some channels
    image = np.concatenate([grey, coloured]).reshape(400, 1000, 3).astype(np.float32)
    # 0.3 % differ; a table of 2 ** 14 cells would differ in 2.4 %, one of 2 ** 12 in 6 %
    assert_within_one_code_and_mostly_exact(image, key=0.18, log_average=0.5, max_differing_fraction=0.01)


def test_tonemap_matches_the_float64_formula_to_one_code_in_the_dark_end_of_the_srgb_curve():
    display = np.linspace(0.0, 0.01, 300_000)  # codes 0 to 25: the linear segment up to 0.0031308, then the steep power
    level = display / (1 - display)  # with log_average == key the Reinhard curve maps level to display
    image = np.repeat(level[:, None], 3, axis=1).reshape(300, 1000, 3).astype(np.float32)
    # 1.0 % differ; codes of the cells' lower edges (not centres) would differ in 1.7 %, 2 ** 14 cells in 4.5 %
    assert_within_one_code_and_mostly_exact(image, key=0.18, log_average=0.18, max_differing_fraction=0.015)
    assert tonemap_rgb(image, log_average=0.18).max() == 25


def test_tonemap_treats_nan_infinite_and_negative_samples_as_zero_and_leaves_its_input_alone():
    image = np.random.default_rng(2).uniform(0.0, 10.0, (6, 5, 3)).astype(np.float32)
    damaged = image.copy()
    damaged[0, 0] = [np.nan, np.inf, -np.inf]
    damaged[1, 1, 0] = -3.0
    damaged[2, 2, 2] = np.inf
    before = damaged.copy()
    zeroed = np.where(np.isfinite(damaged) & (damaged > 0), damaged, np.float32(0))
    preview = tonemap_rgb(damaged)
    np.testing.assert_array_equal(preview, tonemap_rgb(zeroed))  # the log-average ignores them too
    assert preview[0, 0].tolist() == [0, 0, 0]
    np.testing.assert_array_equal(damaged, before)


def test_an_empty_image_tonemaps_to_an_empty_preview():
    assert tonemap_rgb(np.zeros((10, 0, 3), np.float32), log_average=1.0).shape == (10, 0, 3)


def test_a_pixel_beyond_float32s_scaled_range_shows_white_not_black():
    """luminance x key / log-average overflowed float32 to inf, and inf / (1 + inf) is NaN: a 1e38 pixel on a
    dim background was drawn black."""
    image = np.full((8, 8, 3), 1e-3, np.float32)
    image[4, 4] = 1e38
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        preview = tonemap_rgb(image)
    assert preview[4, 4].tolist() == [255, 255, 255]
