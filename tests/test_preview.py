"""Previews (hdrcam.preview): the reduction a large image gets before it is tone-mapped."""

from __future__ import annotations

import numpy as np

from hdrcam.preview import reduced_for_preview


def test_a_large_image_is_reduced_by_a_whole_factor_to_block_means_in_linear_light():
    image = np.random.default_rng(0).random((100, 70, 3), np.float32) * 1e4
    small = reduced_for_preview(image, 40)  # factor 3: 33 x 23, the last row and column left out
    assert small.shape == (33, 23, 3) and small.dtype == np.float32
    blocks = image[:99, :69].reshape(33, 3, 23, 3, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(small, blocks, rtol=1e-5)
    assert reduced_for_preview(image, 100) is image
