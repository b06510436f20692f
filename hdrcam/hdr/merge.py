"""Merge a RAW bracket into linear HDR on the Bayer data (before demosaicing).

Per frame k with exposure t_k, black-subtracted signal y_k (DN) estimates the rate x = y_k / t_k. Under
the linear sensor's noise model, Var(y_k) = g * E[y_k] + r^2 (g DN per electron, r read noise in DN), the
minimum-variance unbiased combination weights each sample by its inverse variance, t_k^2 / Var(y_k)
(Granados et al. 2010); variances are evaluated at the pooled estimate (a second pass) so the weights do
not favour samples that happen to be low. Clipped samples (at or above the clip level measured per CFA
position from the data - the pile-up below the metadata white level, hdrcam.io.raw_clipping - minus a
margin, dilated so their neighbours are not trusted either) get no weight; a pixel clipped in every frame
keeps the lower bound clip / t_shortest and is flagged. Exposure ratios are estimated from the data
(ratio of sums over pixels unclipped in both frames), starting from the EXIF times.

Units of the result: relative radiance, full wells per second at ISO 100 (1.0 = a signal that fills the
sensor in one second at base ISO).

Speed: every per-pixel step runs on strips of rows in a thread pool (one thread per core; numpy releases the
GIL), and each pixel's arithmetic does not depend on the strip: a strip size changes nothing but the order
in which the exposure-ratio sums (float64) are added.
"""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from hdrcam.errors import InputError
from hdrcam.io.raw import RawFrame
from hdrcam.io.raw_clipping import clipped_samples, tiled
from hdrcam.parallel import strips, worker_threads
from hdrcam.profiles import CameraSpec

CLIP_MARGIN = 0.01  # of the black-to-clip range
MIN_RATIO_SAMPLES = 200
RATIO_HEADROOM = 0.7  # of the clip level, for the shorter frame of a pair
SIGNAL_FLOOR = 5.0  # read-noise sigmas in the selecting frame, for ratio estimation
STRIP_ROWS = 16  # rows per work item (5 frames x 16 rows x 6000 px of float32: 1.9 MB of temporaries)


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
    variance: np.ndarray  # H x W float32, of ``rate``
    clipped_everywhere: np.ndarray  # H x W bool: clipped in every frame; rate is a lower bound
    exposures_s: np.ndarray  # estimated true exposure per frame (shortest first)
    labelled_exposures_s: np.ndarray  # from the files
    clip_level_dn: float  # above black, the lowest of the CFA positions'
    clip_level_tile_dn: np.ndarray  # 2 x 2, absolute DN per CFA position: samples at or above are clipped
    notes: list[str]
    usable_frames: np.ndarray  # H x W uint8 bit mask: bit k set where frame k's sample was used
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


def black_subtracted(frame: RawFrame, dark: RawFrame | None = None, rows: slice = slice(None)) -> np.ndarray:
    """Signal in DN above black (float32) of ``rows`` (a slice with step 1); a dark frame, when given, replaces
    the black level."""
    bayer = frame.bayer_dn[rows].astype(np.float32)
    if dark is not None:
        if dark.bayer_dn.shape != frame.bayer_dn.shape:
            raise InputError(f"{dark.metadata.path}: dark frame size {dark.bayer_dn.shape} differs from "
                             f"{frame.bayer_dn.shape}")
        return bayer - dark.bayer_dn[rows].astype(np.float32)
    top = rows.indices(frame.bayer_dn.shape[0])[0]
    tile = np.roll(frame.metadata.black_level_tile(), -(top % 2), axis=0)  # the CFA phase of the first row
    height, width = bayer.shape
    black = np.tile(tile, ((height + 1) // 2, (width + 1) // 2))[:height, :width]
    return bayer - black


def clip_level_tile_dn(frames: list[RawFrame]) -> np.ndarray:
    """2 x 2 tile of clip levels (absolute DN) for a bracket: per CFA position, the lowest measured in any
    frame (one sensor at one ISO clips at one level; frames that reach it show the pile-up)."""
    return np.min(np.stack([frame.clip_level_tile_dn for frame in frames]), axis=0)


def dilated(mask: np.ndarray) -> np.ndarray:
    """A clipped-sample mask grown by one pixel: neighbours of clipped samples (blooming, crosstalk, and the
    demosaicing footprint) are not trusted either."""
    return cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)


def estimate_exposures(signals: list[np.ndarray], masks: list[np.ndarray], labelled_s: np.ndarray,
                       threshold_dn: float, noise_floor_dn: float, notes: list[str],
                       pool: ThreadPoolExecutor | None = None) -> np.ndarray:
    """True exposure times from the data: adjacent-frame ratios, anchored to the labels' geometric mean.

    The ratio of frame k+1 to k is sum(y_k+1) / sum(y_k) over pixels unclipped in both whose shorter-frame
    signal is below RATIO_HEADROOM of the clip level divided by the ratio, and which carry signal: a third
    frame (k+2, else k-1) is above SIGNAL_FLOOR read-noise sigmas there or clipped. Selecting on a frame
    outside the pair keeps the selection independent of the pair's noise (selecting on a noisy value near a
    floor biases the ratio), while dropping the empty background, whose noise would swamp a point source.
    """
    ratios = []
    parts = strips(signals[0].shape[0], STRIP_ROWS)
    for k in range(len(signals) - 1):  # masks: clipped samples, not dilated (each sample stands alone here)
        labelled = labelled_s[k + 1] / labelled_s[k]
        other = k + 2 if k + 2 < len(signals) else k - 1
        candidates = np.empty(signals[0].shape, bool)  # unclipped in both frames and carrying signal

        def select(rows: slice, k=k, other=other) -> None:
            candidates[rows] = ~masks[k][rows] & ~masks[k + 1][rows]
            if other >= 0:
                candidates[rows] &= (signals[other][rows] > SIGNAL_FLOOR * noise_floor_dn) | masks[other][rows]

        list((pool.map if pool else map)(select, parts))
        ratio, count = labelled, 0
        for _ in range(3):  # the upper bound depends on the ratio: refine it
            bound = RATIO_HEADROOM * threshold_dn / ratio

            def sums(rows: slice, k=k, bound=bound) -> tuple[int, float, float]:
                short = signals[k][rows]
                valid = candidates[rows] & (short < bound)
                return (int(np.count_nonzero(valid)), float(short[valid].sum(dtype=np.float64)),
                        float(signals[k + 1][rows][valid].sum(dtype=np.float64)))

            totals = np.array(list((pool.map if pool else map)(sums, parts)), np.float64).sum(axis=0)
            count, denominator = int(totals[0]), float(totals[1])
            if count < MIN_RATIO_SAMPLES or denominator <= 0:
                break
            ratio = float(totals[2]) / denominator
        if count < MIN_RATIO_SAMPLES or ratio <= 1.0:
            notes.append(f"frames {k}-{k + 1}: only {count} pixels usable in both; using the labelled ratio "
                         f"{labelled:.4f}")
            ratio = labelled
        else:
            notes.append(f"frames {k}-{k + 1}: ratio {ratio:.4f} from {count} pixels (labels say {labelled:.4f})")
        ratios.append(ratio)
    relative = np.concatenate([[1.0], np.cumprod(ratios)])
    scale = np.exp(np.mean(np.log(labelled_s)) - np.mean(np.log(relative)))
    return relative * scale


def merge_bayer(frames: list[RawFrame], camera: CameraSpec, *, darks: list[RawFrame | None] | None = None,
                estimate_ratios: bool = True, threads: int | None = None) -> BayerMerge:
    """Inverse-variance merge of black-subtracted Bayer frames (shortest first), on ``threads`` threads
    (default: one per core)."""
    meta = frames[0].metadata
    iso = meta.iso or 100.0
    black = float(np.mean(meta.black_level_dn))
    noise = NoiseModel.from_camera(camera, iso, meta.white_level_dn, black)
    darks = darks or [None] * len(frames)
    read_variance = noise.read_noise_dn ** 2 * (2.0 if any(d is not None for d in darks) else 1.0)
    notes: list[str] = []
    clip_tile = clip_level_tile_dn(frames)
    black_tile = meta.black_level_tile()
    threshold_tile = black_tile + (clip_tile - black_tile) * (1.0 - CLIP_MARGIN)
    clip = float((clip_tile - black_tile).min())
    threshold = clip * (1.0 - CLIP_MARGIN)
    height, width = frames[0].bayer_dn.shape
    signals = [np.empty((height, width), np.float32) for _ in frames]
    clipped = [np.empty((height, width), bool) for _ in frames]
    labelled = np.array([frame.metadata.exposure_s for frame in frames])
    rate = np.empty((height, width), np.float32)
    variance = np.empty((height, width), np.float32)
    everywhere = np.empty((height, width), bool)
    usable_frames = np.zeros((height, width), np.uint8)

    def prepare(rows: slice) -> None:
        for k, (frame, dark) in enumerate(zip(frames, darks)):
            signals[k][rows] = black_subtracted(frame, dark, rows)
            phase = rows.indices(height)[0] % 2  # the CFA row phase of the strip's first row
            clipped[k][rows] = clipped_samples(frame.bayer_dn[rows], np.roll(threshold_tile, -phase, axis=0))

    def merge_strip(rows: slice) -> None:
        y = np.stack([s[rows] for s in signals])
        usable = ~np.stack([m[rows] for m in masks])
        usable_frames[rows] = (usable.astype(np.uint8) << np.arange(len(frames), dtype=np.uint8)[:, None, None]).sum(
            axis=0, dtype=np.uint8)
        t = exposures[:, None, None].astype(np.float32)
        estimate = _weighted(y, t, usable, np.maximum(y, 0.0) * noise.gain_dn_per_e + read_variance)[0]
        pooled = np.maximum(estimate, 0.0)[None] * t * noise.gain_dn_per_e + read_variance
        estimate, information = _weighted(y, t, usable, pooled)
        none = ~usable.any(axis=0)
        phase = rows.indices(height)[0] % 2
        lower_bound = tiled(np.roll(threshold_tile - black_tile, -phase, axis=0), y.shape[1], width) / exposures[0]
        estimate[none] = lower_bound[none]
        information[none] = 0.0
        rate[rows], everywhere[rows] = estimate, none
        variance[rows] = np.where(none, np.inf, 1.0 / np.maximum(information, 1e-30))

    with ThreadPoolExecutor(threads or worker_threads()) as pool:
        list(pool.map(prepare, strips(height, STRIP_ROWS)))
        exposures = estimate_exposures(signals, clipped, labelled, threshold, np.sqrt(read_variance), notes, pool) \
            if estimate_ratios and len(frames) > 1 else labelled.copy()
        masks = list(pool.map(dilated, clipped))
        list(pool.map(merge_strip, strips(height, STRIP_ROWS)))
    to_relative = 1.0 / ((meta.white_level_dn - black) * (iso / 100.0))
    variance *= to_relative ** 2
    variance[everywhere] = np.float32(np.finfo(np.float32).max)
    return BayerMerge(rate * to_relative, variance, everywhere, exposures, labelled, clip, clip_tile, notes,
                      usable_frames, noise, read_variance, to_relative)


def _weighted(y: np.ndarray, t: np.ndarray, usable: np.ndarray, variance_dn2: np.ndarray):
    """sum_k w_k (y_k / t_k) / sum_k w_k with w_k = t_k^2 / Var(y_k) on usable samples; also sum_k w_k."""
    weights = np.where(usable, t * t / variance_dn2, np.float32(0.0))
    information = weights.sum(axis=0)
    estimate = (weights * (y / t)).sum(axis=0) / np.maximum(information, 1e-30)
    return estimate.astype(np.float32), information
