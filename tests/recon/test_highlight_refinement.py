"""The streak fit recovers a clipped blob's brightness from the light its PSF spread onto unclipped pixels."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch

from hdrcam.optics.analytic import dirac, star
from hdrcam.recon.highlight_refinement import refine_highlight_amplitudes
from hdrcam.recon.tiling import clipped_mask
from hdrcam.sensor import fft_convolve

SIZE = 160


def disk(centre_yx: tuple[int, int], radius_px: float) -> np.ndarray:
    y, x = np.mgrid[:SIZE, :SIZE]
    return np.hypot(y - centre_yx[0], x - centre_yx[1]) <= radius_px


def capture(radiance: np.ndarray, psf: np.ndarray) -> np.ndarray:
    """Noise-free frame: the radiance convolved with the PSF, clipped at 1."""
    blurred = fft_convolve(torch.from_numpy(radiance.transpose(2, 0, 1)).float(), torch.from_numpy(psf).float())
    return blurred.clamp(0.0, 1.0).numpy().transpose(1, 2, 0)


def scene(blobs: list[tuple[np.ndarray, float]]) -> np.ndarray:
    y, x = np.mgrid[:SIZE, :SIZE]
    radiance = np.repeat((0.05 + 0.03 * np.sin(x / 7.0) * np.cos(y / 11.0))[..., None], 3, axis=-1)
    for mask, level in blobs:
        radiance[mask] = level
    return radiance.astype(np.float32)


def wrong_guess(truth: np.ndarray, clipped: np.ndarray, factors: list[tuple[np.ndarray, float]]) -> np.ndarray:
    """The truth with each blob's excess over 1 multiplied by a wrong factor (what an unsure network paints)."""
    guess = truth.copy()
    for mask, factor in factors:
        guess[mask] = 1.0 + factor * (truth[mask] - 1.0)
    return guess


def flux(image: np.ndarray, mask: np.ndarray) -> float:
    """Excess over white summed over a blob (relative radiance x pixels x channels): what the streaks measure."""
    return float(np.clip(image[mask] - 1.0, 0.0, None).sum())


def test_fit_recovers_the_brightness_of_two_neighbouring_blobs():
    psf = star(63, points=8)
    first, second = disk((60, 60), 4), disk((70, 100), 3)
    truth = scene([(first, 40.0), (second, 150.0)])
    frame = capture(truth, psf)
    clipped = clipped_mask(frame)
    guess = wrong_guess(truth, clipped, [(first, 5.0), (second, 0.2)])  # 196 and 30.8 painted
    refined, report = refine_highlight_amplitudes(frame, guess, psf, clipped, iterations=30, damping=1e-6, floor=0)
    assert report.blobs == 2 and report.clusters == 1
    _, labels = cv2.connectedComponents(clipped.astype(np.uint8))
    for label in (labels[60, 60], labels[70, 100]):
        blob = labels == label
        # noise-free data and no prior: the least-squares answer is the truth (the painted shapes are right)
        np.testing.assert_allclose(flux(refined, blob), flux(truth, blob), rtol=0.01)
    np.testing.assert_array_equal(refined[~clipped], guess[~clipped])  # unclipped pixels are never touched


def test_damping_moves_a_blob_most_of_the_way():
    psf = star(63, points=8)
    blob = disk((80, 80), 5)
    truth = scene([(blob, 20.0)])
    frame = capture(truth, psf)
    clipped = clipped_mask(frame)
    guess = wrong_guess(truth, clipped, [(blob, 10.0)])  # 191 painted where the truth is 20
    refined, _ = refine_highlight_amplitudes(frame, guess, psf, clipped, floor=0)
    assert abs(flux(refined, clipped) - flux(truth, clipped)) < 0.2 * abs(flux(guess, clipped) - flux(truth, clipped))
    held, _ = refine_highlight_amplitudes(frame, guess, psf, clipped)  # the floor holds faint evidence back
    assert flux(refined, clipped) < flux(held, clipped) < flux(guess, clipped)


def test_a_psf_without_tails_gives_no_evidence_and_keeps_the_brightness():
    psf = dirac(63)
    blob = disk((80, 80), 5)
    truth = scene([(blob, 20.0)])
    frame = capture(truth, psf)
    guess = wrong_guess(truth, clipped_mask(frame), [(blob, 3.0)])
    refined, report = refine_highlight_amplitudes(frame, guess, psf, clipped_mask(frame))
    assert report.median_scale == pytest.approx(1.0)
    np.testing.assert_allclose(flux(refined, blob), flux(guess, blob), rtol=1e-5)


def test_a_painted_spike_is_flattened_the_unpainted_halo_kept_and_the_brightness_kept():
    """81-pixel blob painted 2 over white, with one pixel 200 over and one at white (the network's halo): the
    cap (2 x the blob mean) and the flat share (1/2, over the 80 painted pixels) leave the spike at
    0.5 x 81 / 80 + 0.5 x 2 / (capped mean) times the blob's mean excess (it was 45 times)."""
    psf = dirac(63)
    blob = np.zeros((SIZE, SIZE), bool)
    blob[40:49, 40:49] = True
    guess = scene([(blob, 3.0)])
    guess[44, 44], guess[48, 48] = 201.0, 1.0
    frame = np.clip(guess, 0.0, 1.0)
    refined, _ = refine_highlight_amplitudes(frame, guess, psf, blob)
    excess = refined[blob] - 1.0
    mean = (79 * 2.0 + 200.0) / 81  # the painted blob mean excess
    capped_mean = (79 * 2.0 / mean + 2.0) / 81
    np.testing.assert_allclose(excess.max() / excess.mean(), 0.5 * 81 / 80 + 0.5 * 2.0 / capped_mean, rtol=1e-4)
    np.testing.assert_allclose(flux(refined, blob), flux(guess, blob), rtol=1e-5)
    np.testing.assert_array_equal(refined[48, 48], guess[48, 48])


def test_extremes_no_clipping_all_clipped_and_the_radiance_ceiling():
    psf = star(63, points=8)
    dark = np.zeros((SIZE, SIZE, 3), np.float32)
    refined, report = refine_highlight_amplitudes(dark, dark, psf, clipped_mask(dark))
    assert report.blobs == 0 and np.array_equal(refined, dark)

    white = np.ones((SIZE, SIZE, 3), np.float32)  # every pixel clipped: nothing to fit against
    guess = np.full_like(white, 300.0)
    refined, report = refine_highlight_amplitudes(white, guess, psf, clipped_mask(white))
    assert report.blobs == 1 and np.isfinite(refined).all() and refined.max() <= 256.0
