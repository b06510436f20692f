"""Highlight placement: a sun inside its clipped glow found from its streaks (hdrcam.recon.highlight_placement)."""

from __future__ import annotations

import numpy as np
import torch

from hdrcam.optics.analytic import dirac, star
from hdrcam.recon.highlight_placement import place_highlights
from hdrcam.recon.highlight_spill import subtract_highlight_spill
from hdrcam.recon.tiling import clipped_mask
from hdrcam.sensor import fft_convolve

SIZE = 224
SUN_YX = (108, 117)  # off the glow's centre: where the glow is deepest is not where the sun is
GLOW_YX = (112, 112)


def psf_star() -> np.ndarray:
    """An 8-point star, 80 % in the centre, rays of 80 px: long streaks, as the A7 rank-1 DOE's."""
    return star(161, points=8, centre_fraction=0.8, length_px=80).astype(np.float32)


def convolve(radiance: np.ndarray, psf: np.ndarray) -> np.ndarray:
    planes = torch.from_numpy(np.ascontiguousarray(radiance.transpose(2, 0, 1), np.float32))
    return fft_convolve(planes, torch.from_numpy(psf)).numpy().transpose(1, 2, 0)


def sun_scene() -> tuple[np.ndarray, np.ndarray]:
    """A 0.4 sky, a glow at 1.5 of radius 10 px and a 3 x 3 sun at 2^8 inside it -> (truth, the sun's mask)."""
    y, x = np.mgrid[:SIZE, :SIZE]
    radiance = np.full((SIZE, SIZE, 3), 0.4, np.float32)
    radiance[np.hypot(y - GLOW_YX[0], x - GLOW_YX[1]) <= 10] = 1.5
    sun = (abs(y - SUN_YX[0]) <= 1) & (abs(x - SUN_YX[1]) <= 1)
    radiance[sun] = 256.0
    return radiance, sun


def estimate_without_the_sun(frame: np.ndarray, truth: np.ndarray, sun: np.ndarray, psf: np.ndarray) -> np.ndarray:
    """What the pipeline hands over: the glow right, the sun missed (painted at the glow's 1.5), the unclipped
    pixels the frame less the painted glow's spill."""
    painted = truth.copy()
    painted[sun] = 1.5
    return subtract_highlight_spill(frame, painted, psf, clipped_mask(frame))


def test_a_sun_inside_its_glow_is_placed_where_its_streaks_point_with_its_light():
    truth, sun = sun_scene()
    psf = psf_star()
    frame = np.clip(convolve(truth, psf), 0.0, 1.0)
    estimate = estimate_without_the_sun(frame, truth, sun, psf)
    proposal, report = place_highlights(frame, estimate, psf)
    added = (proposal - estimate).mean(axis=-1)
    true_light = float((truth[sun] - 1.5).mean(axis=-1).sum())
    near = np.zeros_like(sun)
    near[SUN_YX[0] - 3:SUN_YX[0] + 4, SUN_YX[1] - 3:SUN_YX[1] + 4] = True
    assert report.clusters == 1 and report.placed_px > 0
    assert added[near].sum() > 0.8 * added.sum()  # the light goes to the sun, not the glow's deepest point
    assert 0.7 * true_light < added.sum() < 1.3 * true_light
    assert proposal.max() <= 256.0
    error_before = float(((estimate - truth) ** 2).sum())
    assert float(((proposal - truth) ** 2).sum()) < 0.1 * error_before


def test_a_lens_without_streaks_places_nothing():
    truth, sun = sun_scene()
    psf = dirac(161).astype(np.float32)
    frame = np.clip(convolve(truth, psf), 0.0, 1.0)
    estimate = estimate_without_the_sun(frame, truth, sun, psf)
    proposal, report = place_highlights(frame, estimate, psf)
    assert report.clusters == 0 and report.placed_px == 0 and "not run" in report.summary()  # no far light
    np.testing.assert_array_equal(proposal, estimate)


def test_a_textured_surround_places_nothing():
    """Around the same sun, a 0.1 / 0.7 checkerboard of 3 px cells instead of a smooth sky: the estimate's
    unclipped pixels (the frame less the spill) are not the scene, the residual they leave is texture several times
    the noise, and the fit would mistake it for streaks: the gates leave the cluster alone (with neither the ring
    test nor the glow gate, 155 px got 11 x the sun's light)."""
    truth, sun = sun_scene()
    y, x = np.mgrid[:SIZE, :SIZE]
    sky = truth[..., 0] == 0.4
    truth[sky] = np.where(((y // 3 + x // 3) % 2 == 0)[sky], 0.1, 0.7)[:, None]
    psf = psf_star()
    frame = np.clip(convolve(truth, psf), 0.0, 1.0)
    estimate = estimate_without_the_sun(frame, truth, sun, psf)
    proposal, report = place_highlights(frame, estimate, psf)
    assert report.clusters == 1 and report.placed_px == 0
    np.testing.assert_array_equal(proposal, estimate)


def test_a_frame_without_a_pixel_clipped_in_every_channel_is_returned_as_it_is():
    psf = psf_star()
    frame = np.full((64, 64, 3), 0.3, np.float32)
    frame[20:30, 20:30, 0] = 1.0  # red clipped, green and blue not: no sun's core
    proposal, report = place_highlights(frame, frame, psf)
    assert report.clusters == 0 and "no pixel clipped in every channel" in report.summary()
    np.testing.assert_array_equal(proposal, frame)


def test_reconstruct_runs_it_only_on_request_and_the_judge_keeps_the_output_within_the_frame():
    """The public pipeline with the shipped model: off by default ("off" in the result), on request it reports
    what it placed and the output keeps reconstruct's invariants (finite, at most 2^8, unclipped channels the
    frame less spill: never above the frame)."""
    from hdrcam.api import reconstruct
    from hdrcam.train.checkpoint import load_model

    model = load_model()
    truth, _ = sun_scene()
    frame = np.clip(convolve(truth, np.asarray(model.psf, np.float32)), 0.0, 1.0)
    assert reconstruct(frame, model, partner=None, mirror_check=False).placement == "off"
    result = reconstruct(frame, model, partner=None, mirror_check=False, place_highlights=True)
    assert result.placement.startswith("highlight placement")
    assert np.isfinite(result.hdr).all() and result.hdr.max() <= 256.0
    unclipped = frame < 0.99
    assert (result.hdr[unclipped] <= frame[unclipped] + 1e-6).all()


def test_evaluate_scores_the_option_on_request(monkeypatch):
    """evaluate's ``place_highlights`` reaches reconstruct, and the rows come back scored."""
    import hdrcam.evaluate.scoring as scoring
    from hdrcam.stages import evaluate_checkpoints

    asked = []

    def recording(*arguments, **options):
        asked.append(options.get("place_highlights"))
        return reconstruct(*arguments, **options)

    reconstruct = scoring.reconstruct
    monkeypatch.setattr(scoring, "reconstruct", recording)
    rows, _ = evaluate_checkpoints(data="procedural", count=1, size_px=64, place_highlights=True)
    assert asked == [True]
    assert {row.method for row in rows} >= {"ldr", "hdrcam"}
    assert all(np.isfinite(row.metrics["psnr_linear"]) for row in rows)
