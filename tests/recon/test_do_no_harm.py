"""Do no harm: :func:`hdrcam.api.reconstruct` on adversarial frames made from known HDR scenes.

Every frame is made with the forward model of the paper's Eq. 6, y = clip(P * H + eta, 0, 1): P the shipped
model's PSF (or the bare lens's, for a camera without a DOE), eta Gaussian shot + read noise of the simulated
A7 (hdrcam.recon.consistency.NoiseModel, the noise ``reconstruct`` assumes by default) with a fixed seed.
The reconstruction must never be worse than the frame it came from beyond the noise the frame itself carries:
where the recorded streaks do not support a highlight, the frame is the answer.
"""

from __future__ import annotations

import types

import cv2
import numpy as np
import pytest
import torch

from hdrcam.api import reconstruct
from hdrcam.evaluate.metrics import psnr_linear
from hdrcam.profiles import load_profile
from hdrcam.recon.colour_fill import fill_from_unclipped_channels
from hdrcam.recon.consistency import NoiseModel
from hdrcam.recon.tiling import CLIP_LEVEL
from hdrcam.sensor import fft_convolve
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import fixed_psf

NOISE = NoiseModel()
# The squared noise of a pixel recorded at white (sigma(1) = 0.0063): an excess over the clip level of this
# size is below what the camera can tell from white, so a reconstruction may differ from the frame's error by
# this much per pixel on average without having done harm.
WHITE_NOISE_MSE = float(NOISE.sigma(np.float64(1.0)) ** 2)
# The consistency step's per-pixel allowance for unclipped pixels (hdrcam.recon.consistency: K_SIGMA = 3
# standard deviations plus 0.002 of ADC / calibration tolerance), restated here so a loosened bound fails.
K_SIGMA, TOLERANCE = 3.0, 0.002


@pytest.fixture(scope="module")
def model():
    return load_model()


@pytest.fixture(scope="module")
def bare_lens_psf():
    """The camera without a DOE: a Dirac pattern through the simulated profile's f/9.8 lens (it keeps only
    0.53 / 0.65 / 0.80 of a point's light in its centre pixel, the rest in the diffraction skirt)."""
    return fixed_psf("dirac", load_profile("simulated"))


def convolve(scene: np.ndarray, psf: np.ndarray) -> np.ndarray:
    planes = torch.from_numpy(np.ascontiguousarray(scene.transpose(2, 0, 1), np.float32))
    return fft_convolve(planes, torch.from_numpy(np.ascontiguousarray(psf, np.float32))).numpy().transpose(1, 2, 0)


def capture(scene: np.ndarray, psf: np.ndarray, seed: int = 0) -> np.ndarray:
    """y = clip(P * H + eta, 0, 1), eta ~ N(0, sigma(P * H)^2) with the default camera noise."""
    clean = convolve(scene, psf)
    rng = np.random.default_rng(seed)
    noisy = clean + NOISE.sigma(clean) * rng.standard_normal(clean.shape)
    return np.clip(noisy, 0.0, 1.0).astype(np.float32)


def squared_error(image: np.ndarray, truth: np.ndarray, mask: np.ndarray | None = None) -> float:
    error = (np.asarray(image, np.float64) - truth) ** 2
    return float(error[mask].mean() if mask is not None else error.mean())


def check_invariants(result, frame: np.ndarray) -> None:
    """What holds for every frame: shapes, finiteness, confidence, the clip-level floor, never brighter than the
    network's own proposal or what the pixel's unclipped channels show, unclipped channels of clipped pixels
    untouched, spill only ever removed."""
    height, width = frame.shape[:2]
    hdr = result.hdr
    assert hdr.shape == frame.shape and hdr.dtype == np.float32 and np.isfinite(hdr).all()
    assert result.confidence.shape == (height, width)
    assert result.confidence.min() >= 0.0 and result.confidence.max() <= 1.0
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    clipped_channels = frame >= CLIP_LEVEL
    assert np.all(result.confidence[~clipped] == 1.0)  # what the frame recorded is never doubted
    assert 0.0 <= result.fallback_fraction <= 1.0
    # a clipped channel recorded at least the clip level: its radiance is at least 1
    assert np.all(hdr[clipped_channels] >= 1.0)
    # the frame can only take a proposed highlight down, never up, except to what the pixel's unclipped channels
    # show through the highlight's hue (hdrcam.recon.colour_fill; the frames here are white-balanced)
    shown, _ = fill_from_unclipped_channels(frame, np.ones_like(frame))
    ceiling = np.maximum(np.maximum(result.network_hdr, 1.0), shown)[clipped_channels]
    assert np.all(hdr[clipped_channels] <= ceiling * (1 + 1e-6)), float((hdr[clipped_channels] - ceiling).max())
    # a clipped pixel's channels that did not clip recorded their value: it is kept
    kept = clipped[..., None] & ~clipped_channels
    np.testing.assert_array_equal(hdr[kept], frame[kept])
    # unclipped pixels: the frame less a non-negative spill, never below 0
    assert np.all(hdr[~clipped] <= frame[~clipped]) and hdr.min() >= 0.0


def expected_unclipped(frame: np.ndarray, hdr: np.ndarray, psf: np.ndarray) -> np.ndarray:
    """The API's own definition of unclipped pixels: the frame less P * (hdr - 1)+ of the clipped pixels."""
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    highlights = np.where(clipped[..., None], np.clip(hdr - 1.0, 0.0, None), 0.0).astype(np.float32)
    return np.clip(frame - convolve(highlights, psf), 0.0, None)


def grid(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    return np.mgrid[0:height, 0:width].astype(np.float32)


# ---------------------------------------------------------------------------------------------------------
# a. a highlight barely above the clip level


@pytest.mark.parametrize("background", ["bright ramp 0.6-0.9", "mid-grey ramp 0.25-0.4"])
def test_a_highlight_barely_above_clip_is_not_made_worse_than_the_frame(model, background):
    """A disc at 1.05 (5 % above white) on a smooth background: its streaks are a few percent of a 5 % excess,
    far below the noise, so nothing supports a brighter highlight. The squared error of the reconstruction
    against the truth, on clipped pixels and on all pixels, may exceed the frame's by at most WHITE_NOISE_MSE
    (4.0e-5): the per-pixel squared noise at white, i.e. an error the camera cannot resolve. For scale, the
    frame's own error on clipped pixels is (1.05 - 1)^2 = 2.5e-3; a kept excess of just 0.1 would add 1e-2."""
    height = width = 128
    rows, columns = grid(height, width)
    low, high = (0.6, 0.9) if background.startswith("bright") else (0.25, 0.4)
    scene = np.repeat((low + (high - low) * columns / (width - 1))[..., None], 3, axis=-1)
    scene[(rows - 64) ** 2 + (columns - 64) ** 2 <= 22 ** 2] = 1.05
    frame = capture(scene, model.psf, seed=1)
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    assert clipped.sum() > 300  # the disc did clip: the test is about something

    result = reconstruct(frame, model)
    check_invariants(result, frame)
    frame_clipped, output_clipped = squared_error(frame, scene, clipped), squared_error(result.hdr, scene, clipped)
    frame_all, output_all = squared_error(frame, scene), squared_error(result.hdr, scene)
    assert output_clipped <= frame_clipped + WHITE_NOISE_MSE, (output_clipped, frame_clipped)
    assert output_all <= frame_all + WHITE_NOISE_MSE, (output_all, frame_all)


@pytest.mark.xfail(strict=True, raises=AssertionError, reason="known limit (tools/results/real-data/frame-border): "
                   "re-imaging the frame with no light beyond its border leaves the scene's own light near it to be "
                   "fitted as streaks; reading evidence only inside the PSF's reach of the border, or mirroring the "
                   "scene there, fixed this bar but cost the training photographs 0.11-0.13 dB (windows at the "
                   "border whose evidence lies there)")
@pytest.mark.parametrize("seed", [3, 4])
def test_a_barely_clipped_bar_near_the_frames_border_is_not_made_worse_than_the_frame(model, seed):
    """A 12 x 24 px bar at 1.05 on a 0.2-0.4 ramp, 18 px from the frame's bottom border and 14 px from its left,
    captured from a scene that goes on beyond the frame (as a camera's does). The pair proposes it 7-17 x too
    bright and the judge keeps all of it (85.2 -> 69.4 dB): re-imaging the frame from its own pixels misses the
    light from beyond the border, and the scene's own light left there fits as streaks (green and blue
    amplitudes of 86-88 proposals, z 16-21, residual variance 3-7 x the noise)."""
    margin, size = 40, 128
    rows, columns = grid(size + 2 * margin, size + 2 * margin)
    scene = np.repeat((0.2 + 0.2 * (columns - margin) / (size - 1))[..., None], 3, axis=-1)
    scene[margin + 98:margin + 110, margin + 14:margin + 38] = 1.05
    inside = (slice(margin, margin + size), slice(margin, margin + size))
    frame, truth = capture(scene, model.psf, seed=seed)[inside], scene[inside]
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    assert 150 < clipped.sum() < 288  # the bar's inside clips, its edge does not

    result = reconstruct(frame, model)
    check_invariants(result, frame)
    assert squared_error(result.hdr, truth, clipped) <= squared_error(frame, truth, clipped) + WHITE_NOISE_MSE
    assert squared_error(result.hdr, truth) <= squared_error(frame, truth) + WHITE_NOISE_MSE


@pytest.mark.parametrize("background", [
    "mid-grey ramp 0.25-0.4",
    pytest.param("bright ramp 0.6-0.9", marks=pytest.mark.xfail(
        strict=True, raises=AssertionError, reason="known limit (hdrcam/recon/consistency.py, 'Evidence'; "
        "tools/results/real-data/README.md, 'A barely clipped highlight's own edge'): on a surround this bright the "
        "judge alone still keeps 2.3-2.5 x the true excess of a proposal 11 x too bright")),
])
def test_a_barely_clipped_disc_proposed_eleven_times_too_bright_is_not_kept_by_the_judge_alone(model, background):
    """The disc of test a (1.05, 5 % above white) handed to the judge as a network 11 x too bright proposes it
    (1.55; a network trained on a GPU proposed 1.57): the disc's own unclipped edge - pixels a few deep that the
    lens core and the DOE's ring took below white - must not be read as streak evidence for it. Before the fit
    ring started beyond that bright edge, the blue channel's edge light fitted as 28 x the true streaks (z 5) and
    the cluster kept a third of the proposal: 3.7 x the true excess."""
    from hdrcam.recon.consistency import make_consistent

    height = width = 128
    rows, columns = grid(height, width)
    low, high = (0.6, 0.9) if background.startswith("bright") else (0.25, 0.4)
    scene = np.repeat((low + (high - low) * columns / (width - 1))[..., None], 3, axis=-1)
    scene[(rows - 64) ** 2 + (columns - 64) ** 2 <= 22 ** 2] = 1.05
    psf = np.asarray(model.psf, np.float32)
    for seed in (1, 2):
        frame = capture(scene, psf, seed=seed)
        clipped_channels = frame >= CLIP_LEVEL
        proposal = np.where(clipped_channels, 1.0 + 11.0 * (scene - 1.0), frame).astype(np.float32)
        kept, _, _ = make_consistent(frame, proposal, psf, noise=NOISE)
        clipped = clipped_channels.any(axis=-1)
        assert squared_error(kept, scene, clipped) <= squared_error(frame, scene, clipped) + WHITE_NOISE_MSE, seed


# ---------------------------------------------------------------------------------------------------------
# b. a large clipped window


@pytest.mark.parametrize("window", ["grey 3 -> 30", "warm (30, 10, 3)"])
def test_b_large_clipped_window_is_floored_bounded_and_removes_no_more_than_its_spill(model, window):
    """A 60 x 80 window far above white (radiance 3 -> 30 across it, or a warm 30 / 10 / 3) in a dim textured
    room. Truth for the unclipped pixels is the room seen through the PSF with the window at the clip level,
    B = P * min(H, 1) (hdrcam.recon.highlight_spill): the frame there is B plus the window's true spill plus
    noise, and the reconstruction removes its own estimate of that spill."""
    height, width = 144, 160
    rows, columns = grid(height, width)
    room = 0.05 * (1.0 + 0.5 * np.sin(columns / 7.0) * np.cos(rows / 11.0))
    scene = np.repeat(room[..., None], 3, axis=-1)
    if window.startswith("grey"):
        scene[42:102, 40:120] = np.linspace(3.0, 30.0, 80, dtype=np.float32)[None, :, None]
    else:
        scene[42:102, 40:120] = (30.0, 10.0, 3.0)
    frame = capture(scene, model.psf, seed=2)
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    assert clipped.sum() >= 60 * 80

    result = reconstruct(frame, model)
    hdr = result.hdr
    check_invariants(result, frame)  # finite, clipped channels >= 1, never above network_hdr on clipped pixels
    # (nor above what their unclipped channels show)

    # unclipped pixels are the frame less the kept highlights' own spill (the API's definition, Eq. 6) ...
    np.testing.assert_allclose(hdr[~clipped], expected_unclipped(frame, hdr, model.psf)[~clipped], atol=1e-4)
    # ... and not darker than the frame less the window's TRUE spill, P * (H - 1)+, beyond the consistency
    # step's own noise allowance (3 sigma + 0.002): the light removed from a room pixel is at most what the window
    # really sent there plus noise. (The frame's noise cancels: out - frame is minus the removed spill.)
    true_spill = convolve(np.clip(scene - 1.0, 0.0, None), model.psf)
    allowance = K_SIGMA * NOISE.sigma(frame) + TOLERANCE
    over = np.where(clipped[..., None], -np.inf, (frame - hdr) - true_spill - allowance)
    worst = np.unravel_index(int(np.argmax(over)), over.shape)
    assert over.max() <= 0.0, (f"{int((over > 0).sum())} room pixel-channels lost more than the true spill + "
                               f"3 sigma; worst at (row, column, channel) {tuple(int(i) for i in worst)}: removed "
                               f"{float((frame - hdr)[worst]):.4f}, true spill {float(true_spill[worst]):.4f}, "
                               f"sigma {float(NOISE.sigma(frame[worst])):.4f}")
    # the window itself: not further from the truth than the frame's 1.0 (the frame's error is huge here)
    assert squared_error(hdr, scene, clipped) <= squared_error(frame, scene, clipped) + WHITE_NOISE_MSE


# ---------------------------------------------------------------------------------------------------------
# c. a camera without a DOE


@pytest.mark.parametrize("judged_with", ["bare lens", pytest.param("the DOE's PSF (no --psf)", marks=pytest.mark.xfail(
    strict=True, raises=AssertionError, reason="known limit (README, 'A camera without a DOE'): judged through the "
    "DOE's PSF, the bare lens's compact light beside the disc's edge fits as streaks (z 7-17 in green and blue) and "
    "half the proposal is kept: -2.3 dB (bright ramp), -11.2 dB (dim ramp); on real photographs the same mismatch "
    "harmed none (tools/results/real-data/no-doe-defaults)"))])
@pytest.mark.parametrize("background", ["bright ramp 0.6-0.9", "dim ramp 0.2-0.4"])
def test_c_camera_without_doe_gets_no_invented_highlights(model, bare_lens_psf, background, judged_with):
    """The bare lens keeps a highlight's light in and right around it: there are no streaks to tell how bright
    a clipped region is. With highlights whose truth is only 1.0-1.1 (a disc peaking at 1.1, a bar at 1.05),
    the reconstruction - given the same bare-lens PSF, or the default (the shipped DOE's: a user of an ordinary
    camera who left out --psf) - may not invent brightness: the mean output excess over 1 on clipped channels
    stays below 0.1 (the truth's is about 0.05), and the linear PSNR (peak 2^8) is at most 0.3 dB below the
    frame's."""
    height = width = 128
    rows, columns = grid(height, width)
    low, high = (0.6, 0.9) if background.startswith("bright") else (0.2, 0.4)
    scene = np.repeat((low + (high - low) * columns / (width - 1))[..., None], 3, axis=-1)
    radius2 = (rows - 60) ** 2 + (columns - 70) ** 2
    disc = radius2 <= 20 ** 2
    scene[disc] = (1.0 + 0.1 * (1.0 - radius2[disc] / 20 ** 2))[:, None]
    scene[98:110, 14:38] = 1.05
    frame = capture(scene, bare_lens_psf, seed=3)
    clipped_channels = frame >= CLIP_LEVEL
    assert clipped_channels.sum() > 500
    assert scene[clipped_channels].max() <= 1.1 + 1e-6  # nothing clipped is brighter than 1.1

    result = reconstruct(frame, model, psf=bare_lens_psf if judged_with == "bare lens" else None)
    check_invariants(result, frame)
    excess = float((result.hdr[clipped_channels] - 1.0).mean())
    truth_excess = float((scene[clipped_channels] - 1.0).mean())
    frame_psnr, output_psnr = psnr_linear(frame, scene), psnr_linear(result.hdr, scene)
    assert excess < 0.1, f"mean excess {excess:.3f} on clipped channels (truth {truth_excess:.3f})"
    assert output_psnr >= frame_psnr - 0.3, f"PSNR {output_psnr:.2f} dB vs the frame's {frame_psnr:.2f} dB"


# ---------------------------------------------------------------------------------------------------------
# d. uniform frames, e. noise only


def test_d_uniform_grey_frame_is_returned_unchanged(model):
    frame = np.full((96, 112, 3), 0.5, np.float32)
    result = reconstruct(frame, model)
    check_invariants(result, frame)
    np.testing.assert_array_equal(result.hdr, frame)  # nothing clipped -> nothing changes
    assert np.all(result.confidence == 1.0) and result.fallback_fraction == 0.0


def test_d_all_white_frame_is_refused_before_any_network_runs(model, monkeypatch):
    """Every pixel clipped in every channel: no unclipped pixel recorded a streak or the scene, so any highlight
    would be invention - the frame is refused (bad input, one line), and no network is run on it."""
    from hdrcam.errors import InputError
    from hdrcam.recon import tiling

    monkeypatch.setattr(tiling, "hdr_forward", lambda *arguments, **options: pytest.fail("a network ran"))
    with pytest.raises(InputError, match="every pixel is clipped in every channel"):
        reconstruct(np.ones((96, 112, 3), np.float32), model)


def test_d_a_frame_white_in_two_channels_everywhere_is_still_reconstructed(model):
    """Red and green at white everywhere, blue recorded: not all white, so not refused; blue keeps the frame."""
    frame = np.ones((96, 112, 3), np.float32)
    frame[..., 2] = 0.4
    result = reconstruct(frame, model)
    check_invariants(result, frame)
    np.testing.assert_array_equal(result.hdr[..., 2], frame[..., 2])
    assert result.hdr[..., :2].min() >= 1.0


def test_e_noise_only_dark_frame_is_returned_unchanged(model):
    rng = np.random.default_rng(5)
    frame = np.clip(rng.normal(0.01, 0.003, (128, 128, 3)), 0.0, None).astype(np.float32)
    result = reconstruct(frame, model)
    check_invariants(result, frame)
    np.testing.assert_array_equal(result.hdr, frame)
    assert result.fallback_fraction == 0.0 and np.all(result.confidence == 1.0)


# ---------------------------------------------------------------------------------------------------------
# the frame as the final judge, whatever the network proposes (``reconstruct`` takes any object with ``network``
# and ``psf``): a stand-in network that proposes a fixed radiance on every clipped channel


class ConstantProposal(torch.nn.Module):
    """Proposes ``value`` on every channel the frame clipped and the frame elsewhere (the network's interface:
    (N, 3, H, W) frame -> an object whose ``hdr`` is (N, 3, H, W))."""

    def __init__(self, value: float):
        super().__init__()
        self.value = value

    def forward(self, ldr: torch.Tensor):
        return types.SimpleNamespace(hdr=torch.where(ldr >= CLIP_LEVEL, torch.full_like(ldr, self.value), ldr))


def dim_square_at(value: float) -> np.ndarray:
    """A 30 x 30 square at ``value`` in a dark room (0.02), 128 x 128."""
    scene = np.full((128, 128, 3), 0.02, np.float32)
    scene[50:80, 50:80] = value
    return scene


@pytest.mark.parametrize("optics", ["DOE", "bare lens"])
def test_a_proposal_the_frame_contradicts_is_cut_to_a_thousandth_of_its_cost(model, bare_lens_psf, optics):
    """Truth 1.05 on the square; a network proposing 2^8 there. Light of that excess would have lit the
    unclipped pixels around the square far beyond what they recorded, so the judge keeps at most 1 % of it and
    its squared error on the clipped pixels is below a thousandth of what keeping the proposal would cost,
    (256 - 1.05)^2 = 6.5e4 (the frame's own: 2.5e-3).

    Not asserted, because this DOE cannot support it: cutting a proposal of 2.0 for this 1.05 square to the
    frame. The rank-1 PSF keeps 94 % of a point's light within 3 px; an excess of 1 on the square sends so
    little light beyond the lens core (rms 0.001 at 3-10 px) that the square's own blurred edge, whose true
    radiance the frame did not record, explains it as well (rms 0.02 there; tools/results/real-data/README.md).
    With it the judge keeps about a third of such a proposal; the shipped network does not make it (test a)."""
    psf = model.psf if optics == "DOE" else bare_lens_psf
    scene = dim_square_at(1.05)
    frame = capture(scene, psf, seed=4)
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    assert clipped.sum() > 400
    result = reconstruct(frame, types.SimpleNamespace(network=ConstantProposal(256.0), psf=psf), psf=psf)
    check_invariants(result, frame)
    kept_whole_cost = squared_error(np.where(frame >= CLIP_LEVEL, 256.0, frame), scene, clipped)
    output_clipped = squared_error(result.hdr, scene, clipped)
    assert result.fallback_fraction >= 0.99, result.consistency.summary()
    assert output_clipped <= 1e-3 * kept_whole_cost, (output_clipped, kept_whole_cost)


def test_a_proposal_of_exactly_white_falls_back_nowhere(model):
    """A network that proposes no excess (the clip level, 1.0, on every clipped channel) proposes what the frame
    recorded: nothing is taken from it, so the output is the frame floored at 1, no pixel counts as fallen back
    and confidence is 1 everywhere (confidence 0 means 'fell back', api.Reconstruction)."""
    frame = capture(dim_square_at(3.0), model.psf, seed=6)
    clipped_channels = frame >= CLIP_LEVEL
    assert clipped_channels.any()
    result = reconstruct(frame, types.SimpleNamespace(network=ConstantProposal(1.0), psf=model.psf))
    check_invariants(result, frame)
    np.testing.assert_array_equal(result.hdr[clipped_channels], 1.0)
    assert result.consistency.proposed_excess == 0.0 and result.fallback_fraction == 0.0
    assert result.consistency.fallen_back_pixels == 0, result.consistency.summary()
    assert np.all(result.confidence == 1.0), f"confidence {result.confidence.min()} on clipped pixels"


def test_confidence_is_low_only_where_the_frame_reduced_the_proposal(model):
    """Shipped network, small lamps in a dark room: on clipped pixels whose every clipped channel kept the
    network's proposal (floored at 1) unchanged, nothing fell back: confidence is 1 there. And the report
    agrees with itself: a pixel whose proposal was kept whole is not counted among the fallen-back ones."""
    scene = np.full((128, 128, 3), 0.02, np.float32)
    scene[60:63, 60:63] = 200.0
    scene[30:32, 90:92] = (50.0, 80.0, 20.0)
    frame = capture(scene, model.psf, seed=0)
    result = reconstruct(frame, model)
    check_invariants(result, frame)
    clipped_channels = frame >= CLIP_LEVEL
    clipped = clipped_channels.any(axis=-1)
    proposal = np.maximum(result.network_hdr, 1.0)
    kept_whole = clipped & np.all(~clipped_channels | np.isclose(result.hdr, proposal, rtol=1e-5, atol=0.0), axis=-1)
    doubted = kept_whole & (result.confidence < 0.999)
    assert not doubted.any(), (f"{int(doubted.sum())} of {int(kept_whole.sum())} clipped pixels kept the "
                               f"proposal whole yet have confidence down to {result.confidence[doubted].min():.3g}; "
                               f"{result.consistency.summary()}")
    assert result.consistency.fallen_back_pixels <= int((clipped & ~kept_whole).sum())


# ---------------------------------------------------------------------------------------------------------
# refused inputs


def _nan_frame() -> np.ndarray:
    frame = np.full((32, 32, 3), 0.5, np.float32)
    frame[3, 4, 1] = np.nan
    return frame


@pytest.mark.parametrize("name, frame", [
    ("NaN pixel", _nan_frame()),
    ("HDR values of 5.0", np.full((32, 32, 3), 5.0, np.float32)),
    ("2-D array", np.full((32, 32), 0.5, np.float32)),
])
def test_reconstruct_refuses_frames_that_are_not_ldr_captures(model, name, frame):
    with pytest.raises(ValueError):
        reconstruct(frame, model)


def test_the_evidence_band_reaches_as_far_as_the_psf_spreads_its_light():
    """A Dirac keeps everything in its centre: the band stops just beyond the lens core. A PSF with 2 % of its
    light 20 px out along a streak is read 20 px out; with 0.5 % there the 99 % square is again the core."""
    from hdrcam.recon.consistency import EVIDENCE_INNER_PX, evidence_outer_px

    def psf_with(far_share: float) -> np.ndarray:
        psf = np.zeros((3, 63, 63), np.float32)
        psf[:, 31, 31] = 1.0 - far_share
        psf[:, 31, 51] = far_share
        return psf

    assert evidence_outer_px(psf_with(0.0)) == EVIDENCE_INNER_PX + 1
    assert evidence_outer_px(psf_with(0.02)) == 20
    assert evidence_outer_px(psf_with(0.005)) == EVIDENCE_INNER_PX + 1


def test_a_too_bright_edge_around_a_right_core_is_brought_close_to_the_truth_not_left_bright(model):
    """A 32 x 32 window at 6 x white on 0.2, noiseless, through the shipped PSF; the proposal is right in the
    window's core but 8 x too bright in its outer 3 px. The frame cannot tell this edge from a slightly brighter
    core exactly (the smallest change that satisfies it keeps the edge at 1.5 x), so the judge must err toward
    the frame: the edge at most 1.25 x its truth (a bound charging each pixel over its whole PSF footprint kept
    it at 1.3 x), the core kept, and the clipped pixels' squared error at most a quarter of the frame's (a 3 px
    local window halved the core: 0.72 of the frame's)."""
    from hdrcam.recon.consistency import make_consistent

    psf = np.asarray(model.psf, np.float32)
    truth = np.full((160, 160, 3), 0.2, np.float32)
    truth[64:96, 64:96] = 6.0
    frame = np.clip(convolve(truth, psf), 0.0, 1.0).astype(np.float32)
    clipped = frame >= CLIP_LEVEL
    true_excess = np.where(clipped, truth - 1.0, 0.0)
    edge = np.zeros(frame.shape[:2], bool)
    edge[64:96, 64:96] = True
    edge[67:93, 67:93] = False
    proposal = np.where(clipped, 1.0 + np.where(edge[..., None], 8.0, 1.0) * true_excess, frame).astype(np.float32)
    kept, _, _ = make_consistent(frame, proposal, psf, noise=NoiseModel())
    kept_excess = np.where(clipped, kept - 1.0, 0.0)
    assert kept_excess[edge].sum() <= 1.25 * true_excess[edge].sum()
    assert kept_excess[70:90, 70:90].sum() >= 0.5 * true_excess[70:90, 70:90].sum()
    squared_error = float(((kept_excess - true_excess)[clipped] ** 2).sum())
    assert squared_error <= 0.25 * float((true_excess[clipped] ** 2).sum())


def test_a_window_on_a_textured_facade_keeps_its_exact_light(model):
    """A 40 x 40 window at 4 x white on a facade of smoothed noise (0.25 +- 0.08), through the shipped PSF with
    the camera's noise, proposed exactly: the judge keeps its light (at least 0.97 of it on each of six facades).
    The facade's own residual under the evidence operator is texture correlated with the streaks, not noise; when
    the evidence fit's amplitude was itself the kept share, these windows kept 0.74-1.00 of their light."""
    from hdrcam.recon.consistency import make_consistent

    psf = np.asarray(model.psf, np.float32)
    for seed in range(6):
        rng = np.random.default_rng(seed)
        texture = cv2.GaussianBlur(rng.standard_normal((160, 160)).astype(np.float32), (0, 0), 2.0)
        truth = np.repeat((0.25 + 0.08 * texture / texture.std())[..., None], 3, axis=2).clip(0.02)
        truth[60:100, 60:100] = 4.0
        frame = capture(truth, psf, seed=seed)
        clipped = frame >= CLIP_LEVEL
        kept, _, _ = make_consistent(frame, np.where(clipped, truth, frame).astype(np.float32), psf)
        kept_share = np.where(clipped, kept - 1.0, 0.0).sum() / np.where(clipped, truth - 1.0, 0.0).sum()
        assert kept_share >= 0.97, (seed, kept_share)


@pytest.mark.parametrize("too_bright", [4.0, 16.0])
def test_a_too_bright_lamp_whose_ring_lies_6_px_out_is_lowered_to_the_truth_as_a_whole(too_bright):
    """A 4 x 4 lamp at 40 x white on a flat 0.2 background, noiseless, through a PSF that sends 10 % of each
    pixel's light to a square ring 6 px out. Proposed k times too bright, the judge must bring it to the truth:
    the ring pixels it over-lights are lit by the whole lamp, so the whole lamp is lowered, not the edge pixels
    nearest the ring (a 3 px local bound left a peaked lamp that the evidence fit then cut to 0.3 / 0.005 of
    the truth)."""
    from hdrcam.recon.consistency import make_consistent

    kept_excess, true_excess = _judged_ring_lamp(ring_px=6, too_bright=too_bright, make_consistent=make_consistent)
    assert kept_excess.sum() == pytest.approx(true_excess.sum(), rel=0.05)
    lamp = kept_excess[46:50, 46:50]
    assert lamp.max() <= 1.1 * lamp.min()  # lowered as a whole: no peak left by the bound


def _judged_ring_lamp(ring_px: int, too_bright: float, make_consistent) -> tuple[np.ndarray, np.ndarray]:
    """(kept excess, true excess) of a 4 x 4 lamp at 40 x white on 0.2 through a PSF sending 10 % of the light
    to a square ring ``ring_px`` out, proposed ``too_bright`` x its true excess."""
    size = 2 * ring_px + 3
    centre = size // 2
    psf = np.zeros((3, size, size), np.float32)
    ring = np.zeros((size, size), bool)
    low, high = centre - ring_px, centre + ring_px
    ring[low, low:high + 1] = ring[high, low:high + 1] = ring[low:high + 1, low] = ring[low:high + 1, high] = True
    psf[:, ring] = 0.1 / ring.sum()
    psf[:, centre, centre] = 0.9
    truth = np.full((96, 96, 3), 0.2, np.float32)
    truth[46:50, 46:50] = 40.0
    frame = np.clip(convolve(truth, psf), 0.0, 1.0).astype(np.float32)
    clipped = frame >= CLIP_LEVEL
    assert clipped.any(axis=-1).sum() == 16  # the ring itself stays below white: it is the evidence
    true_excess = np.where(clipped, truth - 1.0, 0.0)
    proposal = np.where(clipped, 1.0 + too_bright * true_excess, frame).astype(np.float32)
    kept, _, _ = make_consistent(frame, proposal, psf, noise=NoiseModel())
    return np.where(clipped, kept - 1.0, 0.0), true_excess


@pytest.mark.xfail(strict=True, reason="known failure (hdrcam/recon/consistency.py docstring; tools/results/real-data/"
                   "README.md, 'A local bound that reaches the DOE's ring'): with the ring 8 px out only the lamp's "
                   "nearest column is within the 5 px local bound of the over-lit ring pixels, so their light is "
                   "charged to it alone; the lamp ends peaked and the evidence fit cuts it to 0.67 (4 x) or 0.24 "
                   "(16 x) of the truth (rings 6, 7 and 9-12 px out are lowered as a whole)")
@pytest.mark.parametrize("too_bright", [4.0, 16.0])
def test_a_too_bright_lamp_whose_ring_lies_8_px_out_is_lowered_to_the_truth(too_bright):
    """As the 6 px ring lamp, with the ring 8 px out (toward the frame: a safe failure, but a loss)."""
    from hdrcam.recon.consistency import make_consistent

    kept_excess, true_excess = _judged_ring_lamp(ring_px=8, too_bright=too_bright, make_consistent=make_consistent)
    assert kept_excess.sum() == pytest.approx(true_excess.sum(), rel=0.05)


def evaluated_crop(folder, photograph, name: str, **options) -> dict[str, float]:
    """`hdrcam evaluate`'s protocol on one photograph linked into ``folder`` as ``name`` (the crop is seeded by the
    name): linear PSNR (dB) per method, shipped checkpoint; ``options`` go to evaluate_models (partner=None)."""
    from hdrcam.data.scenes import SceneSource
    from hdrcam.evaluate.scoring import evaluate_models

    (folder / name).symlink_to(photograph)
    rows, _ = evaluate_models({"hdrcam": load_model()}, SceneSource(folder), size_px=512, count=1, examples=0,
                              **options)
    return {row.method: row.metrics["psnr_linear"] for row in rows}


@pytest.mark.xfail(strict=True, raises=AssertionError, reason="known failure of the judge alone "
                   "(tools/results/real-data/README.md, 'Where "
                   "the judge leaks'): the shipped network without its partner paints a window onto an overcast sky "
                   "up to 14 x white and the frame cannot refute it (-3.07 dB with the mirror agreement); strict, "
                   "so a fix of the judge shows up as a failure to remove this mark")
def test_the_judge_alone_does_not_refute_a_window_the_single_network_paints(tmp_path, shared_data):
    psnr_db = evaluated_crop(tmp_path, shared_data / "hdr-train" / "3d-demo-data__peppermint_powerplant_1k.hdr",
                             "photo.hdr", partner=None)
    assert psnr_db["hdrcam"] >= psnr_db["ldr"] - 0.3


def test_a_real_window_onto_an_overcast_sky_is_not_made_worse_than_the_frame(tmp_path, shared_data):
    """`hdrcam evaluate`'s protocol on one real photograph (a training photograph: the networks saw it). The
    shipped network alone paints the window up to 14 x white and the frame cannot refute it (-8.6 dB; -3.07
    with the mirror agreement; tools/results/real-data/README.md, 'Where the judge leaks'); its partner does
    not paint it, and the default pair keeps only what both paint there (+0.07)."""
    psnr_db = evaluated_crop(tmp_path, shared_data / "hdr-train" / "3d-demo-data__peppermint_powerplant_1k.hdr",
                             "photo.hdr")
    assert psnr_db["hdrcam"] >= psnr_db["ldr"] - 0.3


def test_a_sky_barely_clipped_in_blue_is_not_made_worse_than_the_frame(tmp_path, shared_data):
    """`hdrcam evaluate`'s protocol on another crop of a training photograph (a crop is seeded by the file's
    name): MtTamNorth's sky clips in blue only, its truth 1.01 there, and the capture scores 90 dB. The pair
    proposes 3.5 x the true excess; the evidence fit, reading the sky's own gradient (a = 1043 +- 230 times
    the proposal), kept all of it: -0.39 dB. Streaks the ring cannot resolve keep nothing (consistency.py,
    'Evidence'; tools/results/real-data/resolvable-evidence)."""
    psnr_db = evaluated_crop(tmp_path, shared_data / "hdr-train" / "openexr-images__MtTamNorth.exr",
                             "openexr-images__MtTamNorth--v2.exr")
    assert psnr_db["ldr"] > 85.0  # the crop the test is about: highlights barely above white
    assert psnr_db["hdrcam"] >= psnr_db["ldr"] - 0.1, psnr_db


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="known limit (tools/results/real-data/stress-crops): the streaks confirm this cloud's "
                   "light (z 12-28) but not where in the blob it lies; the networks paint a bright ellipse at the "
                   "blob's far end where the truth is brightest at the other (correlation 0.15): -2.21 dB. A flat "
                   "fill of the same light would gain; strict, so a fix shows up as a failure to remove this mark")
def test_an_overcast_sky_whose_networks_misplace_its_brightest_cloud_is_not_made_worse_than_the_frame(
        tmp_path, shared_data):
    """`hdrcam evaluate`'s protocol on another crop of a training photograph (seeded by the file's name): a
    bright cloud of ~4,000 clipped pixels, truth 1.0-2.2."""
    psnr_db = evaluated_crop(tmp_path, shared_data / "hdr-train" / "pmndrs-assets__kloofendal_overcast_1k.hdr",
                             "pmndrs-assets__kloofendal_overcast_1k--v9.hdr")
    assert psnr_db["hdrcam"] >= psnr_db["ldr"] - 0.3, psnr_db


def test_a_lamp_whose_streaks_confirm_it_keeps_its_core_and_the_shape_cap_applies_without_that_evidence(
        model, monkeypatch, cut_evidence_share):
    """A 7 x 7 lamp on 0.05 (noise as the camera's), its centre pixel at 400 x white over a rim at 3 x: the core is
    ~50 x its blob's mean excess. Proposed exactly, through the shipped DOE, its streaks give the evidence
    fit z far above STRONG_EVIDENCE_Z, so the judge keeps the core; where the evidence keeps less than
    STRONG_EVIDENCE_SHARE of a channel the cap applies; with the exemption switched off the shape cap cuts the
    core to SHAPE_CAP x the blob's mean (what cost night scenes most)."""
    from hdrcam.recon import consistency

    psf = np.asarray(model.psf, np.float32)
    truth = np.full((128, 128, 3), 0.05, np.float32)
    truth[61:68, 61:68] = 3.0
    truth[64, 64] = 400.0
    frame = capture(truth, psf)
    clipped = frame >= CLIP_LEVEL
    proposal = np.where(clipped, np.maximum(truth, 1.0), frame).astype(np.float32)

    def kept_core() -> float:
        kept, _, _ = consistency.make_consistent(frame, proposal, psf, noise=NOISE)
        return float(kept[64, 64].mean())

    assert kept_core() >= 0.8 * 400.0
    cap = max(1.0 + consistency.SHAPE_CAP * float((proposal[..., c] - 1.0)[clipped[..., c]].mean()) for c in range(3))
    with monkeypatch.context() as patched:  # strong z, but the evidence keeps too little of the light
        cut_evidence_share(patched)
        assert kept_core() <= cap * (1.0 + 1e-5)
    monkeypatch.setattr(consistency, "STRONG_EVIDENCE_Z", np.inf)
    assert kept_core() <= cap * (1.0 + 1e-5) < 0.15 * 400.0


@pytest.mark.parametrize(("lamp_px", "level"), [(5, 30.0), (3, 200.0)])
def test_a_lamp_proposed_exactly_keeps_its_light_though_its_spill_clips_dim_neighbours(model, lamp_px, level):
    """A square lamp on 0.05 through the shipped PSF, with the camera's noise: its spill clips pixels around
    it whose own radiance is 0.05 (most of the clipped pixels). Proposed exactly, the judge must keep its light
    to within 3 %: those neighbours hold their own light, not the clip level's (charging them at 1 kept 0.74 of
    the 5 px lamp at 30 x white and 0.63 of the 3 px lamp at 200 x)."""
    from hdrcam.recon.consistency import make_consistent

    psf = np.asarray(model.psf, np.float32)
    truth = np.full((128, 128, 3), 0.05, np.float32)
    low = 64 - lamp_px // 2
    truth[low:low + lamp_px, low:low + lamp_px] = level
    frame = capture(truth, psf)
    clipped = frame >= CLIP_LEVEL
    assert (clipped & (truth < 1.0)).any(axis=-1).sum() > clipped.any(axis=-1).sum() / 2  # spill clips them
    proposal = np.where(clipped, truth, frame).astype(np.float32)
    kept, _, _ = make_consistent(frame, proposal, psf, noise=NOISE)
    kept_excess = float(np.where(clipped, kept - 1.0, 0.0).sum())
    true_excess = float(np.where(clipped, np.maximum(truth, 1.0) - 1.0, 0.0).sum())
    assert kept_excess == pytest.approx(true_excess, rel=0.03)


def test_light_a_proposal_moves_from_dark_clipped_pixels_into_a_peak_is_not_kept_above_the_truth(model):
    """A 13 x 13 window at 3 x white on 0.05 through the shipped PSF, with the camera's noise, proposed as 0 on
    its clipped pixels (the bound then charges them no light of their own: B = min(estimate, 1) = 0) and
    8 x its whole excess painted into the central 5 x 5. The judge keeps the proposal's excess at most at the
    truth's (the shape cap and the evidence share hold it there, 0.56 of the truth; the upper bound is slack)."""
    from hdrcam.recon.consistency import make_consistent

    psf = np.asarray(model.psf, np.float32)
    truth = np.full((128, 128, 3), 0.05, np.float32)
    truth[58:71, 58:71] = 3.0
    frame = capture(truth, psf)
    clipped = frame >= CLIP_LEVEL
    true_excess = float(np.where(clipped, np.maximum(truth, 1.0) - 1.0, 0.0).sum())
    proposal = np.where(clipped, 0.0, frame).astype(np.float32)
    peak = clipped[62:67, 62:67]
    proposal[62:67, 62:67] = np.where(peak, 1.0 + 8.0 * true_excess / peak.sum(), proposal[62:67, 62:67])
    kept, _, _ = make_consistent(frame, proposal, psf, noise=NOISE)
    assert float(np.where(clipped, kept - 1.0, 0.0).sum()) <= true_excess


def test_a_white_lamp_keeps_its_colour_whatever_the_channels_evidence_says(model, monkeypatch):
    """A white lamp proposed exactly whose evidence fit came out per channel as (0, 1, 1) - the demo's white lamps
    were kept as (1, 29, 26), cyan cores: the cluster keeps one share, the mean of its channels', so its kept
    excess has the proposal's colour."""
    from hdrcam.recon import consistency

    psf = np.asarray(model.psf, np.float32)
    truth = np.full((128, 128, 3), 0.05, np.float32)
    truth[61:68, 61:68] = 20.0
    frame = capture(truth, psf)
    clipped = frame >= CLIP_LEVEL
    proposal = np.where(clipped, np.maximum(truth, 1.0), frame).astype(np.float32)
    fitted = consistency._evidence_shares
    monkeypatch.setattr(consistency, "_evidence_shares",
                        lambda *arguments: (np.array([0.0, 1.0, 1.0], np.float32) * fitted(*arguments)[0],
                                            fitted(*arguments)[1]))
    kept, _, _ = consistency.make_consistent(frame, proposal, psf, noise=NOISE)
    core = kept[62:67, 62:67].reshape(-1, 3).mean(axis=0) - 1.0
    assert core.min() > 0.5 * core.max(), core  # red kept alongside green and blue, not left at the clip level


def test_a_light_clipped_in_one_channel_keeps_only_what_that_channels_evidence_supports(model):
    """A red light 1.3 x white, clipped in red alone, proposed at 5: its streaks are far below the noise (red share
    0), but green and blue, with no excess to fit, counted as share 1 in the cluster's mean - red kept 2/3 of the
    bounded proposal, 2.88 against the frame's 1.0 and the truth 1.3 (worse than the frame)."""
    from hdrcam.recon.consistency import make_consistent

    psf = np.asarray(model.psf, np.float32)
    truth = np.full((96, 96, 3), 0.2, np.float32)
    truth[46:49, 46:49, 0] = 1.3
    frame = capture(truth, psf, seed=1)
    clipped = frame >= CLIP_LEVEL
    assert clipped[..., 0].any() and not clipped[..., 1:].any()
    proposal = frame.copy()
    proposal[..., 0] = np.where(clipped[..., 0], 5.0, frame[..., 0])
    kept, _, _ = make_consistent(frame, proposal, psf, noise=NOISE)
    spot = clipped[..., 0]
    assert squared_error(kept[..., 0], truth[..., 0], spot) <= squared_error(frame[..., 0], truth[..., 0], spot) + \
        WHITE_NOISE_MSE


def test_a_highlight_whose_evidence_ring_is_empty_keeps_the_frame(model):
    """A 5 x 5 frame: every unclipped pixel lies within EVIDENCE_INNER_PX of the light, so no pixel could show its
    streaks, yet the empty ring read as 'nothing proposed' (share 1) and a proposal of 200 was kept at 9.2 for a
    light twice white."""
    from hdrcam.recon.consistency import make_consistent

    psf = np.asarray(model.psf, np.float32)
    truth = np.full((5, 5, 3), 0.2, np.float32)
    truth[2, 2] = 2.0
    frame = capture(truth, psf)
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    assert clipped.any()
    kept, confidence, _ = make_consistent(frame, np.where(clipped[..., None], 200.0, frame).astype(np.float32), psf,
                                          noise=NOISE)
    np.testing.assert_allclose(kept[clipped], 1.0, atol=1e-6)
    assert np.all(confidence[clipped] == 0.0)


@pytest.mark.parametrize("psf_px", [7, 63])
def test_a_dirac_psf_sends_no_light_to_witness_so_a_proposal_falls_back(psf_px):
    """A user's --psf that is a delta: no unclipped pixel can see a highlight, but the FFT's round-off (1e-7 of
    the peak) counted thousands of witnesses and was fitted as evidence - a proposal of 200 kept at 67-200."""
    from hdrcam.recon.consistency import make_consistent

    psf = np.zeros((3, psf_px, psf_px), np.float32)
    psf[:, psf_px // 2, psf_px // 2] = 1.0
    rng = np.random.default_rng(3)
    truth = (0.2 + 0.4 * rng.random((96, 96, 1)) * np.ones(3)).astype(np.float32)
    truth[40:44, 50:54] = 2.0
    frame = capture(truth, psf)
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    kept, _, _ = make_consistent(frame, np.where(clipped[..., None], 200.0, frame).astype(np.float32), psf,
                                 noise=NOISE)
    np.testing.assert_allclose(kept[clipped], 1.0, atol=1e-6)


# A hot pixel beside a lamp must not cut the lamp's light (hdrcam.recon.consistency, "Defects"). A hot pixel reads
# white; whatever proposes it says at least white there. Charged that own light, which its dark neighbours never
# received, the judge found the neighbours over-explained: before the slack floor (tools/results/real-data/
# slack-floor) a hot pixel 12-30 px from a lamp made it keep none of the lamp (a veto, seen on a dev scene of
# tools/independent_night_scenes.py); after it, 0.47-1.0 per channel. A clipped speck that no light through the PSF
# explains (with a margin for a calibrated PSF) is now judged a sensor defect: no own light, no excess
# (tools/results/real-data/hot-pixel). A dead pixel beside a lamp is a known limit.

LAMP = (slice(62, 67), slice(62, 67))  # a 5 x 5 lamp at 20 x white in the middle of a 128 x 128 frame


def _lamp_scene() -> np.ndarray:
    scene = np.full((128, 128, 3), 0.01, np.float32)
    scene[LAMP] = 20.0
    return scene


def _lamp_share(judged: np.ndarray, scene: np.ndarray) -> np.ndarray:
    """(3,) share of the lamp's true excess that ``judged`` keeps."""
    return (judged[LAMP] - 1.0).sum(axis=(0, 1)) / (scene[LAMP] - 1.0).sum(axis=(0, 1))


def _lamp_kept_beside_a_hot_pixel(psf: np.ndarray, offset_px: int) -> np.ndarray:
    """(3,) share of a 5 x 5 lamp's true excess (20 x white) the judge keeps, proposed exactly, with a hot pixel
    ``offset_px`` to its right."""
    from hdrcam.recon.consistency import make_consistent

    scene = _lamp_scene()
    frame = capture(scene, psf)
    hot = (64, 64 + offset_px)
    assert frame[hot].max() < 0.5  # the lamp's own light there is far below white: the pixel is hot, not lit
    frame[hot] = 1.0
    proposal = scene.copy()
    proposal[hot] = 1.0  # a clipped pixel is at least white: what any network proposes for it
    judged, _, _ = make_consistent(frame, proposal, psf, noise=NOISE)
    assert judged[hot].min() >= 1.0  # the hot pixel keeps the clip level (the floor)
    return _lamp_share(judged, scene)


@pytest.mark.parametrize("offset_px", [12, 18, 22, 26, 30])
def test_a_hot_pixel_beside_a_lamp_leaves_the_lamps_light_as_proposed(model, offset_px):
    kept = _lamp_kept_beside_a_hot_pixel(model.psf, offset_px)
    assert kept.min() >= 0.9, kept  # without the hot pixel 0.995; 0 before the slack floor, 0.47-1.0 after it


def _lamp_kept_beside_a_dead_pixel(psf: np.ndarray, offset_px: int, black_point: bool = False,
                                   listed: bool = False) -> np.ndarray:
    """(3,) share of a 5 x 5 lamp's true excess (20 x white) the judge keeps, proposed exactly, with a pixel
    ``offset_px`` to its right reading 0 (a dead pixel; ``listed``: named in a bad-pixel list and repaired) - or,
    with ``black_point``, a scene point of no light there, captured as it is."""
    from hdrcam.io.bad_pixels import repair_rgb
    from hdrcam.recon.consistency import make_consistent

    scene = _lamp_scene()
    if black_point:
        scene[64, 64 + offset_px] = 0.0
    frame = capture(scene, psf)
    if not black_point:
        frame[64, 64 + offset_px] = 0.0
    if listed:
        bad = np.zeros(frame.shape[:2], bool)
        bad[64, 64 + offset_px] = True
        frame = repair_rgb(frame, bad)[0]
    judged, _, _ = make_consistent(frame, scene, psf, noise=NOISE)
    return _lamp_share(judged, scene)


@pytest.mark.xfail(strict=True, reason="known limit (hdrcam/recon/consistency.py, 'Defects'): a dead pixel's slack is "
                   "the noise allowance and the exact per-cluster scale a minimum over pixels, so the lamp keeps "
                   "0.04-0.92 per channel (5-20 px); a bound for any scene refutes it only within ~6 px, and not "
                   "robustly to a calibrated PSF (tools/results/real-data/hot-pixel)")
@pytest.mark.parametrize("offset_px", [5, 6, 10, 20])
def test_a_dead_pixel_beside_a_lamp_leaves_the_lamps_light_as_proposed(model, offset_px):
    kept = _lamp_kept_beside_a_dead_pixel(model.psf, offset_px)
    assert kept.min() >= 0.9, kept  # without the dead pixel 0.995


@pytest.mark.parametrize("offset_px", [3, 4, 5, 6, 10, 20])
def test_a_listed_dead_pixel_beside_a_lamp_leaves_the_lamps_light_as_proposed(model, offset_px):
    """The known limit above, with the dead pixel in the camera's bad-pixel list (``reconstruct --bad-pixels``):
    repaired from its neighbours before the judge sees the frame, it no longer refutes the lamp."""
    assert _lamp_kept_beside_a_dead_pixel(model.psf, offset_px, listed=True).min() >= 0.9


@pytest.mark.parametrize("offset_px", [4, 5, 6])
def test_a_black_scene_point_beside_a_lamp_leaves_the_lamps_light_as_proposed(model, offset_px):
    """A point of the scene with no light, captured through the PSF, receives the lamp's light like its
    neighbours: the frame there is consistent with the lamp, unlike a dead pixel's."""
    assert _lamp_kept_beside_a_dead_pixel(model.psf, offset_px, black_point=True).min() >= 0.9


def _specks_called_defects(psf: np.ndarray, ground: float, specks: dict[tuple[int, int], float],
                           hot: list[tuple[int, int]]) -> set[tuple[int, int]]:
    """The pixels of a 64 x 64 ``ground`` frame, captured with point lights ``specks`` ({pixel: radiance}) and
    then ``hot`` pixels forced to white, that the judge calls sensor defects."""
    from hdrcam.recon.consistency import _defects, _Kernel

    scene = np.full((64, 64, 3), ground, np.float32)
    for pixel, radiance in specks.items():
        scene[pixel] = radiance
    frame = capture(scene, psf)
    for pixel in hot:
        frame[pixel] = 1.0
    defects = _defects(frame, frame >= CLIP_LEVEL, _Kernel(np.asarray(psf, np.float32)), NOISE)
    return {tuple(int(index) for index in pixel) for pixel in np.argwhere(defects)}


@pytest.mark.parametrize("ground", [0.01, 0.03])
def test_hot_pixels_on_a_dark_ground_are_called_defects(model, ground):
    """Dark: below the 0.05-0.07 of white a pixel's light sends each nearest neighbour through this PSF (on a
    brighter ground a hot pixel cannot be told from light, and its own light over-explains nothing there)."""
    hot = [(20, 20), (40, 40), (40, 41), (41, 40), (41, 41)]  # one hot pixel and a 2 x 2 cluster of them
    assert _specks_called_defects(model.psf, ground, {}, hot) == set(hot)


@pytest.mark.parametrize("ground", [0.01, 0.4])
def test_real_point_lights_that_clip_are_not_called_defects(model, ground):
    """A point at 3 x white, one that barely clips (its centre receives 1.02 of white in the channel that clips
    first) and one at 15 x white whose red neighbours clip from its light alone (a 4-pixel T; charging each
    of them the clip level called such points defects on development night scenes): their neighbours received
    their light, so the frame cannot refute them."""
    psf = np.asarray(model.psf, np.float32)
    centre = psf.shape[-1] // 2
    barely = 1.02 / float(psf[:, centre, centre].max())
    frame_points = {(20, 20): 3.0, (40, 40): barely, (20, 44): 15.0}
    assert _specks_called_defects(psf, ground, frame_points, []) == set()


@pytest.mark.parametrize("site", [(0, 0), (0, 1), (1, 0), (1, 1)])
def test_a_hot_photosite_in_the_real_arw_is_called_a_defect_after_demosaicing(model, shared_data, site):
    """A photosite of the real A7R III ARW forced to the white level, inside its darkest 64 x 64 block, at each
    position of the 2 x 2 CFA tile: demosaicing spreads it to its nearest neighbours (a quarter to a half of
    white), not as far as the PSF would spread light, so the frame still refutes it - and only it."""
    import dataclasses

    from hdrcam.io.ldr_frame import raw_relative_rgb
    from hdrcam.io.raw import read_raw
    from hdrcam.recon.consistency import _defects, _Kernel

    path = shared_data / "raw" / "sony-ilce7rm3-DSC2164.ARW"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    raw = read_raw(path)
    height, width = (side // 64 * 64 for side in raw.bayer_dn.shape)
    blocks = raw.bayer_dn[:height, :width].reshape(height // 64, 64, width // 64, 64).mean(axis=(1, 3))
    block_row, block_column = np.unravel_index(np.argmin(blocks), blocks.shape)
    top, left = max(block_row * 64 - 32, 0), max(block_column * 64 - 32, 0)  # even: the CFA phase is kept
    bayer = raw.bayer_dn[top:top + 128, left:left + 128].copy()
    hot = (block_row * 64 + 32 - top + site[0], block_column * 64 + 32 - left + site[1])
    bayer[hot] = raw.metadata.white_level_dn
    frame = raw_relative_rgb(dataclasses.replace(raw, bayer_dn=bayer)).astype(np.float32)
    assert np.median(frame) < 0.01 and (frame >= CLIP_LEVEL).any(axis=-1).sum() == 1
    defects = _defects(frame, frame >= CLIP_LEVEL, _Kernel(np.asarray(model.psf, np.float32)), NOISE)
    assert {tuple(int(index) for index in pixel) for pixel in np.argwhere(defects)} == {hot}


def test_a_blob_larger_than_a_speck_is_never_called_a_defect(model):
    """Five pixels forced to white on a dark ground: refuted by its neighbours, but a blob this size may be a real
    highlight seen through a PSF calibrated too wide, whose edge the bound must keep charging."""
    blob = [(30, 30), (30, 31), (30, 32), (31, 30), (31, 31)]
    assert _specks_called_defects(model.psf, 0.01, {}, blob) == set()


def test_a_hot_pixel_painted_as_a_lamp_keeps_the_clip_level(model):
    """A network that reads a hot pixel as a lamp and proposes 5 x white there: the judge keeps the frame's white,
    reports the proposal fallen back and says the pixel is one no light explains."""
    from hdrcam.recon.consistency import make_consistent

    frame = capture(np.full((64, 64, 3), 0.01, np.float32), model.psf)
    frame[30, 30] = 1.0
    proposal = frame.copy()
    proposal[30, 30] = 5.0
    judged, confidence, report = make_consistent(frame, proposal, np.asarray(model.psf, np.float32), noise=NOISE)
    np.testing.assert_array_equal(judged[30, 30], 1.0)
    assert confidence[30, 30] == 0.0 and report.fallen_back_pixels == 1
    assert report.defect_pixels == 1 and "1 clipped pixels no light can explain" in report.summary()
    assert report.proposed_excess == pytest.approx(12.0) and report.fallback_fraction == 1.0  # 4 x 3 channels
