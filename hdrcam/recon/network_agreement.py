"""Two networks' proposals, judged: what both paint, unless the frame's streaks confirm one of them.

Two networks trained behind the same PSF (a model and its partner) each propose an HDR estimate of the frame.
Where the frame cannot tell a highlight from texture (a window onto a hazy sky, a bright wall), independently
trained networks seldom paint the same wrong light: their per-pixel, per-channel minimum keeps only what both
paint, and the judge (:func:`hdrcam.recon.consistency.make_consistent`) bounds it by the frame. The minimum
also gives up what the bolder network gets right where the frame does show it (lamps at night, whose
streaks the shipped DOE records clearly). So the judge also runs on each network's own proposal, and a
cluster of clipped pixels whose streaks show one network's proposed light beyond doubt (the judge's
``strong_evidence`` clusters: evidence z >= STRONG_EVIDENCE_Z in some channel) keeps that network's judged
result - the amount is the judgement's (each channel already scaled by its evidence share), so the share
need not reach STRONG_EVIDENCE_SHARE as it must for the shape cap's exemption (requiring it left lamps whose
blue streaks kept 0.6-0.8 to the minimum: night dev scenes -0.5 dB); strong in both, the judged cluster that
holds more light (a whole cluster from one judgement, so the judge's bound on its excess holds for it). Every
other pixel keeps the judged minimum.

Measured (dev cases, then under a rule written first) in tools/results/real-data/README.md, "Two networks
agree unless the frame confirms one".
"""

from __future__ import annotations

import numpy as np

from hdrcam.recon.consistency import FALLEN_BACK_SHARE, ConsistencyReport, NoiseModel, judge_estimates
from hdrcam.recon.tiling import CLIP_LEVEL, clipped_clusters


def judge_pair(frame: np.ndarray, first: np.ndarray, second: np.ndarray, psf: np.ndarray, *, noise: NoiseModel
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, ConsistencyReport]:
    """H x W x 3 frame in [0, 1], two networks' H x W x 3 estimates (relative radiance), the (3, k, k) PSF ->
    (the proposal taken per pixel: the minimum, or the estimate of the network the streaks bear out; the judged
    estimate, as :func:`hdrcam.recon.consistency.make_consistent` returns it; H x W confidence in [0, 1]; the report of what was kept).

    Each cluster (hdrcam.recon.tiling.clipped_clusters) is taken whole from one judgement, so the judge's upper
    bound on its excess holds for it as the judge left it: strong streak evidence for one network's proposal,
    that network's; for both, the one whose judged cluster holds more light; else the minimum's. The report
    counts the proposed and kept excess of the pixels' chosen sources, and its ``confirmed`` and
    ``strong_evidence`` masks are, per pixel, those of the judgement the pixel was taken from."""
    proposals = [np.minimum(first, second), first, second]  # indices 0, 1, 2 of ``source`` below
    judgements = judge_estimates(frame, proposals, psf, noise=noise)  # the frame's side of the judge found once
    clipped_channels = frame >= CLIP_LEVEL
    clipped = clipped_channels.any(axis=-1)
    source = np.zeros(frame.shape[:2], np.uint8)  # per pixel: 0 the minimum's judgement, 1 first's, 2 second's
    first_strong, second_strong = judgements[1][2].strong_evidence, judgements[2][2].strong_evidence
    for crop, own in clipped_clusters(clipped, psf.shape[-1] // 2):
        in_first, in_second = (first_strong[crop] & own).any(), (second_strong[crop] & own).any()
        if in_first and in_second:
            light = [float(np.where(clipped_channels[crop] & own[..., None], judged[crop] - 1.0, 0.0).sum())
                     for judged, _, _ in judgements[1:]]
            chosen = 1 if light[0] >= light[1] else 2
        else:
            chosen = 1 if in_first else 2 if in_second else 0
        source[crop][own] = chosen

    taken = np.nonzero(source)  # the clipped pixels taken from a network's own judgement
    taken_from = source[taken]

    def picked(values: list[np.ndarray]) -> np.ndarray:  # values[0] (a fresh array of this call) changed in place
        for index in (1, 2):
            pixels = (taken[0][taken_from == index], taken[1][taken_from == index])
            values[0][pixels] = values[index][pixels]
        return values[0]

    proposal = picked(proposals).astype(np.float32, copy=False)
    judged = picked([judged for judged, _, _ in judgements]).astype(np.float32, copy=False)
    confidence = picked([confidence for _, confidence, _ in judgements]).astype(np.float32, copy=False)
    at = np.nonzero(clipped)  # the report's sums over the clipped pixels alone (a 24 MP frame: seconds less)
    clipped_at = clipped_channels[at]
    report = ConsistencyReport(
        clusters=judgements[0][2].clusters,
        proposed_excess=float(np.where(clipped_at, np.maximum(proposal[at], 1.0) - 1.0, 0.0).sum()),
        kept_excess=float(np.where(clipped_at, judged[at] - 1.0, 0.0).sum()),
        clipped_pixels=len(at[0]),
        fallen_back_pixels=int((confidence[at] < FALLEN_BACK_SHARE).sum()),
        confirmed=picked([report.confirmed for _, _, report in judgements]),
        strong_evidence=picked([report.strong_evidence for _, _, report in judgements]),
        defect_pixels=judgements[0][2].defect_pixels)  # the frame's alone: the same in every judgement
    return proposal, judged, confidence, report
