"""True exposure times of a bracket, estimated from its data: ratios of adjacent frames, anchored to the labels.

The ratio of frame k+1 to k is sum(y_k+1) / sum(y_k) over pixels unclipped in both whose shorter-frame signal,
predicted by the mean of its eight same-colour neighbours (hdrcam.hdr.neighbour_mean), is below RATIO_HEADROOM of the
clip level divided by the ratio, and which carry signal: a third frame (k+2, else k-1) is above SIGNAL_FLOOR
read-noise sigmas there or clipped. The bound and the signal test use values whose noise is independent of
the pixel's own two samples: a bound on a sample's own noisy value biases the sums. Bounding y_k itself made the
ratio 26.1 for a true 7.8 at ISO 25600 (a bound of a few electrons: the samples that read high were the ones
dropped) and 9.1 for 7.9 at ISO 6400; from the neighbours, 7.7 and 7.9. The third frame drops the empty
background, whose noise would swamp a point source. The upper bound depends on the ratio, so each ratio is
refined up to REFINEMENTS times, starting from the labels.

Signals are in DN above black; exposures in seconds.

Speed: one pass over strips of rows (a thread pool's map) serves every refinement. Per pair it sums the
selected pixels whose neighbour mean lies below the labelled bound divided by BOUND_BAND, and keeps those
within BOUND_BAND of that bound; a refinement whose bound stays in the band adds the kept pixels below
it to those sums. A bound outside the band (a ratio off its label by more than BOUND_BAND) costs one more
pass for that refinement. A strip's sums are float32 sums of products by numpy's einsum (relative error
~1e-7; not BLAS, whose own threads would compete with the pool's), added over strips in float64, as are the
kept pixels' sums.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from hdrcam.hdr.neighbour_mean import NEIGHBOUR_ROWS, neighbour_mean

MIN_RATIO_SAMPLES = 200
RATIO_HEADROOM = 0.7  # of the clip level, for the shorter frame of a pair
SIGNAL_FLOOR = 5.0  # read-noise sigmas in the selecting frame
REFINEMENTS = 3
BOUND_BAND = 1.25  # pixels within this factor of the labelled bound are kept for the refinements

StripData = Callable[[slice], tuple[list[np.ndarray], list[np.ndarray]]]


def estimate_exposures(strip_data: StripData, row_strips: list[slice], labelled_s: np.ndarray, threshold_dn: float,
                       noise_floor_dn: float, notes: list[str], pool: ThreadPoolExecutor) -> np.ndarray:
    """Estimated exposure per frame (seconds, shortest first; geometric mean equal to the labels').

    ``strip_data(rows)``: every frame's float32 signal (DN above black) on those rows and its samples at or
    above the clip threshold ``threshold_dn`` (bool; not dilated: each sample stands alone here);
    ``noise_floor_dn``: the read noise of one signal. One line per pair is appended to ``notes``.
    """
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

    def first_pass(rows: slice) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
        signals, clipped, predictions = strip_and_predictions(rows)
        below_band = np.zeros((pairs, 3), np.float64)
        kept = []
        for k, (low, high) in enumerate(bands):
            selected = _selected(signals, clipped, k, noise_floor_dn)
            predicted = predictions[k]
            below = np.less(predicted, low)
            below &= selected
            below_band[k] = _sums(signals[k], signals[k + 1], below)
            inside = np.greater_equal(predicted, low)
            inside &= np.less(predicted, high)
            inside &= selected
            kept.append((predicted[inside], signals[k][inside], signals[k + 1][inside]))
        return below_band, kept

    strip_results = list(pool.map(first_pass, row_strips))
    below_band = np.sum([below for below, _ in strip_results], axis=0)  # added in strip order
    kept = [strip_kept for _, strip_kept in strip_results]  # per strip, per pair

    def full_pass(bounds: dict[int, float]) -> np.ndarray:
        def sums(rows: slice) -> np.ndarray:
            signals, clipped, predictions = strip_and_predictions(rows)
            totals = np.zeros((pairs, 3), np.float64)
            for k, bound in bounds.items():
                valid = np.less(predictions[k], bound)
                valid &= _selected(signals, clipped, k, noise_floor_dn)
                totals[k] = _sums(signals[k], signals[k + 1], valid)
            return totals

        return np.sum(list(pool.map(sums, row_strips)), axis=0)

    ratios, counts, refining = list(labelled), [0] * pairs, list(range(pairs))
    unestimated: dict[int, str] = {}  # pair -> why its labelled ratio is used
    for _ in range(REFINEMENTS):
        bounds = {k: bound_dn(ratios[k]) for k in refining}
        outside = {k: bound for k, bound in bounds.items() if not bands[k][0] <= bound <= bands[k][1]}
        totals = full_pass(outside) if outside else np.zeros((pairs, 3))
        in_band = {k: bound for k, bound in bounds.items() if k not in outside}
        kept_totals = np.sum(list(pool.map(lambda strip_kept: _kept_sums(strip_kept, in_band), kept)), axis=0)
        for k in in_band:
            totals[k] = below_band[k] + kept_totals[k]
        for k in list(refining):
            counts[k] = int(totals[k, 0])
            if counts[k] < MIN_RATIO_SAMPLES:
                unestimated[k] = f"only {counts[k]} pixels usable in both"
            elif totals[k, 1] <= 0:
                unestimated[k] = f"the shorter frame's {counts[k]} usable pixels hold no signal above black"
            elif totals[k, 2] <= totals[k, 1]:  # no bound follows from a longer frame that is no brighter
                unestimated[k] = (f"the longer frame is no brighter over {counts[k]} usable pixels (ratio "
                                  f"{totals[k, 2] / totals[k, 1]:.4f})")
            else:
                ratios[k] = float(totals[k, 2] / totals[k, 1])
                continue
            ratios[k] = labelled[k]
            refining.remove(k)
    for k in range(pairs):
        if k in unestimated:
            notes.append(f"frames {k}-{k + 1}: {unestimated[k]}; using the labelled ratio {labelled[k]:.4f}")
        else:
            notes.append(f"frames {k}-{k + 1}: ratio {ratios[k]:.4f} from {counts[k]} pixels (labels say "
                         f"{labelled[k]:.4f})")
    relative = np.concatenate([[1.0], np.cumprod(ratios)])
    scale = np.exp(np.mean(np.log(labelled_s)) - np.mean(np.log(relative)))
    return relative * scale


def _kept_sums(strip_kept: list[tuple[np.ndarray, np.ndarray, np.ndarray]], bounds_dn: dict[int, float]
               ) -> np.ndarray:
    """Per pair k of ``bounds_dn``: (count, sum of the shorter, sum of the longer frame's signal) over a strip's
    kept pixels of that pair (``strip_kept[k]``: the shorter frame's neighbour mean and both frames' float32
    signals) whose neighbour mean is below ``bounds_dn[k]``, summed in float64 (einsum casting to float64 as it
    goes)."""
    totals = np.zeros((len(strip_kept), 3), np.float64)
    for k, bound in bounds_dn.items():
        predicted, shorter, longer = strip_kept[k]
        below = np.less(predicted, bound).view(np.uint8)  # as 0 / 1 weights: a third of a selection's time
        totals[k] = (np.count_nonzero(below), np.einsum("i,i->", shorter, below, dtype=np.float64),
                     np.einsum("i,i->", longer, below, dtype=np.float64))
    return totals


def _sums(shorter: np.ndarray, longer: np.ndarray, valid: np.ndarray) -> tuple[int, float, float]:
    """(count, sum of ``shorter``, sum of ``longer``) over ``valid`` (float32 products summed by einsum)."""
    weights = valid.astype(np.float32)
    return (np.count_nonzero(valid), float(np.einsum("ij,ij->", shorter, weights)),
            float(np.einsum("ij,ij->", longer, weights)))


def _selected(signals: list[np.ndarray], clipped: list[np.ndarray], k: int, noise_floor_dn: float) -> np.ndarray:
    """Strip bool: unclipped in frames k and k+1 and carrying signal in a third frame (or clipped there)."""
    selected = np.logical_or(clipped[k], clipped[k + 1])
    np.logical_not(selected, out=selected)
    other = k + 2 if k + 2 < len(signals) else k - 1
    if other >= 0:
        selected &= (signals[other] > SIGNAL_FLOOR * noise_floor_dn) | clipped[other]
    return selected
