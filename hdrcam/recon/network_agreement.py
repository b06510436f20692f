"""Two networks' proposals, judged: what both paint, unless the frame's streaks confirm one of them.

Two networks trained behind the same PSF (a model and its partner) each propose an HDR estimate of the frame.
Where the frame cannot tell a highlight from texture (a window onto a hazy sky, a bright wall), independently
trained networks seldom paint the same wrong light: their per-pixel, per-channel minimum keeps only what both
paint, and the judge (:func:`hdrcam.recon.consistency.make_consistent`) bounds it by the frame. The minimum
also gives up what the bolder network gets right where the frame does show it (lamps at night, whose
streaks the shipped DOE records clearly). So the judge also runs on each network's own proposal, and a
cluster of clipped pixels whose streak evidence confirms one network's proposal beyond doubt (the judge's
``confirmed`` clusters: evidence z >= STRONG_EVIDENCE_Z and every channel's evidence share >=
STRONG_EVIDENCE_SHARE) keeps that network's judged result; confirmed in both, the larger per pixel and
channel. Every other pixel keeps the judged minimum.

Measured (dev cases, then under a rule written first) in tools/results/real-data/README.md, "Two networks
agree unless the frame confirms one".
"""

from __future__ import annotations

import numpy as np

from hdrcam.recon.consistency import FALLEN_BACK_SHARE, ConsistencyReport, NoiseModel, make_consistent
from hdrcam.recon.tiling import CLIP_LEVEL


def judge_pair(frame: np.ndarray, first: np.ndarray, second: np.ndarray, psf: np.ndarray, *, noise: NoiseModel
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, ConsistencyReport]:
    """H x W x 3 frame in [0, 1], two networks' H x W x 3 estimates (relative radiance), the (3, k, k) PSF ->
    (the proposal taken per pixel: the minimum, or the confirmed network's estimate; the judged estimate, as
    :func:`make_consistent` returns it; H x W confidence in [0, 1], that of the network whose judged pixel is
    the brighter where both are confirmed; the report of what was kept).

    The report counts the proposal and kept excess of the pixels' chosen sources (kept after the shape cap)
    and, in ``confirmed``, the clipped pixels whose cluster one network's streak evidence confirmed."""
    agreed = np.minimum(first, second)
    judged_agreed, confidence_agreed, report_agreed = make_consistent(frame, agreed, psf, noise=noise)
    judged_first, confidence_first, report_first = make_consistent(frame, first, psf, noise=noise)
    judged_second, confidence_second, report_second = make_consistent(frame, second, psf, noise=noise)
    only_first = (report_first.confirmed & ~report_second.confirmed)[..., None]
    only_second = (report_second.confirmed & ~report_first.confirmed)[..., None]
    both = (report_first.confirmed & report_second.confirmed)[..., None]
    first_brighter = (judged_first.sum(axis=-1) >= judged_second.sum(axis=-1))[..., None]

    def chosen(agreed_value, first_value, second_value, *, larger: bool):
        """Per pixel: the confirmed network's value, the minimum's elsewhere; confirmed in both, the larger
        (per channel) when ``larger``, else the value of the network whose judged pixel is brighter."""
        values = [value if value.ndim == 3 else value[..., None] for value in (agreed_value, first_value, second_value)]
        in_both = np.maximum(values[1], values[2]) if larger else np.where(first_brighter, values[1], values[2])
        picked = np.where(only_first, values[1], np.where(only_second, values[2], np.where(both, in_both, values[0])))
        return (picked if agreed_value.ndim == 3 else picked[..., 0]).astype(np.float32)

    proposal = chosen(agreed, first, second, larger=True)
    judged = chosen(judged_agreed, judged_first, judged_second, larger=True)
    confidence = chosen(confidence_agreed, confidence_first, confidence_second, larger=False)
    clipped_channels = frame >= CLIP_LEVEL
    clipped = clipped_channels.any(axis=-1)
    confirmed = report_first.confirmed | report_second.confirmed
    report = ConsistencyReport(
        clusters=report_agreed.clusters,
        proposed_excess=float(np.where(clipped_channels, np.maximum(proposal, 1.0) - 1.0, 0.0).sum()),
        kept_excess=float(np.where(clipped_channels, judged - 1.0, 0.0).sum()),
        clipped_pixels=int(clipped.sum()),
        fallen_back_pixels=int((confidence[clipped] < FALLEN_BACK_SHARE).sum()),
        confirmed=confirmed)
    return proposal, judged, confidence, report
