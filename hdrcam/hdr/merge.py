"""Merge a RAW bracket into linear HDR on the Bayer data (before demosaicing).

Per frame k with exposure t_k, black-subtracted signal y_k (DN) estimates the rate x = y_k / t_k. Under
the linear sensor's noise model, Var(y_k) = g * E[y_k] + r^2 (g DN per electron, r read noise in DN), the
minimum-variance unbiased combination weights each sample by its inverse variance, t_k^2 / Var(y_k)
(Granados et al. 2010); variances are evaluated at the pooled estimate (a second pass) so the weights do
not favour samples that happen to be low. Clipped samples (at or above the clip level measured per CFA
position from the data - the pile-up below the metadata white level, hdrcam.io.raw_clipping - minus a
margin, dilated so their neighbours are not trusted either) get no weight; a pixel clipped in every frame
keeps the lower bound clip / t_shortest and is flagged. Exposure ratios are estimated from the data
(hdrcam.hdr.exposure_ratios: a slope free of black-level errors), starting from the EXIF times - read as the
shutter's true times where a Sony body labels its 1/3 EV notches nominally (1/125 s is really 2^-7 s:
hdrcam.capture.notches.true_exposure_s), which also anchor the absolute scale: a bracket from 1/1000 s, labels
taken as they are, was 4.3 % dark, and brackets of other notches disagreed by up to 4 %; other makes' labels are
taken as written.

Units of the result: relative radiance, full wells per second at ISO 100 (1.0 = a signal that fills the
sensor in one second at base ISO).

Speed: every per-pixel step runs on strips of rows in a thread pool (one thread per core; numpy and OpenCV
release the GIL), converting the uint16 data of the strip to float32 signals and finding its clipped samples as
it goes (no full-size float copy of the frames, no full-size masks), with in-place float32 arithmetic - OpenCV's
where it takes one pass for numpy's two or three (a masked multiply-accumulate, a scaled sum); each pixel's
arithmetic does not depend on the strip, so a strip size changes nothing but the exposure-ratio sums' rounding
(float64 sums of float32 products: well within 1e-6).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from hdrcam.errors import InputError
from hdrcam.capture.notches import true_exposure_s
from hdrcam.hdr.exposure_ratios import estimate_exposures
from hdrcam.hdr.neighbour_mean import NEIGHBOUR_ROWS
from hdrcam.io.raw import RawFrame
from hdrcam.io.raw_clipping import (SEARCH_FROM, is_in_top_part, one_sensor_white, sensor_white_dn,
                                    straddles_top_part, tiled)
from hdrcam.parallel import strips, worker_threads
from hdrcam.profiles import CameraSpec

_NEIGHBOURS = np.ones((3, 3), np.uint8)
MAX_FRAMES = 64  # bits of the widest usable-frame mask
UINT16_WHITE_DN = 65535.0
LIT_SIGMAS, LIT_FRACTION = 10.0, 1e-3  # a bracket that records light has more samples this far above black
LIT_CLUSTER_SAMPLES = 4  # or one 8-connected group this large (a point light's 2 x 2 core)
CLIP_MARGIN = 0.01  # of the black-to-clip range
STRIP_ROWS = 64  # rows per work item: a strip's temporaries (64 x 6000 px float32, 1.5 MB each) stay in the
# caches, and per-call costs (held under the GIL) are spread over enough pixels; the weighted passes of a 24 MP
# bracket of five frames took 0.85 / 0.48 / 0.44 / 0.38 / 0.58 s on 2 threads with 8 / 16 / 32 / 64 / 128 rows


@dataclasses.dataclass(frozen=True)
class NoiseModel:
    """Shot + read noise of one camera at one ISO, in digital numbers."""

    gain_dn_per_e: float
    read_noise_dn: float

    @classmethod
    def from_camera(cls, camera: CameraSpec, iso: float, white_level_dn: float, black_level_dn: float
                    ) -> "NoiseModel":
        gain = (white_level_dn - black_level_dn) / camera.full_well_e * (iso / 100.0)
        return cls(gain, camera.read_noise_e * gain)


@dataclasses.dataclass
class BayerMerge:
    rate: np.ndarray  # H x W float32, relative radiance (full wells per second at ISO 100)
    variance: np.ndarray | None  # H x W float32, of ``rate`` (with ``with_variance``)
    clipped_everywhere: np.ndarray  # H x W bool: clipped in every frame; rate is a lower bound
    exposures_s: np.ndarray  # estimated true exposure per frame (shortest first)
    labelled_exposures_s: np.ndarray  # from the files
    clip_level_dn: float  # above black, the lowest of the CFA positions'
    clip_level_tile_dn: np.ndarray  # 2 x 2, absolute DN per CFA position: samples at or above are clipped
    notes: list[str]
    usable_frames: np.ndarray  # H x W bit mask (uint8 up to 8 frames, wider above): bit k set where frame k's
    # sample was used
    noise: NoiseModel
    read_variance_dn2: float  # per sample, after black or dark subtraction
    to_relative: float  # relative radiance per DN/s

    def variance_at(self, rate: np.ndarray) -> np.ndarray:
        """Variance of the merged rate, per pixel, if the true rate were ``rate`` (same shape, relative units).

        Weights computed from a rate that excludes a sample's own noise (e.g. its neighbours) keep a
        weighted fit unbiased; the merge's own ``variance`` uses the sample itself and so favours samples
        that came out low.
        """
        signal_dn_per_s = np.maximum(rate, 0.0) / self.to_relative
        information = np.zeros(rate.shape, np.float64)
        for k, t in enumerate(self.exposures_s):
            used = (self.usable_frames >> k) & 1 == 1
            variance_dn2 = signal_dn_per_s * t * self.noise.gain_dn_per_e + self.read_variance_dn2
            information += np.where(used, t * t / variance_dn2, 0.0)
        with np.errstate(divide="ignore"):
            return np.where(information > 0, self.to_relative ** 2 / information, np.inf)


def black_subtracted(frame: RawFrame, window: tuple[slice, slice] = (slice(None), slice(None))) -> np.ndarray:
    """The frame's signal in DN above its black level (float32; black per CFA position), on ``window`` (rows,
    columns; default: the whole frame). The merge itself subtracts strip by strip, or a dark frame instead
    (:class:`_BracketStrips`)."""
    rows, columns = window
    data = frame.bayer_dn[rows, columns]
    phase = ((rows.start or 0) % 2, (columns.start or 0) % 2)  # the window's first sample's CFA position
    black = np.roll(frame.metadata.black_level_tile(), (-phase[0], -phase[1]), axis=(0, 1))
    return np.subtract(data, tiled(black, *data.shape), dtype=np.float32)


def clip_level_tile_dn(frames: list[RawFrame]) -> np.ndarray:
    """2 x 2 tile of clip levels (absolute DN) for a bracket (shortest frame first): per CFA position, the lowest
    measured in any frame (one sensor at one ISO clips at one level; frames that reach it show the pile-up), or
    the sensor's white where other positions show it far below the metadata white (:func:`one_sensor_white`)."""
    meta = frames[0].metadata
    return one_sensor_white(np.min(np.stack([frame.clip_level_tile_dn for frame in frames]), axis=0),
                            meta.black_level_tile(), meta.white_level_dn, frames[-1].bayer_dn)


def dilated(mask: np.ndarray) -> np.ndarray:
    """A clipped-sample mask grown by one pixel: neighbours of clipped samples (blooming, crosstalk, and the
    demosaicing footprint) are not trusted either."""
    if not mask.any():
        return mask
    return cv2.dilate(mask.view(np.uint8), _NEIGHBOURS).view(bool)


class _BracketStrips:
    """Every frame's data on a strip of rows, from the uint16 samples when asked (nothing full-size is stored):
    the signal (float32 DN above the frame's own black level - bodies that measure black from the masked border
    declare a slightly different one in every file - or above its dark frame: 2 bytes per sample are read
    instead of a stored float32 copy's 4) and the clipped samples (at or above the clip threshold of their CFA
    position), alone or as the usable samples: unclipped with eight unclipped neighbours (from the strip and one
    row either side)."""

    def __init__(self, frames: list[RawFrame], darks: list[RawFrame | None], threshold_tile_dn: np.ndarray):
        self.frames, self.darks = frames, darks
        self.height, width = frames[0].bayer_dn.shape
        for dark in darks:
            if dark is not None and dark.bayer_dn.shape != (self.height, width):
                raise InputError(f"{dark.metadata.path}: dark frame size {dark.bayer_dn.shape} differs from "
                                 f"{(self.height, width)}")
        rows = min(STRIP_ROWS + 2 * NEIGHBOUR_ROWS, self.height)  # a strip and the ratio estimate's halo
        strips_of_black: dict[bytes, list[np.ndarray]] = {}  # one pair of strips per distinct black tile
        self.black = []  # per frame, per CFA row phase of a strip's first row
        for frame in frames:
            black_tile = frame.metadata.black_level_tile()
            if black_tile.tobytes() not in strips_of_black:
                strips_of_black[black_tile.tobytes()] = [tiled(np.roll(black_tile, -phase, axis=0), rows, width)
                                                         for phase in (0, 1)]
            self.black.append(strips_of_black[black_tile.tobytes()])
        # integer data at or above a threshold is at or above its ceiling: one uint16 comparison per sample
        self.first_clipped_dn = [tiled(np.roll(np.ceil(threshold_tile_dn), -phase, axis=0), rows + 2, width
                                       ).astype(np.uint16) for phase in (0, 1)]

    def signals(self, rows: slice) -> list[np.ndarray]:
        top, bottom, _ = rows.indices(self.height)
        signals = []
        for frame, dark, black in zip(self.frames, self.darks, self.black):
            subtrahend = black[top % 2][:bottom - top] if dark is None else dark.bayer_dn[rows]
            signals.append(cv2.subtract(frame.bayer_dn[rows], subtrahend, dtype=cv2.CV_32F))  # numpy's: 2.5x longer
        return signals

    def clipped(self, rows: slice) -> list[np.ndarray]:
        top, bottom, _ = rows.indices(self.height)
        first_clipped = self.first_clipped_dn[top % 2][:bottom - top]
        return [np.greater_equal(frame.bayer_dn[top:bottom], first_clipped) for frame in self.frames]

    def signals_and_clipped(self, rows: slice) -> tuple[list[np.ndarray], list[np.ndarray]]:
        return self.signals(rows), self.clipped(rows)

    def usable(self, rows: slice) -> list[np.ndarray]:
        """Per frame, uint8 1 where the strip's sample and its eight neighbours are unclipped, else 0: the
        complement of the clipped samples :func:`dilated` (an erosion of the unclipped ones, from the strip and
        one row either side; outside the image counts as unclipped)."""
        top, bottom, _ = rows.indices(self.height)
        above, below = min(top, 1), min(self.height - bottom, 1)
        unclipped = [np.logical_not(mask, out=mask).view(np.uint8)
                     for mask in self.clipped(slice(top - above, bottom + below))]
        return [(mask if mask.all() else cv2.erode(mask, _NEIGHBOURS))[above:above + bottom - top]
                for mask in unclipped]


def merge_bayer(frames: list[RawFrame], camera: CameraSpec, *, darks: list[RawFrame | None] | None = None,
                estimate_ratios: bool = True, with_variance: bool = False, threads: int | None = None,
                scene_fills_frame: bool = True) -> BayerMerge:
    """Inverse-variance merge of black-subtracted Bayer frames (shortest first), on ``threads`` threads
    (default: one per core); ``with_variance``: also the variance of each merged rate. ``scene_fills_frame``
    False for a point-source target (a pinhole through a bare lens lights a few hundred samples): no warning
    that the longest frame recorded almost no light."""
    if len(frames) > MAX_FRAMES:
        raise InputError(f"{len(frames)} frames: a bracket of at most {MAX_FRAMES} merges (the usable-frame bit mask)")
    meta = frames[0].metadata
    iso = meta.iso or _assumed_iso(frames)
    black = float(np.mean(meta.black_level_dn))
    clip_tile = clip_level_tile_dn(frames)
    white = sensor_white_dn(meta.white_level_dn, black, clip_tile)
    _warn_if_white_unconfirmed(frames[-1], white, black, clip_tile)
    _warn_if_levels_straddle(clip_tile, meta.black_level_tile(), meta.white_level_dn)
    noise = NoiseModel.from_camera(camera, iso, white, black)
    if scene_fills_frame:
        _warn_if_no_light(frames[-1], black, noise)
    darks = darks or [None] * len(frames)
    read_variance = noise.read_noise_dn ** 2 * (2.0 if any(d is not None for d in darks) else 1.0)
    notes: list[str] = []
    black_tile = meta.black_level_tile()
    threshold_tile = black_tile + (clip_tile - black_tile) * (1.0 - CLIP_MARGIN)
    clip = float((clip_tile - black_tile).min())
    threshold = clip * (1.0 - CLIP_MARGIN)
    height, width = frames[0].bayer_dn.shape
    bracket = _BracketStrips(frames, darks, threshold_tile)
    row_strips = strips(height, STRIP_ROWS)
    labelled = np.array([frame.metadata.exposure_s for frame in frames])
    nominal_true = np.array([true_exposure_s(t, meta.make) for t in labelled])  # the anchor: 1/125 s is 2^-7 s
    to_relative = 1.0 / ((white - black) * (iso / 100.0))
    rate = np.empty((height, width), np.float32)
    variance = np.empty((height, width), np.float32) if with_variance else None
    usable_frames = np.empty((height, width), np.min_scalar_type((1 << len(frames)) - 1))
    strip_height = min(STRIP_ROWS, height)
    clip_above_black = [tiled(np.roll(threshold_tile - black_tile, -phase, axis=0), strip_height, width)
                        for phase in (0, 1)]  # per CFA row phase of a strip's first row

    def merge_strip(rows: slice) -> None:
        top, bottom, _ = rows.indices(height)
        usable = bracket.usable(rows)
        bits = usable_frames[rows]  # bit k set where frame k is usable
        np.copyto(bits, usable[0])
        for k in range(1, len(frames)):
            bits += np.multiply(usable[k], 1 << k, dtype=bits.dtype)
        signals = bracket.signals(rows)
        times = exposures.astype(np.float32)
        rates = [np.divide(y, t) for y, t in zip(signals, times)]  # per frame, DN/s
        scratch = np.empty_like(rates[0])

        def own_variance(k: int) -> np.ndarray:  # Var(y_k) at the sample itself: g max(y_k, 0) + r^2
            cv2.threshold(signals[k], 0.0, 0.0, cv2.THRESH_TOZERO, dst=scratch)  # numpy's maximum: 4x longer
            return affine(scratch, noise.gain_dn_per_e, read_variance, out=scratch)

        def pooled_variance(k: int) -> np.ndarray:  # Var(y_k) at the pooled estimate: g max(x, 0) t_k + r^2
            return affine(pooled, noise.gain_dn_per_e * float(times[k]), read_variance, out=scratch)

        estimate, _ = _weighted(rates, times, usable, own_variance)
        pooled = cv2.threshold(estimate, 0.0, 0.0, cv2.THRESH_TOZERO, dst=estimate)[1]
        estimate, information = _weighted(rates, times, usable, pooled_variance)
        none = bits == 0
        np.copyto(estimate, clip_above_black[top % 2][:bottom - top] / exposures[0], where=none)
        np.multiply(estimate, to_relative, out=rate[rows])
        if variance is not None:
            np.maximum(information, 1e-30, out=information)
            np.divide(to_relative ** 2, information, out=variance[rows])
            np.copyto(variance[rows], np.finfo(np.float32).max, where=none)

    with ThreadPoolExecutor(threads or worker_threads()) as pool:
        exposures = estimate_exposures(bracket.signals_and_clipped, row_strips, nominal_true, threshold,
                                       np.sqrt(read_variance), notes, pool, black_dn=float(black_tile.min()),
                                       names=[str(frame.metadata.path) for frame in frames]) \
            if estimate_ratios and len(frames) > 1 else nominal_true.copy()
        list(pool.map(merge_strip, row_strips))
    if not np.array_equal(nominal_true, labelled):
        notes.append(f"{meta.make} labels read as the notches' true times (1/125 s is 2^-7 s): "
                     + ", ".join(f"{t:.6g}" for t in nominal_true) + " s")
    elif len(frames) > 1:  # said, so a user of another make knows what set the scale (a nominal label is 2-4 % off)
        owner = f"{meta.make.strip()}'s" if meta.make.strip() else "the files'"
        notes.append(f"{owner} labels taken as written (exact times or the notches' nominal labels; only Sony's are "
                     "known to be nominal): " + ", ".join(f"{t:.6g}" for t in labelled) + " s")
    return BayerMerge(rate, variance, usable_frames == 0, exposures, labelled, clip, clip_tile, notes,
                      usable_frames, noise, read_variance, to_relative)


ASSUMED_ISO = 100.0


def _assumed_iso(frames: list[RawFrame]) -> float:
    """ASSUMED_ISO for a bracket whose files record no ISO (mixed ISOs are refused when it is read), with a
    warning: the result's unit is full wells per second at ISO 100, so a bracket shot at ISO 400 would read 4x
    too bright."""
    names = frames[0].metadata.path.name + (" and the bracket's other frames" if len(frames) > 1 else "")
    warnings.warn(f"{names}: no ISO recorded; ISO {ASSUMED_ISO:g} is assumed, and the radiance (full wells per "
                  f"second at ISO {ASSUMED_ISO:g}) scales with it: frames shot at ISO 400 would read 4x too bright")
    return ASSUMED_ISO


def _warn_if_white_unconfirmed(longest: RawFrame, white_dn: float, black_dn: float, clip_tile_dn: np.ndarray) -> None:
    """Warn when nothing confirms a white level of 65535 (a DNG's default for 16-bit samples, whatever the
    sensor's depth) that scales the result: no frame clips (no pile-up) and even the longest frame stays below
    the top part of the black-to-white range. For a 14-bit sensor every radiance would be 4x too small."""
    if white_dn < UINT16_WHITE_DN or not np.all(clip_tile_dn >= white_dn):
        return
    brightest_dn = int(longest.bayer_dn.max())
    if not is_in_top_part(brightest_dn, black_dn, white_dn):
        warnings.warn(f"no frame clips and the brightest sample ({brightest_dn} DN, "
                      f"{longest.metadata.path.name}) stays below the top half of the range to the white level "
                      f"{white_dn:g} DN: the radiance scale (full wells) assumes that white level; if the sensor "
                      "clips lower, add a frame long enough to clip")


def _warn_if_levels_straddle(clip_tile_dn: np.ndarray, black_tile_dn: np.ndarray, white_level_dn: float) -> None:
    """Warn when some CFA positions clip below the top part of the black-to-white range and others within it.
    One sensor clips every position at about one level (hdrcam.io.raw_clipping), so one of the two is not the
    sensor's white; the radiance scale takes the metadata's (:func:`sensor_white_dn`), which may be that far off."""
    if straddles_top_part(clip_tile_dn, black_tile_dn, white_level_dn):
        start_dn = float(np.mean(black_tile_dn)) + SEARCH_FROM * (white_level_dn - float(np.mean(black_tile_dn)))
        warnings.warn(f"the CFA positions' clip levels ({', '.join(f'{v:g}' for v in clip_tile_dn.ravel())} DN) "
                      f"lie both below and above {start_dn:g} DN, half way to the white level {white_level_dn:g} "
                      "DN, where one sensor clips all of them at about one level: the radiance scale assumes the "
                      "white level, and may be off by their ratio")


def _warn_if_no_light(longest: RawFrame, black_dn: float, noise: NoiseModel) -> None:
    """Warn when even the longest frame recorded almost no light (fewer than LIT_FRACTION of its samples
    LIT_SIGMAS read-noise sigmas above black, and no 8-connected group of LIT_CLUSTER_SAMPLES of them): dark
    frames given as lights, or a capped lens. Hot pixels stand alone; a few lamps on black light compact groups,
    though far fewer samples than the fraction."""
    lit_mask = longest.bayer_dn > black_dn + LIT_SIGMAS * max(noise.read_noise_dn, 1.0)
    lit = np.count_nonzero(lit_mask)
    if lit < LIT_FRACTION * longest.bayer_dn.size and _clustered(lit_mask) < LIT_CLUSTER_SAMPLES:
        warnings.warn(f"{longest.metadata.path.name}, the longest frame, recorded almost no light ({lit} samples "
                      f"more than {LIT_SIGMAS:g} read-noise sigmas above black): dark frames given as lights "
                      "(give them with --darks), or the lens was capped?")


def _clustered(mask: np.ndarray) -> int:
    """How many True samples lie in 8-connected groups of at least LIT_CLUSTER_SAMPLES (a point light's core):
    random hot pixels, even thousands of them, next to never form one."""
    count, _, stats, _ = cv2.connectedComponentsWithStats(mask.view(np.uint8), connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    return int(areas[areas >= LIT_CLUSTER_SAMPLES].sum())


def _weighted(rates: list[np.ndarray], times: np.ndarray, usable: list[np.ndarray],
              variance_dn2: Callable[[int], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(sum_k w_k x_k / sum_k w_k, sum_k w_k) with w_k = t_k^2 / Var(y_k) on usable samples (float32, in frame
    order); ``x_k``: frame k's rate y_k / t_k, ``usable[k]``: uint8, nonzero where frame k is used,
    ``variance_dn2(k)``: Var(y_k) in DN^2 (a scratch array). The sums are OpenCV's masked accumulations (one
    pass each, where numpy needs a product, a sum and a masked copy)."""
    numerator, information = np.zeros_like(rates[0]), np.zeros_like(rates[0])
    weight = np.empty_like(rates[0])
    for k, (rate, t) in enumerate(zip(rates, times)):
        np.divide(t * t, variance_dn2(k), out=weight)
        cv2.accumulate(weight, information, mask=usable[k])
        cv2.accumulateProduct(weight, rate, numerator, mask=usable[k])
    # not cv2.max(information, 1e-30): OpenCV takes a 1 x 1 array beside a scalar for the scalar (a 4 x 1 result)
    return np.divide(numerator, np.maximum(information, np.float32(1e-30)), out=numerator), information


def affine(values: np.ndarray, scale: float, offset: float, *, out: np.ndarray) -> np.ndarray:
    """``scale * values + offset`` (float32) into ``out`` in one pass (OpenCV's weighted sum with a zero
    second term; numpy takes two)."""
    return cv2.addWeighted(values, scale, values, 0.0, offset, dst=out)
