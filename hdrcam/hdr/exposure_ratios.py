"""True exposure times of a bracket, estimated from its data: ratios of adjacent frames, anchored to the labels.

The ratio of frame k+1 to k is taken over pixels unclipped in both whose shorter-frame signal, predicted by the
mean of its eight same-colour neighbours (hdrcam.hdr.neighbour_mean), lies below RATIO_HEADROOM of the clip
level divided by the ratio and ADC_ZERO_SIGMAS read-noise sigmas above the ADC's zero (0 DN; a black level of 0
puts it at black, a high ISO's noise reaches it from a black of 512: the data clip the noise there, and the
clipped samples' mean lies above their signal - by 0.4 % at 2 sigmas, 0.01 % at 3), and which carry signal in a
third frame (k+2, else k-1: above SIGNAL_FLOOR sigmas there, or clipped). The bounds and the signal tests use
values whose noise is independent of the pixel's own two samples: a bound on a sample's own noisy value biases
the sums. Bounding y_k itself made the ratio 26.1 for a true 7.8 at ISO 25600 (a bound of a few electrons: the
samples that read high were the ones dropped) and 9.1 for 7.9 at ISO 6400; from the neighbours, 7.7 and 7.9. The
third frame drops the empty background, whose noise would swamp a point source.

The estimate is the instrumental-variable slope cov(z, y_k+1) / cov(z, y_k), the instrument z the pixel's own
sample in the third frame (its noise is independent of both samples', and it is as sharp as they are: the
neighbour mean, blurred over the CFA's spacing, made the ratios a fifth noisier on 96 x 128 crops; a two-frame
bracket has only the neighbour mean): a black level off by a fraction of a DN in either frame, which biases a
ratio of sums by that fraction over the shorter frame's mean signal (one DN over a frame 2 DN above black: 36 %
off, for every pixel of the image through the scale; +-1 DN, 5-9 % on a simulated night bracket), cancels from
it. The slope is used where its standard error (instrumental variables': the residuals' spread times z's,
over the covariance; offset-free too) is at most SLOPE_ERROR of it. A scene without that
contrast (a flat field) gives the ratio of the sums, sum(y_k+1) / sum(y_k), where the shorter frame's mean
signal is at least SUMS_MIN_SIGNAL_DN (a DN of black-level error then moves it 1 % at most), and says so; else
the label stands, with the reason. The upper bound depends on the ratio, so each ratio is refined up to
REFINEMENTS times, starting from the labels. A ratio more than IMPLAUSIBLE_STOPS from its label is used, with a
warning.

Given the frames' names, a pair whose data contradict the bracket is refused (InputError naming the frame): a longer
frame no brighter than the shorter one where a ratio follows from the data (a slope or sums that clear the bounds
above: not noise or a black-level error), or a shorter frame with no signal above black where the third frame,
scaled by the labels, says it should average at least NO_LIGHT_EXPECTED_DN (a capped lens, a failed shutter or
flash, a frame of another scene). Its full inverse-variance weight would pull the merge down by its error (a
black middle frame of four left three patches at 0.075 of their radiance). A pair with too few pixels or too
little signal to tell keeps its label.

Signals are in DN above black; exposures in seconds.

Speed: one pass over strips of rows (a thread pool's map) serves every refinement. Per pair it sums the
selected pixels whose neighbour mean lies below the labelled bound divided by BOUND_BAND, and keeps those
within BOUND_BAND of that bound; a refinement whose bound stays in the band adds the kept pixels below
it to those sums. A bound outside the band (a ratio off its label by more than BOUND_BAND) costs one more
pass for that refinement. The sums (count, and of y_k, y_k+1, z, z y_k, z y_k+1) are float64 sums of float32
products (OpenCV; not BLAS, whose own threads would compete with the pool's).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from hdrcam.errors import InputError
from hdrcam.hdr.neighbour_mean import NEIGHBOUR_ROWS, neighbour_mean

MIN_RATIO_SAMPLES = 200
RATIO_HEADROOM = 0.7  # of the clip level, for the shorter frame of a pair
SIGNAL_FLOOR = 5.0  # read-noise sigmas in the selecting frame
REFINEMENTS = 3
BOUND_BAND = 1.25  # pixels within this factor of the labelled bound are kept for the refinements
ADC_ZERO_SIGMAS = 2.0  # the shorter frame's prediction above the ADC's zero (module docstring)
SLOPE_ERROR = 0.01  # the slope's relative standard error, at most
SPREAD_PRECISION = 1e-6  # of the sum of z^2: a spread below it is rounding (float32 products: ~1e-7), not contrast
SUMS_MIN_SIGNAL_DN = 100.0  # the shorter frame's mean signal for the ratio of sums: a DN of black error, 1 %
NO_LIGHT_EXPECTED_DN = 30.0  # a frame expected this far above black that averages at or below it recorded no
# light: more than a black level's error (per-row BlackLevelDeltaV offsets averaged into one level: up to 25 DN)
IMPLAUSIBLE_STOPS = 0.5  # a working shutter is off its label by a few per cent; half a stop is 41 %
SUMS = 10  # per pair: count, and the sums of y_k, y_k+1, z, z y_k, z y_k+1, z^2, y_k^2, y_k+1^2, y_k y_k+1

StripData = Callable[[slice], tuple[list[np.ndarray], list[np.ndarray]]]


def estimate_exposures(strip_data: StripData, row_strips: list[slice], labelled_s: np.ndarray, threshold_dn: float,
                       noise_floor_dn: float, notes: list[str], pool: ThreadPoolExecutor, *, black_dn: float = np.inf,
                       names: list[str] | None = None) -> np.ndarray:
    """Estimated exposure per frame (seconds, shortest first; geometric mean equal to the labels').

    ``strip_data(rows)``: every frame's float32 signal (DN above black) on those rows and its samples at or
    above the clip threshold ``threshold_dn`` (bool; not dilated: each sample stands alone here);
    ``noise_floor_dn``: the read noise of one signal; ``black_dn``: the black level, the signal of the ADC's zero
    below it (the default: far). One line per pair is appended to ``notes``. ``names``: the frames' paths, to
    refuse a frame whose data contradict the bracket (module docstring); without them its pair keeps its label.
    """
    floor_dn = ADC_ZERO_SIGMAS * noise_floor_dn - black_dn  # the shorter frame's prediction, clear of the ADC's zero
    pairs = len(labelled_s) - 1
    labelled = [float(labelled_s[k + 1] / labelled_s[k]) for k in range(pairs)]

    def bound_dn(ratio: float) -> float:
        return RATIO_HEADROOM * threshold_dn / ratio

    bands = [(bound_dn(ratio) / BOUND_BAND, bound_dn(ratio) * BOUND_BAND) for ratio in labelled]

    height = max(rows.stop for rows in row_strips)

    def strip_and_predictions(rows: slice) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
        """The strip's signals and clipped samples, and each pair's shorter-frame neighbour means (from the
        strip and NEIGHBOUR_ROWS rows either side: the same whatever the strips)."""
        top, bottom = max(rows.start - NEIGHBOUR_ROWS, 0), min(rows.stop + NEIGHBOUR_ROWS, height)
        signals, clipped = strip_data(slice(top, bottom))
        inner = slice(rows.start - top, rows.stop - top)
        predicted = [neighbour_mean(signal)[inner] for signal in signals[:pairs]]
        return [signal[inner] for signal in signals], [mask[inner] for mask in clipped], predicted

    def first_pass(rows: slice) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]]:
        signals, clipped, predictions = strip_and_predictions(rows)
        below_band = np.zeros((pairs, SUMS), np.float64)
        kept = []
        for k, (low, high) in enumerate(bands):
            predicted = predictions[k]
            selected = _selected(signals, clipped, predicted, k, noise_floor_dn, floor_dn)
            below = np.less(predicted, low)
            below &= selected
            instrument = _instrument(signals, predicted, k)
            below_band[k] = _sums(instrument, signals[k], signals[k + 1], below)
            inside = np.greater_equal(predicted, low)
            inside &= np.less(predicted, high)
            inside &= selected
            kept.append((predicted[inside], instrument[inside], signals[k][inside], signals[k + 1][inside]))
        return below_band, kept

    strip_results = list(pool.map(first_pass, row_strips))
    below_band = np.sum([below for below, _ in strip_results], axis=0)  # added in strip order
    kept = [strip_kept for _, strip_kept in strip_results]  # per strip, per pair

    def full_pass(bounds: dict[int, float]) -> np.ndarray:
        def sums(rows: slice) -> np.ndarray:
            signals, clipped, predictions = strip_and_predictions(rows)
            totals = np.zeros((pairs, SUMS), np.float64)
            for k, bound in bounds.items():
                valid = np.less(predictions[k], bound)
                valid &= _selected(signals, clipped, predictions[k], k, noise_floor_dn, floor_dn)
                totals[k] = _sums(_instrument(signals, predictions[k], k), signals[k], signals[k + 1], valid)
            return totals

        return np.sum(list(pool.map(sums, row_strips)), axis=0)

    ratios, refining = list(labelled), list(range(pairs))
    counts, methods = [0] * pairs, [""] * pairs  # each pair's pixels and method at its last refinement
    unestimated: dict[int, str] = {}  # pair -> why its labelled ratio is used
    contradictions: dict[int, str] = {}  # pair -> the refusal naming its contradicting frame (with ``names``)
    for _ in range(REFINEMENTS):
        bounds = {k: bound_dn(ratios[k]) for k in refining}
        outside = {k: bound for k, bound in bounds.items() if not bands[k][0] <= bound <= bands[k][1]}
        totals = full_pass(outside) if outside else np.zeros((pairs, SUMS))
        in_band = {k: bound for k, bound in bounds.items() if k not in outside}
        kept_totals = np.sum(list(pool.map(lambda strip_kept: _kept_sums(strip_kept, in_band), kept)), axis=0)
        for k in in_band:
            totals[k] = below_band[k] + kept_totals[k]
        for k in list(refining):
            counts[k] = int(totals[k, 0])
            ratio, methods[k], why_not = _ratio(totals[k])
            if ratio is not None:
                ratios[k] = ratio
                continue
            unestimated[k] = why_not
            if names is not None:
                contradiction = _contradiction(totals[k], k, labelled, names)
                if contradiction:
                    contradictions[k] = contradiction
            ratios[k] = labelled[k]
            refining.remove(k)
    if contradictions:
        raise InputError(contradictions[min(contradictions)])
    for k in range(pairs):
        if k in unestimated:
            notes.append(f"frames {k}-{k + 1}: {unestimated[k]}; using the labelled ratio {labelled[k]:.4f}")
            continue
        how = "" if methods[k] == "slope" else \
            " (the frames' sums: too little contrast for a slope that cancels a black-level error)"
        notes.append(f"frames {k}-{k + 1}: ratio {ratios[k]:.4f} from {counts[k]} pixels{how} (labels say "
                     f"{labelled[k]:.4f})")
        stops = float(np.log2(ratios[k] / labelled[k]))
        if abs(stops) > IMPLAUSIBLE_STOPS:
            warnings.warn(f"frames {k}-{k + 1}: their data give an exposure ratio of {ratios[k]:.4g} where the labels "
                          f"say {labelled[k]:.4g} ({stops:+.1f} stops), and the image's scale follows it: a "
                          "mislabelled exposure (bulb, a rounded long one), flickering light or a wrong black level?")
    relative = np.concatenate([[1.0], np.cumprod(ratios)])
    scale = np.exp(np.mean(np.log(labelled_s)) - np.mean(np.log(relative)))
    return relative * scale


def _ratio(totals: np.ndarray, require_brighter: bool = True) -> tuple[float | None, str, str]:
    """A pair's ratio from its sums (module docstring), how it was found ("slope" or "sums"), and why none
    follows from them when it is None; ``require_brighter`` False: also a ratio of 1 or less (what the data say,
    though no bound follows from it)."""
    count, shorter, longer, instrument, instrument_shorter, instrument_longer, instrument_squared, \
        shorter_squared, longer_squared, shorter_longer = totals
    if count < MIN_RATIO_SAMPLES:
        return None, "", f"only {int(count)} pixels usable in both"

    def centred(product: float, first: float, second: float) -> float:  # sum of (a - mean a)(b - mean b)
        return product - first * second / count

    covariance = centred(instrument_shorter, instrument, shorter)
    slope = centred(instrument_longer, instrument, longer) / covariance if covariance > 0 else 0.0
    residual = centred(longer_squared, longer, longer) - 2 * slope * centred(shorter_longer, shorter, longer) + \
        slope ** 2 * centred(shorter_squared, shorter, shorter)  # of y_k+1 - slope y_k, times count
    spread = centred(instrument_squared, instrument, instrument)  # of z; lost to rounding on a uniform field
    error = np.sqrt(max(residual, 0.0) * spread / count) / covariance \
        if covariance > 0 and spread > SPREAD_PRECISION * instrument_squared else np.inf  # the slope's std. error
    mean_dn = shorter / count
    if slope > 0 and error <= SLOPE_ERROR * slope:
        numerator, denominator, how = slope, 1.0, "slope"
    elif mean_dn >= SUMS_MIN_SIGNAL_DN:
        numerator, denominator, how = longer, shorter, "sums"
    elif mean_dn <= 0:
        return None, "", f"the shorter frame's {int(count)} usable pixels hold no signal above black"
    else:
        return None, "", (f"too little contrast for a slope (standard error {_percent(error, slope)} over "
                          f"{int(count)} pixels) and signal for the sums (mean {mean_dn:.3g} DN: a DN of "
                          f"black-level error moves them {100 / mean_dn:.0f} %)")
    if numerator <= denominator and require_brighter:  # no bound follows from a longer frame that is no brighter
        return None, "", (f"the longer frame is no brighter over {int(count)} usable pixels (ratio "
                          f"{numerator / denominator:.4f})")
    return float(numerator / denominator), how, ""


def _contradiction(totals: np.ndarray, k: int, labelled: list[float], names: list[str]) -> str:
    """The refusal of pair k's contradicting frame (module docstring), or "" where its data say nothing against
    the labels (too few pixels, too little signal)."""
    count, shorter, longer, instrument = totals[:4]
    if count < MIN_RATIO_SAMPLES:
        return ""
    measured, _, _ = _ratio(totals, require_brighter=False)
    why = "it recorded no light (a capped lens, a failed shutter or flash), or it is another scene's or mislabelled; " \
        "remove it from the bracket"
    if measured is not None and measured <= 1.0:  # a bracket is sorted by exposure: every labelled ratio is > 1
        return (f"{names[k + 1]}: exposed {labelled[k]:.3g} times as long as {os.path.basename(names[k])}, yet no "
                f"brighter over {int(count)} pixels usable in both (ratio {measured:.3g}): {why}")
    other = _third_frame(k, len(names))
    if shorter > 0 or other < 0:
        return ""
    scale = 1.0 / (labelled[k] * labelled[k + 1]) if other > k else labelled[k - 1]  # the third frame's to frame k's
    expected_dn = instrument / count * scale
    if expected_dn < NO_LIGHT_EXPECTED_DN:  # too dim to tell a frame without light from a black-level error
        return ""
    return (f"{names[k]}: no signal above black over {int(count)} pixels where {os.path.basename(names[other])} "
            f"says, by the labelled exposures, about {expected_dn:.0f} DN: {why}")


def _percent(error: float, slope: float) -> str:
    return f"{100 * error / slope:.2g} %" if slope > 0 and np.isfinite(error) else "unbounded"


def _kept_sums(strip_kept: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
               bounds_dn: dict[int, float]) -> np.ndarray:
    """Per pair k of ``bounds_dn``: the SUMS over a strip's kept pixels of that pair (``strip_kept[k]``: the
    shorter frame's neighbour mean, the instrument and both frames' float32 signals) whose neighbour mean is
    below ``bounds_dn[k]``."""
    totals = np.zeros((len(strip_kept), SUMS), np.float64)
    for k, bound in bounds_dn.items():
        predicted, instrument, shorter, longer = strip_kept[k]
        totals[k] = _sums(instrument, shorter, longer, np.less(predicted, bound))
    return totals


def _sums(instrument: np.ndarray, shorter: np.ndarray, longer: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The SUMS (count; sums of ``shorter``, ``longer``, ``instrument``, ``instrument`` times each of them, and
    the squares of ``instrument``, ``shorter`` and ``longer``, and ``shorter`` times ``longer``) over ``valid``:
    float32 products summed in float64 by OpenCV (numpy's einsum sums in float32, whose rounding the
    covariances' differences magnified to 2e-6 of the ratios between strip sizes)."""
    weights = valid.astype(np.float32)
    weighted = cv2.multiply(instrument, weights)
    weighted_shorter = cv2.multiply(shorter, weights)
    return np.array([np.count_nonzero(valid), cv2.sumElems(weighted_shorter)[0],
                     cv2.sumElems(cv2.multiply(longer, weights))[0], cv2.sumElems(weighted)[0],
                     cv2.sumElems(cv2.multiply(shorter, weighted))[0], cv2.sumElems(cv2.multiply(longer, weighted))[0],
                     cv2.sumElems(cv2.multiply(instrument, weighted))[0],
                     cv2.sumElems(cv2.multiply(shorter, weighted_shorter))[0],
                     cv2.sumElems(cv2.multiply(longer, cv2.multiply(longer, weights)))[0],
                     cv2.sumElems(cv2.multiply(longer, weighted_shorter))[0]])


def _third_frame(k: int, frames: int) -> int:
    """The frame pair k draws on beside its own two: k+2, else k-1 (-1: none, a two-frame bracket)."""
    return k + 2 if k + 2 < frames else k - 1


def _instrument(signals: list[np.ndarray], predicted: np.ndarray, k: int) -> np.ndarray:
    """Pair k's instrument on a strip: the third frame's signal, else ``predicted`` (the shorter frame's
    neighbour mean)."""
    other = _third_frame(k, len(signals))
    return signals[other] if other >= 0 else predicted


def _selected(signals: list[np.ndarray], clipped: list[np.ndarray], predicted: np.ndarray, k: int,
              noise_floor_dn: float, floor_dn: float) -> np.ndarray:
    """Strip bool: unclipped in frames k and k+1, the shorter frame's prediction ``predicted`` at ``floor_dn``
    or above, and signal in a third frame (or clipped there)."""
    selected = np.logical_or(clipped[k], clipped[k + 1])
    np.logical_not(selected, out=selected)
    if floor_dn > -np.inf:
        selected &= predicted >= floor_dn
    other = _third_frame(k, len(signals))
    if other >= 0:
        selected &= (signals[other] > SIGNAL_FLOOR * noise_floor_dn) | clipped[other]
    return selected
