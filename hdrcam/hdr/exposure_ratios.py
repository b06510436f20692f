"""True exposure times of a bracket, estimated from its data: ratios of adjacent frames, anchored to the labels.

The ratio of frame k+1 to k is sum(y_k+1) / sum(y_k) over pixels unclipped in both whose shorter-frame signal
is below RATIO_HEADROOM of the clip level divided by the ratio, and which carry signal: a third frame (k+2,
else k-1) is above SIGNAL_FLOOR read-noise sigmas there or clipped. Selecting on a frame outside the pair
keeps the selection independent of the pair's noise (selecting on a noisy value near a floor biases the
ratio), while dropping the empty background, whose noise would swamp a point source. The upper bound depends
on the ratio, so each ratio is refined up to REFINEMENTS times, starting from the labels.

Signals are in DN above black; exposures in seconds. Every pair's sums of one refinement are taken in one
pass over strips of rows (a thread pool's map; the first pass also keeps each pair's candidate pixels for
the next): a strip's sums are float32 sums of products by numpy's einsum (relative error ~1e-7; not BLAS,
whose own threads would compete with the pool's), added over strips in float64.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

MIN_RATIO_SAMPLES = 200
RATIO_HEADROOM = 0.7  # of the clip level, for the shorter frame of a pair
SIGNAL_FLOOR = 5.0  # read-noise sigmas in the selecting frame
REFINEMENTS = 3


def estimate_exposures(strip_signals: Callable[[slice], list[np.ndarray]], clipped: list[np.ndarray],
                       row_strips: list[slice], labelled_s: np.ndarray, threshold_dn: float, noise_floor_dn: float,
                       notes: list[str], pool: ThreadPoolExecutor) -> np.ndarray:
    """Estimated exposure per frame (seconds, shortest first; geometric mean equal to the labels').

    ``strip_signals(rows)``: every frame's float32 signal (DN above black) on those rows; ``clipped``: H x W bool
    per frame, samples at or above the clip threshold ``threshold_dn`` (not dilated: each sample stands alone
    here); ``noise_floor_dn``: the read noise of one signal. One line per pair is appended to ``notes``.
    """
    pairs = len(labelled_s) - 1
    labelled = [float(labelled_s[k + 1] / labelled_s[k]) for k in range(pairs)]
    ratios, counts, refining = list(labelled), [0] * pairs, list(range(pairs))
    candidates = [np.empty(clipped[0].shape, bool) for _ in range(pairs)]  # found in the first pass
    for refinement in range(REFINEMENTS):
        bounds = {k: RATIO_HEADROOM * threshold_dn / ratios[k] for k in refining}

        def sums(rows: slice, bounds=bounds, first=refinement == 0) -> np.ndarray:
            signals = strip_signals(rows)
            totals = np.zeros((pairs, 3), np.float64)  # per pair: count, sum of the shorter, sum of the longer
            for k, bound in bounds.items():
                if first:
                    _find_candidates(signals, clipped, k, rows, noise_floor_dn, out=candidates[k][rows])
                valid = np.less(signals[k], bound)
                valid &= candidates[k][rows]
                weights = valid.astype(np.float32)
                totals[k] = (np.count_nonzero(valid), np.einsum("ij,ij->", signals[k], weights),
                             np.einsum("ij,ij->", signals[k + 1], weights))
            return totals

        totals = np.sum(list(pool.map(sums, row_strips)), axis=0)  # added in strip order
        for k in list(refining):
            counts[k] = int(totals[k, 0])
            if counts[k] < MIN_RATIO_SAMPLES or totals[k, 1] <= 0:
                refining.remove(k)
            else:
                ratios[k] = float(totals[k, 2] / totals[k, 1])
    for k in range(pairs):
        if counts[k] < MIN_RATIO_SAMPLES or ratios[k] <= 1.0:
            notes.append(f"frames {k}-{k + 1}: only {counts[k]} pixels usable in both; using the labelled ratio "
                         f"{labelled[k]:.4f}")
            ratios[k] = labelled[k]
        else:
            notes.append(f"frames {k}-{k + 1}: ratio {ratios[k]:.4f} from {counts[k]} pixels (labels say "
                         f"{labelled[k]:.4f})")
    relative = np.concatenate([[1.0], np.cumprod(ratios)])
    scale = np.exp(np.mean(np.log(labelled_s)) - np.mean(np.log(relative)))
    return relative * scale


def _find_candidates(signals: list[np.ndarray], clipped: list[np.ndarray], k: int, rows: slice,
                     noise_floor_dn: float, out: np.ndarray) -> None:
    """``out`` (strip bool): unclipped in frames k and k+1 and carrying signal in a third frame (or clipped there)."""
    np.logical_or(clipped[k][rows], clipped[k + 1][rows], out=out)
    np.logical_not(out, out=out)
    other = k + 2 if k + 2 < len(signals) else k - 1
    if other >= 0:
        out &= (signals[other] > SIGNAL_FLOOR * noise_floor_dn) | clipped[other][rows]
