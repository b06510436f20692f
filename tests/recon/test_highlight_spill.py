"""Unclipped pixels: the frame less the PSF-spread light of the clipped highlights' excess over the clip level
(an identity of Eq. 6: what remains is the scene with its highlights at the clip level, seen through the PSF)."""

from __future__ import annotations

import numpy as np
import torch

from hdrcam.optics.analytic import star
from hdrcam.recon.highlight_spill import subtract_highlight_spill
from hdrcam.recon.tiling import clipped_clusters, clipped_mask
from hdrcam.sensor import fft_convolve


def convolve(image: np.ndarray, psf: np.ndarray) -> np.ndarray:
    planes = fft_convolve(torch.from_numpy(image.transpose(2, 0, 1).copy()), torch.from_numpy(psf))
    return planes.numpy().transpose(1, 2, 0)


def test_with_the_true_highlights_the_unclipped_pixels_are_the_scene_clipped_at_one_seen_through_the_psf():
    psf = star(31, points=8)
    y, x = np.mgrid[:160, :200]
    scene = np.repeat((0.1 + 0.05 * np.sin(x / 5.0))[..., None], 3, axis=-1).astype(np.float32)
    scene[40:44, 50:54] = (90.0, 60.0, 30.0)
    frame = np.clip(convolve(scene, psf), 0.0, 1.0)
    clipped = clipped_mask(frame)
    rng = np.random.default_rng(0)
    guess = np.where(clipped[..., None], scene, rng.uniform(0, 5, scene.shape)).astype(np.float32)  # junk outside
    output = subtract_highlight_spill(frame, guess, psf, clipped)
    background = convolve(np.where(clipped[..., None], np.minimum(scene, 1.0), scene).astype(np.float32), psf)
    # float32 FFT round-off of a 90x highlight
    np.testing.assert_allclose(output[~clipped], background[~clipped], atol=5e-5)
    np.testing.assert_array_equal(output[clipped], scene[clipped])
    far = np.ones_like(clipped)
    far[40 - 15 - 4:44 + 15 + 4, 50 - 15 - 4:54 + 15 + 4] = False  # beyond the PSF's reach of the blob
    np.testing.assert_array_equal(output[far & ~clipped], frame[far & ~clipped])


def test_too_bright_highlights_clamp_the_background_at_zero_and_no_clipping_returns_the_frame():
    psf = star(31, points=8)
    frame = np.full((64, 64, 3), 0.01, np.float32)
    frame[30:32, 30:32] = 1.0
    clipped = clipped_mask(frame)
    output = subtract_highlight_spill(frame, np.full_like(frame, 256.0), psf, clipped)
    assert output.min() >= 0.0 and np.isfinite(output).all()
    dark = np.full((32, 32, 3), 0.2, np.float32)
    assert np.array_equal(subtract_highlight_spill(dark, dark * 7, psf, clipped_mask(dark)), dark)


def test_clusters_whose_crops_overlap_each_have_their_spill_removed():
    """An L-shaped lamp and a small one inside the L's bounding box, more than two PSF radii from it (two
    clusters): the L's crop holds the small lamp's reach, so a crop-by-crop overwrite would restore its spill."""
    psf = star(31, points=8)
    scene = np.full((200, 200, 3), 0.1, np.float32)
    scene[50:54, 50:54] = (80.0, 80.0, 80.0)  # first in raster order, so its crop is handled first
    scene[140:144, 40:144] = (90.0, 60.0, 30.0)
    scene[80:144, 140:144] = (90.0, 60.0, 30.0)
    frame = np.clip(convolve(scene, psf), 0.0, 1.0)
    clipped = clipped_mask(frame)
    clusters = clipped_clusters(clipped, 15)
    assert len(clusters) == 2
    (first, _), (second, _) = clusters
    in_both = np.zeros(clipped.shape, int)
    in_both[first] += 1
    in_both[second] += 1
    assert (in_both > 1).any()
    output = subtract_highlight_spill(frame, scene, psf, clipped)
    background = convolve(np.where(clipped[..., None], np.minimum(scene, 1.0), scene).astype(np.float32), psf)
    np.testing.assert_allclose(output[~clipped], background[~clipped], atol=1e-4)  # float32 FFTs of 2^8 lamps
