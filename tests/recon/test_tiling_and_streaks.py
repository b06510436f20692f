"""Tiled, scene-adaptive reconstruction and the clipped-streak check."""

import numpy as np
import pytest
import torch
from torch import nn

from hdrcam.optics.analytic import star
from hdrcam.recon.network import Reconstruction
from hdrcam.recon.streaks import check_streaks
import cv2

from hdrcam.recon.tiling import _reflected, plan_regions, reconstruct_frame
from hdrcam.sensor import fft_convolve


class PointwiseNet(nn.Module):
    """A stand-in network whose output is a pointwise function of its input (no context)."""

    def forward(self, ldr):
        hdr = ldr * 3.0 + ldr ** 2
        return Reconstruction(ldr, ldr, torch.ones_like(ldr), hdr)


@pytest.mark.parametrize("shape", [(100, 130), (300, 517), (16, 16)])
def test_tiles_blend_without_seams(shape):
    frame = np.random.default_rng(0).random((*shape, 3)).astype(np.float32)
    hdr, report = reconstruct_frame(PointwiseNet(), frame, psf_radius_px=5, adaptive=False, core_px=64, halo_px=32)
    assert np.allclose(hdr, frame * 3.0 + frame ** 2, atol=1e-5)  # the ramps sum to one everywhere
    assert report.windows == report.windows_run == -(-shape[0] // 64) * -(-shape[1] // 64)


def test_adaptive_skips_everything_on_a_frame_with_nothing_clipped():
    frame = np.random.default_rng(1).random((200, 300, 3)).astype(np.float32) * 0.9
    hdr, report = reconstruct_frame(PointwiseNet(), frame, psf_radius_px=10, core_px=64, halo_px=32)
    assert report.windows_run == 0 and np.array_equal(hdr, frame)
    assert "highlight recovery skipped" in report.summary()
    dark = np.zeros((64, 64, 3), np.float32)  # all-dark frame
    assert np.array_equal(reconstruct_frame(PointwiseNet(), dark, psf_radius_px=10)[0], dark)


def test_adaptive_runs_only_the_tiles_within_the_psf_reach_of_a_clipped_pixel():
    frame = np.full((256, 256, 3), 0.2, np.float32)
    frame[100, 100] = 1.0  # a single clipped pixel
    hdr, report = reconstruct_frame(PointwiseNet(), frame, psf_radius_px=10, core_px=64, halo_px=32)
    assert report.clipped_pixels == 1 and report.windows_run == 1 and report.windows == 16
    assert hdr[100, 100, 0] == pytest.approx(4.0)  # processed: 3 x 1 + 1
    assert hdr[10, 10, 0] == pytest.approx(0.2)  # passed through
    frame[:] = 1.0  # all clipped: every window runs, output finite
    hdr, report = reconstruct_frame(PointwiseNet(), frame, psf_radius_px=10, core_px=64, halo_px=32)
    assert report.windows_run == 16 and np.isfinite(hdr).all()


def test_regions_follow_the_clipped_patches_and_merge_when_their_halos_meet():
    frame = np.full((400, 900, 3), 0.2, np.float32)
    frame[100, 100] = frame[300, 800] = 1.0
    far = plan_regions(frame, psf_radius_px=10, core_px=64, halo_px=16)
    assert len(far) == 2
    reach = 10 + 8  # PSF radius + the cross-fade (blend = min(halo, core / 2) / 2)
    assert (far[0].top, far[0].left, far[0].height, far[0].width) == (100 - reach, 100 - reach, 2 * reach + 1,
                                                                      2 * reach + 1)
    frame[100, 150] = 1.0  # 50 px from the first: their windows' halos overlap, one region covers both
    near = plan_regions(frame, psf_radius_px=10, core_px=64, halo_px=16)
    assert len(near) == 2 and near[0].width == 50 + 2 * reach + 1
    assert plan_regions(frame * 0.5, psf_radius_px=10) == []
    assert len(plan_regions(frame * 0.5, psf_radius_px=10, adaptive=False)) == 1


def test_adaptive_output_is_the_network_near_clipped_pixels_and_the_frame_beyond_reach():
    frame = np.random.default_rng(2).random((300, 300, 3)).astype(np.float32) * 0.5
    frame[150, 150] = 1.0
    hdr, report = reconstruct_frame(PointwiseNet(), frame, psf_radius_px=10, core_px=64, halo_px=16)
    network = frame * 3.0 + frame ** 2
    yy, xx = np.mgrid[:300, :300]
    within = np.hypot(yy - 150, xx - 150) <= 10
    assert np.allclose(hdr[within], network[within], atol=1e-5)
    beyond = np.maximum(abs(yy - 150), abs(xx - 150)) > 10 + 8
    assert np.array_equal(hdr[beyond], frame[beyond])
    assert report.windows_run == 1 and report.network_pixels < report.full_frame_network_pixels / 10


@pytest.mark.parametrize("length", [1, 2, 7])
def test_reflected_indices_match_opencv_reflect_101(length):
    row = np.arange(length, dtype=np.float32)[None]
    padded = cv2.copyMakeBorder(row, 0, 0, 20, 20, cv2.BORDER_REFLECT_101) if length > 1 else np.zeros((1, 41))
    assert np.array_equal(_reflected(np.arange(-20, length + 20), length), padded[0].astype(int))


def _captured(radiance: float) -> tuple[np.ndarray, np.ndarray]:
    psf = star(63, points=8)
    scene = np.full((3, 200, 200), 0.1, np.float32)
    scene[:, 100:103, 100:103] = radiance
    scene[:, 20:22, 20:60] = 5.0  # a thin clipped sign far from the lamp
    frame = fft_convolve(torch.from_numpy(scene), torch.from_numpy(psf)).clamp(0, 1).permute(1, 2, 0).numpy()
    return frame, psf


def test_streak_check_is_quiet_when_only_the_core_clips():
    frame, psf = _captured(100.0)
    check = check_streaks(frame, psf, core_radius_px=3)
    assert check.clipped_streak_pixels == 0 and not check.mask.any() and check.warning() is None


def test_streak_check_finds_clipped_streaks_and_suggests_less_exposure():
    frame, psf = _captured(1e4)  # 9e4 in the core: its 8 streaks clip
    check = check_streaks(frame, psf, core_radius_px=3)
    assert check.clipped_streak_pixels > 50 and check.suggested_exposure_change_ev <= -1
    assert check.mask[101, 101 + 20] and not check.mask[21, 40]  # near the lamp, not at the sign
    assert "EV less exposure" in check.warning()
    # the suggestion is a lower bound: shortening the exposure by it clears at least part of the streaks
    reduced = np.clip(frame * 0 + _captured(1e4 * 2 ** check.suggested_exposure_change_ev)[0], 0, 1)
    assert check_streaks(reduced, psf, 3).clipped_streak_pixels < check.clipped_streak_pixels
