"""The clip level of a RAW frame, measured from its data: the pile-up of samples below the metadata white.

Many bodies clip below the white level their files declare (a pile-up at 13 500-16 372 DN where the
metadata says 15 000-16 383), and lossy compression (Sony cRAW) scatters the clipped samples a little
above the pile-up. Per position of the 2 x 2 CFA tile, the clip level is the most populated single value in
the top part of the range when it stands far above the histogram just below it - its mean and its nearest
occupied values (a spike, not the smooth tail of a bright area, nor the noise peak of a flat one); then every
sample at or above it is clipped. Without such a pile-up the clip level
is the metadata white level - unless no sample reaches the top part of the range, when a pile-up at the largest
sample is looked for (a white level far above the data). A clip level is never above the white level. A position
with no pile-up of its own (a small light clips a few of its samples) takes the pile-up of all four positions'
samples together, where its brightest samples reach it and none goes above.

One sensor's ADC clips every CFA position at (nearly) one level: the positions' pile-ups may differ by a few DN
(the A7R III's cRAW: 16 383 and 16 372), and each keeps its own; but when, over a bracket, some positions show a
pile-up far below the metadata white (the fallback above) and others none while their brightest samples stay at
or below it - red and blue that never clipped in a green-lit scene - the pile-up is the sensor's white for them
too (:func:`one_sensor_white`). A position whose samples go above it keeps the white level: its pile-up is not
the sensor's white (a stuck readout at 3000 DN read as red's pile-up in a short frame).
"""

from __future__ import annotations

import cv2
import numpy as np

SEARCH_FROM = 0.5  # of the black-to-white range: a pile-up below this is not a clip level
MIN_PILE_SAMPLES = 8  # fewer samples at one value are hot pixels or chance (3 clipped 4 x 4 px lights give 12)
PILE_CONTRAST = 8.0  # the pile-up's count over the mean count per occupied value just below it...
NEAREST_BELOW = 3  # ...and over the mean count of this many nearest occupied values more than
PILE_WIDTH_DN = 8  # this far below it, by
NEAREST_CONTRAST = 3.0  # this much: the noise peak of a flat, unclipped area (a wall at 0.75 of white, sigma ~60
# DN) stands far above the window's mean but hardly above its own neighbours (a ratio of 1 to 1.3); a clipped
# sensor's pile-up stands far above them, even when a per-column offset after the clip spreads it over a few DN
# (values on a coarser grid - 12-bit data in a 14-bit file - leave neighbours empty: the nearest occupied count)
ONE_SENSOR_SLACK = 0.05  # of the black-to-clip range: one sensor's positions clip within it of one another (the
# A7R III's cRAW: 11 DN apart, scattered 256 DN above); a position brighter than that is not clipped at that level
MIN_SIGNAL = 0.01  # of the black-to-white range: the largest sample of data whose own white is far below the
# metadata's (10-bit data in 16-bit samples reaches 1.6 %); less is a dark frame's noise
BELOW_WINDOW = 0.05  # of the black-to-white range: the neighbourhood the pile-up is compared with


def measure_clip_levels(bayer_dn: np.ndarray, black_tile_dn: np.ndarray, white_level_dn: float) -> np.ndarray:
    """2 x 2 float32 tile of clip levels in DN (absolute, like the data), one per CFA position; positions that found
    no pile-up of their own take the pile-up of all positions' samples together (:func:`_shared_pile_up`)."""
    levels = np.empty((2, 2), np.float32)
    histograms = {}
    for row in range(2):
        for column in range(2):
            samples, black = bayer_dn[row::2, column::2], float(black_tile_dn[row, column])
            histograms[row, column] = _top_histogram(samples, black, white_level_dn)
            levels[row, column] = _clip_level(samples, black, white_level_dn, histograms[row, column])
    return _shared_pile_up(levels, histograms, float(np.mean(black_tile_dn)), white_level_dn)


def _shared_pile_up(levels_dn: np.ndarray, histograms: dict, black_dn: float, white_level_dn: float) -> np.ndarray:
    """``levels_dn`` (2 x 2, absolute DN) with each position left at the white level given the highest pile-up of
    the four positions' samples together (their top-part ``histograms`` summed: no second pass over the data),
    looked for in windows of BELOW_WINDOW stepped down from the brightest sample (a brightly lit wall lower down
    holds more samples than a lamp's few, and a hot pixel may lie above the pile), where the position holds
    samples at it (within PILE_WIDTH_DN) and fewer than MIN_PILE_SAMPLES above it (hot pixels, a lossy codec's
    scatter). A small light clips a few samples of each position - a 3 x 3 px lamp two or four - fewer than
    MIN_PILE_SAMPLES: on a body clipping at 15 000 DN under a white level of 16 383, such a lamp read 0.91 of white
    and "no clipped pixels"; one sensor's ADC clips all positions at one level (module docstring). Only the top
    part is searched: a stuck readout far below white is no sensor's clip level."""
    unfound = levels_dn >= white_level_dn
    if not unfound.any():
        return levels_dn
    low = min(start for start, _ in histograms.values())
    shared = np.zeros(max(start - low + counts.size for start, counts in histograms.values()), np.int64)
    for start, counts in histograms.values():
        shared[start - low:start - low + counts.size] += counts
    occupied = np.flatnonzero(shared)
    if occupied.size == 0:
        return levels_dn
    window = max(int(BELOW_WINDOW * (white_level_dn - black_dn)), 8)
    top, level = int(occupied[-1]), None
    while level is None:
        start = max(0, top - window)
        level = _pile_in(shared[start:top + 1], low + start, white_level_dn - black_dn, white_level_dn,
                         at_ceiling_only=False)
        if start == 0:
            break
        top -= window // 2
    if level is None or level >= white_level_dn:
        return levels_dn
    reaches = np.array([[_clipped_there(histograms[row, column], int(level)) for column in range(2)]
                        for row in range(2)])
    return np.where(unfound & reaches, level, levels_dn).astype(np.float32)


def _clipped_there(histogram: tuple[int, np.ndarray], level_dn: int) -> bool:
    """Whether a position's top-part ``histogram`` (low, counts) holds samples within PILE_WIDTH_DN below
    ``level_dn`` or at it, and fewer than MIN_PILE_SAMPLES above it."""
    low, counts = histogram
    index = level_dn - low
    return index >= 0 and counts[max(0, index - PILE_WIDTH_DN):index + 1].sum() > 0 and \
        counts[index + 1:].sum() < MIN_PILE_SAMPLES


def one_sensor_white(levels_dn: np.ndarray, black_tile_dn: np.ndarray, white_level_dn: float,
                     longest_bayer_dn: np.ndarray) -> np.ndarray:
    """A bracket's clip levels ``levels_dn`` (2 x 2, absolute DN) with each position that found no pile-up (at
    ``white_level_dn``) set to the highest level found below the top part of the range, where some position found
    one there and that position's samples in the longest frame ``longest_bayer_dn`` stay within ONE_SENSOR_SLACK
    of it (module docstring: a position clipping a few DN above the others' pile-up, too few samples for its own,
    is the same sensor's clip; one whose samples go far above it is not). A DNG with WhiteLevel 65535, or none
    (the DNG spec's default, 2^BitsPerSample - 1), over 14-bit data: with only green clipped, red and blue stayed
    at 65535, the largest level set the full well, and every
    radiance came out 4x too dark (12-bit data: 16x)."""
    far_below = _below_top_part(levels_dn, black_tile_dn, white_level_dn)
    if not far_below.any():
        return levels_dn
    sensor_white = levels_dn[far_below].max()
    brightest = np.array([[longest_bayer_dn[row::2, column::2].max() for column in range(2)] for row in range(2)])
    within = brightest <= sensor_white + ONE_SENSOR_SLACK * (sensor_white - float(np.mean(black_tile_dn)))
    return np.where((levels_dn >= white_level_dn) & within, sensor_white, levels_dn).astype(np.float32)


def channel_clip_level(samples_dn: np.ndarray, black_dn: float, white_level_dn: float) -> float:
    """The clip level (DN) of one CFA position's samples: the pile-up value, else ``white_level_dn``.

    When no sample reaches the top part of the black-to-white range at all, the white level may be far above
    what the sensor delivers (a DNG without WhiteLevel defaults to 2^bits - 1: 12-bit data in 16-bit samples),
    so a pile-up at the largest sample, found the same way below it, is taken instead - unless that sample is
    within MIN_SIGNAL of black (a frame with the lens cap on holds no light to clip)."""
    return _clip_level(samples_dn, black_dn, white_level_dn, _top_histogram(samples_dn, black_dn, white_level_dn))


def _clip_level(samples_dn: np.ndarray, black_dn: float, white_level_dn: float, histogram: tuple) -> float:
    """:func:`channel_clip_level` given the samples' ``histogram`` above the top part (:func:`_top_histogram`)."""
    low, counts = histogram
    level = _pile_in(counts, low, white_level_dn - black_dn, white_level_dn, at_ceiling_only=False)
    if level is None and samples_dn.size:
        largest = float(samples_dn.max())
        if largest >= black_dn + MIN_SIGNAL * (white_level_dn - black_dn) and \
                _below_top_part(largest, black_dn, white_level_dn):  # a dark frame's noise shows no sensor white
            level = _pile_up(samples_dn, black_dn, largest, at_ceiling_only=True)
    return float(white_level_dn) if level is None else level


def _pile_up(samples_dn: np.ndarray, black_dn: float, ceiling_dn: float, at_ceiling_only: bool) -> float | None:
    """The most populated value in the top part of black..``ceiling_dn`` if it is a pile-up (module docstring;
    ``at_ceiling_only``: only a pile-up at ``ceiling_dn`` itself counts), else None."""
    low, counts = _top_histogram(samples_dn, black_dn, ceiling_dn)
    return _pile_in(counts, low, ceiling_dn - black_dn, ceiling_dn, at_ceiling_only)


def _top_histogram(samples_dn: np.ndarray, black_dn: float, ceiling_dn: float) -> tuple[int, np.ndarray]:
    """(low, counts): the first value of the top part of black..``ceiling_dn`` and the counts of each integer value
    from it up (a pile-up above the ceiling is found, and capped, as well)."""
    low = int(np.ceil(black_dn + SEARCH_FROM * (ceiling_dn - black_dn)))
    return low, _counts_from(samples_dn, low)


def _pile_in(counts: np.ndarray, low: int, span: float, ceiling_dn: float, at_ceiling_only: bool) -> float | None:
    """The pile-up among ``counts`` (of each value from ``low`` up; ``span``: the black-to-ceiling range), else
    None (:func:`_pile_up`)."""
    if counts.sum() < MIN_PILE_SAMPLES:
        return None
    peak = int(np.argmax(counts))
    pile = int(counts[peak])
    start = max(0, peak - max(int(BELOW_WINDOW * span), 8))
    below = counts[start:peak]
    occupied = below[below > 0]
    density = occupied.mean() if occupied.size else 0.0
    outside = counts[start:max(start, peak - PILE_WIDTH_DN)]
    outside = outside[outside > 0][-NEAREST_BELOW:]
    nearest = outside.mean() if outside.size else 0.0
    if pile < MIN_PILE_SAMPLES or pile < PILE_CONTRAST * density or pile < NEAREST_CONTRAST * nearest or \
            (at_ceiling_only and low + peak != ceiling_dn):
        return None
    return float(min(low + peak, ceiling_dn))


def _counts_from(samples_dn: np.ndarray, low_dn: int) -> np.ndarray:
    """int64 counts of each integer value from ``low_dn`` up (index 0: ``low_dn``) among ``samples_dn`` (integer
    data; a CFA position's strided view is copied once, at 2 bytes a sample), by OpenCV's histogram: numpy's
    bincount casts every sample it counts to int64 first, 5x longer on a bright 24 MP frame. Its float32 counts
    are exact up to 2^24 samples at one value (beyond, off by a few parts in 10^8: no decision changes)."""
    if samples_dn.dtype not in (np.uint8, np.uint16):  # other integer types (tests, odd decoders): numpy's, exact
        return np.bincount(samples_dn[samples_dn >= low_dn].astype(np.int64) - low_dn)
    samples = np.ascontiguousarray(samples_dn)
    end = int(np.iinfo(samples.dtype).max) + 1
    if end <= low_dn or samples.size == 0:
        return np.zeros(0, np.int64)
    return cv2.calcHist([samples], [0], None, [end - low_dn], [low_dn, end]).ravel().astype(np.int64)


def sensor_white_dn(white_level_dn: float, black_dn: float, clip_tile_dn: np.ndarray) -> float:
    """The white level that defines a full well: the metadata's, unless the clip levels were found below the
    top part of its range (the fallback of :func:`channel_clip_level`: a white level far above the data), when
    the highest clip level is the sensor's white."""
    highest = float(np.max(clip_tile_dn))
    return highest if _below_top_part(highest, black_dn, white_level_dn) else float(white_level_dn)


def is_in_top_part(value_dn: float, black_dn: float, white_level_dn: float) -> bool:
    """True when ``value_dn`` lies in the part of black..white where a pile-up is searched for (SEARCH_FROM up)."""
    return not _below_top_part(value_dn, black_dn, white_level_dn)


def straddles_top_part(clip_tile_dn: np.ndarray, black_tile_dn: np.ndarray, white_level_dn: float) -> bool:
    """True when some CFA positions' clip levels lie below the top part of black..white and others in it."""
    below = _below_top_part(clip_tile_dn, black_tile_dn, white_level_dn)
    return bool(below.any() and not below.all())


def _below_top_part(value_dn, black_dn, white_level_dn: float):
    """``value_dn < black_dn + SEARCH_FROM * (white_level_dn - black_dn)``, for numbers or arrays (elementwise)."""
    return value_dn < black_dn + SEARCH_FROM * (white_level_dn - black_dn)


def clipped_samples(bayer_dn: np.ndarray, clip_tile_dn: np.ndarray) -> np.ndarray:
    """H x W bool: samples at or above their CFA position's clip level."""
    mask = np.empty(bayer_dn.shape, bool)
    for row in range(2):
        for column in range(2):
            mask[row::2, column::2] = bayer_dn[row::2, column::2] >= clip_tile_dn[row, column]
    return mask


def all_clipped(bayer_dn: np.ndarray, clip_tile_dn: np.ndarray) -> bool:
    """True when every sample is at or above its CFA position's clip level (each position's minimum; no mask)."""
    return all(bayer_dn[row::2, column::2].min(initial=np.iinfo(bayer_dn.dtype).max) >= clip_tile_dn[row, column]
               for row in range(2) for column in range(2))


def tiled(tile: np.ndarray, height: int, width: int) -> np.ndarray:
    """A 2 x 2 tile repeated over H x W (float32)."""
    return np.tile(np.asarray(tile, np.float32), ((height + 1) // 2, (width + 1) // 2))[:height, :width]
