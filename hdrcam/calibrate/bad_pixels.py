"""Finding a sensor's bad pixels - hot ones that read bright without light, dead ones that read dark in it - in RAW
frames of one camera.

A sample is a candidate in one frame where it lies more than CANDIDATE_SIGMAS spreads from the median of its 3 x 3
same-colour neighbours (its CFA sub-plane's), the spread being 1.4826 x the median absolute deviation of every
sample of that sub-plane from its own neighbours' median (the noise, on a dark or evenly lit frame); it is bad
where it is a candidate in at least ``confirm_share`` of the frames. Dark frames show hot pixels, evenly lit
frames (a flat field, an out-of-focus grey card) dead ones: find each kind in its own frames and join the lists
(dcraw's format concatenates). Photographs serve only where their scenes differ: an edge of the scene that
stays on one pixel from frame to frame is a candidate in each.

Not rawpy.enhance.find_bad_pixels: with hot and dead pixels both sought it subtracts the median from the uint16
samples in place, so every sample below its neighbours' median wraps around to a candidate (rawpy 0.28: 2,309
candidates in a 64 x 96 dark frame with 3 DN of read noise and two defects); and its threshold, 1/150 of the
frame's brightest sample, is no measure of the noise. Numpy and OpenCV load on first use (``hdrcam bad-pixels
--help`` reads the default alone).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from hdrcam.errors import InputError

if TYPE_CHECKING:
    import numpy as np

    from hdrcam.io.raw import RawFrame, RawMetadata

MIN_FRAMES = 2  # one frame cannot tell a defect from a sharp point of its scene
DEFAULT_CONFIRM_SHARE = 0.9
CANDIDATE_SIGMAS = 8.0  # beyond a Gaussian's reach (~1e-15 per sample), wide of a Poisson tail at low counts
MAD_TO_SIGMA = 1.4826  # a Gaussian's standard deviation per median absolute deviation
MIN_SPREAD_DN = 1.0  # the spread of a sub-plane with no noise (a synthetic or heavily processed frame)
MAX_BAD_SHARE = 0.002  # of the samples: a sensor's defects are far fewer; two copies of one real A7R III
# photograph confirm 1.9 % of theirs (the scene's edges and texture)


def find_bad_pixels(frames: list[str | Path], confirm_share: float = DEFAULT_CONFIRM_SHARE) -> np.ndarray:
    """H x W bool (the visible RAW area, sensor orientation): the samples that stand out from their same-colour
    neighbours in at least ``confirm_share`` (0 < share <= 1) of ``frames``, RAW files of one camera and size, or
    folders of them (:func:`frames_of_one_camera`). InputError (one line) for fewer than MIN_FRAMES frames, a frame
    given twice or copied, frames of another camera or size, a file hdrcam does not read, or more than
    MAX_BAD_SHARE of the samples found (the frames' scene, not the sensor)."""
    if not 0.0 < confirm_share <= 1.0:
        raise InputError(f"the confirming share of frames must lie in (0, 1], got {confirm_share:g}")
    return bad_pixels_in(frames_of_one_camera(frames), confirm_share)


def listed_frames(frames: list[str | Path]) -> list[Path]:
    """``frames`` with each folder replaced by the files that may be RAW in it, as fuse lists a folder
    (:func:`hdrcam.capture.ingest.raw_files`)."""
    from hdrcam.capture.ingest import raw_files

    return [path for given in map(Path, frames) for path in (raw_files(given) if given.is_dir() else [given])]


def frames_of_one_camera(frames: list[str | Path]) -> list[RawMetadata]:
    """The metadata of ``frames`` (files, or folders listed as fuse lists them: the files LibRaw does not open as
    RAW - a JPEG beside each RAW, a README - skipped with a warning naming each, as fuse skips them; a file given
    by name must be RAW). InputError for fewer than MIN_FRAMES, for a frame counted twice (the same file, a link
    to it or a byte-identical copy: it would confirm its own one-off hits as defects), or for frames of another
    camera model or size."""
    import warnings

    from hdrcam.hdr.bracket_input import refuse_differences, refuse_repeated_files
    from hdrcam.io.raw import NotRawError, read_raw_metadata, sensor_fingerprint

    metadata, skipped = [], []
    for given in map(Path, frames):
        if not given.is_dir():
            metadata.append(read_raw_metadata(given))
            continue
        for path in listed_frames([given]):
            try:
                metadata.append(read_raw_metadata(path))
            except NotRawError as error:
                skipped.append(error)
    for error in skipped:
        warnings.warn(f"skipped {error}")
    if len(metadata) < MIN_FRAMES:  # after each file is checked: a missing one is named as such
        raise InputError(f"bad pixels are found in at least {MIN_FRAMES} frames (a defect stays where it is, a "
                         f"point of the scene moves); got {len(metadata)}")
    refuse_repeated_files(metadata, "the frames")
    reference, one_camera = metadata[0], "bad pixels are found in frames of one camera"
    for meta in metadata[1:]:
        fingerprints = [(what, value, expected) for (what, value), (_, expected)
                        in zip(sensor_fingerprint(meta), sensor_fingerprint(reference))]
        refuse_differences(meta, reference, [("camera model", meta.camera_model, reference.camera_model),
                                             *fingerprints], one_camera)
    if len({(meta.height_px, meta.width_px) for meta in metadata}) > 1:
        listed = ", ".join(f"{meta.path.name} {meta.width_px} x {meta.height_px}" for meta in metadata)
        raise InputError(f"frames of different sizes ({listed}): {one_camera}")
    return metadata


def bad_pixels_in(frames: list[RawMetadata], confirm_share: float = DEFAULT_CONFIRM_SHARE) -> np.ndarray:
    """:func:`find_bad_pixels` on the frames :func:`frames_of_one_camera` checked."""
    import numpy as np

    from hdrcam.io.raw import read_raw

    paths = [meta.path for meta in frames]
    counts = np.zeros((frames[0].height_px, frames[0].width_px), np.uint16)
    for path in paths:
        counts += candidates(read_raw(path))
    bad = counts >= np.ceil(confirm_share * len(paths) - 1e-9)
    if bad.mean() > MAX_BAD_SHARE:
        raise InputError(f"{int(bad.sum())} of {bad.size} samples ({100 * bad.mean():.2g} %) stand out in "
                         f"{confirm_share:g} of the {len(paths)} frames, more than a sensor's defects (at most "
                         f"{100 * MAX_BAD_SHARE:g} %): frames of one scene, or darks that saw light? Find bad pixels "
                         "in dark frames and in evenly lit ones")
    return bad


def candidates(frame: RawFrame) -> np.ndarray:
    """H x W bool: the samples of one RawFrame more than CANDIDATE_SIGMAS spreads from the median of their 3 x 3
    same-colour neighbours (each CFA position's spread its own)."""
    import numpy as np

    from hdrcam.calibrate.hot_pixels import same_colour_median
    from hdrcam.hdr.merge import black_subtracted

    signal_dn = black_subtracted(frame)
    deviation = signal_dn - same_colour_median(signal_dn)
    found = np.zeros(signal_dn.shape, bool)
    for row in (0, 1):
        for column in (0, 1):
            plane = deviation[row::2, column::2]
            spread = max(MAD_TO_SIGMA * float(np.median(np.abs(plane))), MIN_SPREAD_DN)
            found[row::2, column::2] = np.abs(plane) > CANDIDATE_SIGMAS * spread
    return found
