"""Demosaicing (hdrcam.io.demosaic): every layout and method against known colours; the float bilinear path
against OpenCV's own integer conversion."""

from __future__ import annotations

import numpy as np
import pytest

import hdrcam.io.demosaic as demosaicing
from hdrcam.io.demosaic import METHODS, cfa_masks, demosaic

PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
COLOUR_DN = np.array([1000.0, 3000.0, 5000.0])


def _mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    return (cfa_masks(rgb.shape[:2], pattern).transpose(1, 2, 0) * rgb).sum(axis=-1)


@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("method", METHODS)
def test_a_flat_colour_comes_back_in_every_layout(pattern, method):
    bayer = _mosaic(np.broadcast_to(COLOUR_DN, (24, 32, 3)), pattern).astype(np.uint16)
    rgb = demosaic(bayer, pattern, method)
    assert rgb.dtype == np.float32 and rgb.shape == (24, 32, 3)
    np.testing.assert_allclose(rgb[4:-4, 4:-4], np.broadcast_to(COLOUR_DN, (16, 24, 3)), rtol=1e-3)


@pytest.mark.parametrize("pattern", PATTERNS)
def test_float_bilinear_is_opencvs_integer_bilinear(pattern):
    bayer = np.random.default_rng(0).integers(0, 16000, (40, 48)).astype(np.uint16)
    exact = demosaic(bayer.astype(np.float32), pattern)
    opencv = demosaic(bayer, pattern)  # cv2.cvtColor rounds to integers
    assert np.abs(exact - opencv)[1:-1, 1:-1].max() <= 0.5
    for channel, colour in enumerate("RGB"):  # measured samples are kept
        kept = cfa_masks(bayer.shape, pattern)[channel] == 1
        np.testing.assert_array_equal(exact[..., channel][kept], bayer[kept], err_msg=colour)


def test_edge_aware_refuses_float_data():
    with pytest.raises(ValueError, match="8/16-bit"):
        demosaic(np.zeros((8, 8), np.float32), "RGGB", "edge-aware")


@pytest.mark.parametrize("pattern", PATTERNS)
def test_float_bilinear_on_strips_is_the_whole_image(pattern, monkeypatch):
    bayer = np.random.default_rng(1).normal(0, 1000, (23, 18)).astype(np.float32)
    whole = demosaic(bayer, pattern)  # one strip
    monkeypatch.setattr(demosaicing, "FLOAT_STRIP_ROWS", 3)  # strips starting on either CFA row phase
    np.testing.assert_array_equal(demosaic(bayer, pattern), whole)


def test_menons_ringing_at_a_clipped_light_stays_within_the_measured_samples():
    bayer = np.full((64, 64), 0.02, np.float32)
    bayer[24:40, 24:40] = 1.0  # a clipped light with a sharp edge
    bayer[30:34, 10:14] = 0.5
    rgb = demosaic(bayer, "RGGB", "menon2007")
    assert rgb.min() >= 0.0 and rgb.max() <= 1.0  # the refinement rang to below zero and above white before
    assert np.allclose(rgb[24:40, 24:40][4:-4, 4:-4], 1.0)  # inside the light: white in every channel
