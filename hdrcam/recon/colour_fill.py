"""A clipped channel read from the pixel's unclipped channels and its highlight's hue (cross-channel highlight
reconstruction, as raw converters do it: dcraw -H, darktable's "inpaint opposed").

Where a pixel clipped in some channels but not all, the frame still measured it: its unclipped channels j,
read against the hue of the highlight around it, bound the clipped channel k. In camera RGB that is most of the
clipping a real sensor does - the green photosites fill first (a white surface records (0.36, 1, 0.81) of green's
signal through the Sony A7's colour filters), so green and blue clip while red still reads - and no streak is
needed for it.

The hue r_kj = k / j is the ratio of sums over the highlight's rim: the pixels unclipped in every channel within
RIM_PX of a pixel where channel k clipped but not next to one (a demosaiced pixel there mixed the clipped sample
into its value: a white disc's rim read green / red 0.8 where it was 2), weighted by their channel j squared (the
brightest rim pixels carry the highlight's own colour; a dim surround often carries its own). The smallest of
HUE_WINDOWS_PX (square windows about the pixel) holding any rim pixel decides. A highlight is paler than the
surface around it - a specular glint or a lamp takes the colour of the light, not of the brass or the shade around
it (a brass fitting's rim read red/blue 13 where its glint was 3.7) - so the hue is shrunk toward the frame's
neutral n (the RGB a grey surface records: equal channels in a white-balanced frame, a RAW file's as-shot neutral
in camera RGB): r = (r_kj)^HUE_SHRINK (n_k / n_j)^(1 - HUE_SHRINK). The estimate is the f_j-weighted mean of f_j r
over the unclipped channels, and a clipped channel is at least 1 (the sensor recorded white) - so a channel barely
clipped beside unclipped ones its hue does not lift stays at the clip level.

Units: relative radiance, 1 = the sensor's white level; the frame in [0, 1].
"""

from __future__ import annotations

import cv2
import numpy as np

from hdrcam.errors import InputError
from hdrcam.recon.tiling import CLIP_LEVEL

RIM_PX = 3  # the highlight's rim: unclipped pixels this close to a pixel where the channel clipped ...
RIM_GAP_PX = 1  # ... but farther than this: a demosaiced pixel next to a clipped sample mixes it into its value
HUE_WINDOWS_PX = (15, 31, 63, 127)  # windows about a pixel searched for rim pixels, smallest first
MIN_REFERENCE = 0.05  # a rim pixel's reference channel must read at least this (above the read-noise floor)
TILE_PX = 256  # the frame is filled in tiles of this side that hold partly clipped pixels (time and memory
# follow the highlights, not the frame; each tile reads its context, so the result is the whole frame's)
HUE_SHRINK = 0.75  # exponent of the rim's hue against the neutral's (1: the rim's hue; 0: the neutral's);
# chosen on the training photographs from 1 / 0.75 / 0.5 / 0.25 / 0 (tools/results/real-data/colour-fill)


def fill_from_unclipped_channels(frame: np.ndarray, hdr: np.ndarray,
                                 neutral_rgb=(1.0, 1.0, 1.0)) -> tuple[np.ndarray, int]:
    """H x W x 3 frame in [0, 1] and its reconstruction -> (the reconstruction with each clipped channel of a
    partly clipped pixel raised to at least its cross-channel estimate, how many channel samples were raised).
    ``neutral_rgb``: the RGB a grey surface records in the frame's units (any scale; equal channels for a
    white-balanced frame)."""
    neutral = checked_neutral(neutral_rgb)
    frame = np.asarray(frame, np.float32)
    clipped = frame >= CLIP_LEVEL
    partly = clipped.any(axis=-1) & ~clipped.all(axis=-1)
    output = np.array(hdr, np.float32, copy=True)
    if not partly.any():
        return output, 0
    reach = RIM_PX + HUE_WINDOWS_PX[-1] // 2  # a pixel's estimate reads nothing farther than this
    height, width = partly.shape
    raised_total = 0
    for top in range(0, height, TILE_PX):  # tiles holding partly clipped pixels, each with the context it reads
        for left in range(0, width, TILE_PX):
            core = (slice(top, min(top + TILE_PX, height)), slice(left, min(left + TILE_PX, width)))
            if not partly[core].any():
                continue
            box = (slice(max(top - reach, 0), min(top + TILE_PX + reach, height)),
                   slice(max(left - reach, 0), min(left + TILE_PX + reach, width)))
            estimate, estimated = _cross_channel_estimate(frame[box], clipped[box], partly[box], neutral)
            inner = (slice(top - box[0].start, core[0].stop - box[0].start),
                     slice(left - box[1].start, core[1].stop - box[1].start))
            estimate, estimated = estimate[inner], estimated[inner]
            raised = estimated & (estimate > output[core])
            output[core] = np.where(raised, estimate, output[core])
            raised_total += int(raised.sum())
    return output, raised_total


def checked_neutral(neutral_rgb) -> np.ndarray:
    """``neutral_rgb`` as three positive finite numbers (float64), else InputError."""
    try:
        neutral = np.asarray(neutral_rgb, np.float64)
    except (TypeError, ValueError):
        neutral = np.empty(0)
    if neutral.shape != (3,) or not np.all(np.isfinite(neutral)) or not np.all(neutral > 0):
        raise InputError(f"neutral_rgb {neutral_rgb!r}: the RGB a grey surface records, three positive numbers")
    return neutral


def _cross_channel_estimate(frame: np.ndarray, clipped: np.ndarray, partly: np.ndarray,
                            neutral: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per channel k: the estimate on the pixels of ``partly`` where k clipped, and where there is one."""
    unclipped_pixel = ~clipped.any(axis=-1)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * RIM_PX + 1,) * 2)
    gap = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * RIM_GAP_PX + 1,) * 2)
    estimate = np.zeros(frame.shape, np.float32)
    estimated = np.zeros(frame.shape, bool)
    for k in range(3):
        target = partly & clipped[..., k]
        if not target.any():
            continue
        rim = cv2.dilate(clipped[..., k].astype(np.uint8), disc).astype(bool) & unclipped_pixel
        rim &= ~cv2.dilate(clipped[..., k].astype(np.uint8), gap).astype(bool)
        weighted_sum, weight_sum = np.zeros(target.shape, np.float64), np.zeros(target.shape, np.float64)
        for j in (j for j in range(3) if j != k):
            usable = target & ~clipped[..., j]
            if not usable.any():
                continue
            hue, found = _rim_hue(frame[..., k], frame[..., j], rim & (frame[..., j] >= MIN_REFERENCE), usable)
            usable &= found
            hue = hue ** HUE_SHRINK * (neutral[k] / neutral[j]) ** (1.0 - HUE_SHRINK)
            reference = frame[..., j].astype(np.float64)
            weighted_sum += np.where(usable, reference * reference * hue, 0.0)
            weight_sum += np.where(usable, reference, 0.0)
        have = weight_sum > 0
        estimate[..., k] = np.where(have, np.maximum(weighted_sum / np.where(have, weight_sum, 1.0), 1.0), 0.0)
        estimated[..., k] = have
    return estimate, estimated


def _rim_hue(channel_k: np.ndarray, channel_j: np.ndarray, rim: np.ndarray, needed: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """k / j over the rim pixels (weights j^2) in the smallest window about each pixel that holds one, and
    where one does; larger windows are searched only while a ``needed`` pixel has none."""
    weight = np.where(rim, channel_j.astype(np.float64) ** 2, 0.0)
    weighted_k, weighted_j = weight * channel_k, weight * channel_j
    count = rim.astype(np.float64)
    hue = np.zeros(rim.shape, np.float64)
    found = np.zeros(rim.shape, bool)
    for window in HUE_WINDOWS_PX:
        size = (window, window)
        present = cv2.boxFilter(count, -1, size, normalize=False, borderType=cv2.BORDER_REFLECT) > 0.5
        new = present & ~found
        if new.any():
            sum_k = cv2.boxFilter(weighted_k, -1, size, normalize=False, borderType=cv2.BORDER_REFLECT)
            sum_j = cv2.boxFilter(weighted_j, -1, size, normalize=False, borderType=cv2.BORDER_REFLECT)
            hue[new] = sum_k[new] / np.maximum(sum_j[new], 1e-12)
            found |= new
        if found[needed].all():
            break
    return hue, found
