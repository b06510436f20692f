"""The destreak gate: the network's streak-free image is used only within the streaks' reach of a clipped light."""

from __future__ import annotations

import numpy as np
import torch

from hdrcam.recon.destreak import FEATHER_PX, destreak_frame, streak_zone
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.presets import preset


def frame_with_one_light() -> np.ndarray:
    rng = np.random.default_rng(0)
    frame = rng.uniform(0.05, 0.3, (96, 128, 3)).astype(np.float32)
    frame[40:43, 60:63] = 1.0
    return frame


def test_zone_is_one_within_reach_and_zero_beyond_the_feather():
    frame = frame_with_one_light()
    zone = streak_zone(frame, reach_px=10)
    assert zone[41, 61] == 1.0 and zone[41, 62 + 10] == 1.0  # 10 px from the light
    assert zone[41, 63 + 10 + FEATHER_PX + 1] == 0.0 and zone[0, 0] == 0.0
    assert np.all(streak_zone(np.zeros_like(frame), reach_px=10) == 0.0)


def test_gated_destreak_keeps_the_frame_outside_the_zone_and_passes_a_frame_without_lights():
    torch.manual_seed(0)
    network = ReconstructionNet(preset("fast"))
    frame = frame_with_one_light()
    clean, report = destreak_frame(network, frame, psf_radius_px=10)
    outside = streak_zone(frame, 10) == 0.0
    np.testing.assert_array_equal(clean[outside], frame[outside])
    assert not np.allclose(clean[~outside], frame[~outside]) and 0.0 < report.streak_zone_fraction < 0.2
    everywhere, _ = destreak_frame(network, frame, psf_radius_px=10, gate=False)
    assert not np.allclose(everywhere[outside], frame[outside])
    dark = np.full_like(frame, 0.1)
    unchanged, report = destreak_frame(network, dark, psf_radius_px=10)
    assert np.array_equal(unchanged, dark) and report.streak_zone_fraction == 0.0


def test_clipped_channels_keep_the_frames_value_gated_or_not():
    """A clipped value is a lower bound of its light: the network's I_U took 1251 of 4492 clipped values of a
    streaked frame below the clip level (down to 0.949), so a later reconstruct saw those lights as less clipped."""
    torch.manual_seed(0)
    network = ReconstructionNet(preset("fast"))
    frame = frame_with_one_light()
    clipped = frame >= 0.99
    for gate in (True, False):
        clean, _ = destreak_frame(network, frame, psf_radius_px=10, gate=gate)
        np.testing.assert_array_equal(clean[clipped], frame[clipped])
