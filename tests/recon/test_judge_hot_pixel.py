"""A hot pixel beside a lamp must not veto the lamp's light (hdrcam.recon.consistency, the upper bound's slack).

A hot pixel reads white; whatever proposes it says at least white there, so the judge charges it the clip level
of own light, which its dark neighbours did not receive: the own-light term alone over-explains them. With the
slack y - P * B + 3 sigma + TOLERANCE negative there, the exact per-cluster scale (a minimum over the pixels the
excess reaches) was 0 wherever the lamp's spill touched those neighbours: a hot pixel 12-30 px from a lamp made
the judge keep none of it (seen on a dev scene of tools/independent_night_scenes.py;
tools/results/real-data/slack-floor). The slack is now floored at the noise allowance, max(y - P * B, 0) +
3 sigma + TOLERANCE: the veto is gone, but where the lamp's spill on the hot pixel's neighbours exceeds that
allowance the lamp is still cut in that channel (0.47-1.0 kept) - the own light B itself is not yet judged."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hdrcam.recon.consistency import NoiseModel, make_consistent
from hdrcam.sensor import fft_convolve
from hdrcam.train.checkpoint import load_model

NOISE = NoiseModel()


@pytest.fixture(scope="module")
def psf():
    return load_model().psf


def _capture(scene: np.ndarray, psf: np.ndarray) -> np.ndarray:
    planes = torch.from_numpy(np.ascontiguousarray(scene.transpose(2, 0, 1), np.float32))
    clean = fft_convolve(planes, torch.from_numpy(np.ascontiguousarray(psf, np.float32))).numpy().transpose(1, 2, 0)
    noisy = clean + NOISE.sigma(clean) * np.random.default_rng(0).standard_normal(clean.shape)
    return np.clip(noisy, 0.0, 1.0).astype(np.float32)


def _lamp_kept_beside_a_hot_pixel(psf: np.ndarray, offset_px: int) -> np.ndarray:
    """(3,) share of a 5 x 5 lamp's true excess (20 x white) the judge keeps, proposed exactly, with a hot pixel
    ``offset_px`` to its right."""
    scene = np.full((128, 128, 3), 0.01, np.float32)
    scene[62:67, 62:67] = 20.0  # a 5 x 5 lamp at 20 x white
    frame = _capture(scene, psf)
    hot = (64, 64 + offset_px)
    assert frame[hot].max() < 0.5  # the lamp's own light there is far below white: the pixel is hot, not lit
    frame[hot] = 1.0
    proposal = scene.copy()
    proposal[hot] = 1.0  # a clipped pixel is at least white: what any network proposes for it
    judged, _, _ = make_consistent(frame, proposal, psf, noise=NOISE)
    lamp = (slice(62, 67), slice(62, 67))
    assert judged[hot].min() >= 1.0  # the hot pixel keeps the clip level (the floor)
    return (judged[lamp] - 1.0).sum(axis=(0, 1)) / (scene[lamp] - 1.0).sum(axis=(0, 1))


@pytest.mark.parametrize("offset_px", [12, 18, 22, 26, 30])
def test_a_hot_pixel_beside_a_lamp_does_not_veto_the_lamps_light(psf, offset_px):
    kept = _lamp_kept_beside_a_hot_pixel(psf, offset_px)
    assert kept.min() >= 0.4, kept  # was 0 in every channel


@pytest.mark.xfail(strict=True, reason="known limit (module docstring): the hot pixel's own light is charged at the "
                   "clip level, so where the lamp's spill on its neighbours exceeds the noise allowance the lamp is "
                   "still cut in that channel")
@pytest.mark.parametrize("offset_px", [12, 22])
def test_a_hot_pixel_beside_a_lamp_leaves_the_lamps_light_as_proposed(psf, offset_px):
    kept = _lamp_kept_beside_a_hot_pixel(psf, offset_px)
    assert kept.min() >= 0.9, kept  # without the hot pixel 0.995
