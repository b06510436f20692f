"""A bracket (and optional darks) -> linear HDR image: merge on Bayer data, demosaic, colour.

Output channels: R, G, B in linear sRGB primaries (or camera RGB with ``camera_rgb``), relative radiance
(full wells per second at ISO 100); ``clipped`` = 1 where some CFA sample feeding the pixel was clipped in
every frame (its value is a lower bound); optional per-channel variance. The image stays in the sensor's
orientation, as the frames' Bayer data; ``orientation`` (the first frame's EXIF Orientation code) says how to
display it.
"""

from __future__ import annotations

import dataclasses
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from hdrcam.colorimetry import camera_to_srgb_matrix
from hdrcam.errors import InputError
from hdrcam.hdr.bracket_input import read_bracket
from hdrcam.hdr.merge import BayerMerge, merge_bayer
from hdrcam.io.bad_pixels import BadPixelList, repair_mosaic
from hdrcam.io.demosaic import DEFAULT_METHOD, FLOAT_METHODS, demosaic
from hdrcam.io.raw import DAYLIGHT_ASSUMED, RawFrame, RawMetadata
from hdrcam.io.raw_clipping import all_clipped
from hdrcam.parallel import strips, worker_threads
from hdrcam.profiles import CameraSpec

UNITS = "relative radiance: full wells per second at ISO 100"
VARIANCE_DEMOSAIC = "bilinear"  # whatever the image's method: a weighted mean of variances stays one; Menon's
# edge-directed estimate of a variance plane, made for images, put 0 at thousands of measured samples
COLOUR_STRIP_ROWS = 64


@dataclasses.dataclass
class FusedImage:
    rgb: np.ndarray  # H x W x 3 float32
    clipped: np.ndarray  # H x W bool
    variance: np.ndarray | None  # H x W x 3 float32 (demosaiced variance of the Bayer merge), if asked for
    merge: BayerMerge
    frame_metadata: list[RawMetadata]  # shortest exposure first; the frames' pixels are freed after the merge
    colour: str  # "linear sRGB (D65)" or "camera RGB"
    bad_pixels_repaired: int = 0  # listed sensor defects replaced in the merged mosaic (hdrcam.io.bad_pixels)

    @property
    def orientation(self) -> int:
        """EXIF Orientation code (1 to 8) that displays the image upright (6: turn 90 degrees clockwise); the
        pixels stay in the sensor's orientation. The first frame's."""
        return self.frame_metadata[0].orientation

    FLOAT32_CHANNELS = ("variance",)  # float32 even in a half-float EXR: variances span 1e-8 (a dim pixel of a
    # long exposure, below half's smallest subnormal 6e-8) to 1e30 (unknown: clipped in every frame)

    def exr_channels(self) -> dict[str, np.ndarray]:
        """The EXR's channels: RGB, the clipped mask and, if computed, the variance (unknown, 1e30 or more,
        where every frame clipped)."""
        channels = {"RGB": self.rgb, "clipped": self.clipped}
        if self.variance is not None:
            channels["variance"] = self.variance
        return channels

    def attributes(self) -> dict:
        """The EXR's attributes; ``orientation`` is the EXIF code of the pixels, which are in the sensor's
        orientation (not turned)."""
        return {"units": UNITS, "colour": self.colour, "orientation": self.orientation,
                "frames": ", ".join(meta.path.name for meta in self.frame_metadata),
                "labelled_exposures_s": ", ".join(f"{t:.6g}" for t in self.merge.labelled_exposures_s),
                "estimated_exposures_s": ", ".join(f"{t:.6g}" for t in self.merge.exposures_s),
                "clip_level_dn": float(self.merge.clip_level_dn),
                "clip_levels_dn": ", ".join(f"{v:g}" for v in self.merge.clip_level_tile_dn.ravel()),
                "bad_pixels_repaired": self.bad_pixels_repaired}


def matching_darks(frames: list[RawFrame], darks_source: Path | None) -> list[RawFrame | None] | None:
    """A dark frame per light frame, matched by exposure time; InputError when one is missing or was taken by
    another camera or at another ISO (its dark current and read noise are not the lights')."""
    if darks_source is None:
        return None
    darks = read_bracket([darks_source], kind="dark")
    light, dark_meta = frames[0].metadata, darks[0].metadata
    for what, value, expected in (("camera", dark_meta.camera_model, light.camera_model),
                                  ("ISO", dark_meta.iso, light.iso)):
        if value != expected:
            raise InputError(f"{dark_meta.path}: dark frames of {what} {value} for lights of {what} {expected} "
                             f"({light.path.name}); take the darks with the lights' settings")
    matched = []
    for frame in frames:
        exposure = frame.metadata.exposure_s
        dark = min(darks, key=lambda d: abs(np.log(d.metadata.exposure_s / exposure)))
        if abs(dark.metadata.exposure_s / exposure - 1) > 0.01:
            raise InputError(f"{darks_source}: no dark frame at {exposure:g} s for {frame.metadata.path.name}")
        if dark.bayer_dn.shape != frame.bayer_dn.shape:
            raise InputError(f"{dark.metadata.path}: dark frame of {dark.bayer_dn.shape[1]} x {dark.bayer_dn.shape[0]} "
                             f"px for frames of {frame.bayer_dn.shape[1]} x {frame.bayer_dn.shape[0]} px")
        if np.array_equal(dark.bayer_dn, frame.bayer_dn):  # subtracted from itself, every pixel would be 0
            raise InputError(f"{dark.metadata.path}: the dark frame for {frame.metadata.path.name} holds the same data "
                             "as that light frame: give the dark frames (lens capped) with --darks, not the lights")
        _warn_if_lit(dark)
        matched.append(dark)
    return matched


DARK_LIT_LEVEL = 0.05  # of the black-to-white range above black: no dark current or hot pixel crowd reaches it
DARK_LIT_FRACTION = 0.01  # of a dark frame's samples that high: it recorded light


def _warn_if_lit(dark: RawFrame) -> None:
    """Warn when a dark frame recorded light (more than DARK_LIT_FRACTION of its samples DARK_LIT_LEVEL of the
    range above black): light frames given as darks, or an uncapped lens, would subtract the scene."""
    black = float(np.max(dark.metadata.black_level_dn))
    level = black + DARK_LIT_LEVEL * (dark.metadata.white_level_dn - black)
    lit = float(np.mean(dark.bayer_dn[::4, ::4] > level))
    if lit > DARK_LIT_FRACTION:
        warnings.warn(f"{dark.metadata.path.name}, a dark frame, recorded light ({100 * lit:.1f} % of its samples "
                      f"above {100 * DARK_LIT_LEVEL:g} % of white): light frames given as darks, or the lens was not "
                      "capped? They are subtracted from the lights")


def fuse(sources: list[Path], camera: CameraSpec, *, darks: Path | None = None, camera_rgb: bool = False,
         with_variance: bool = False, demosaic_method: str = DEFAULT_METHOD,
         bad_pixels: BadPixelList | None = None) -> FusedImage:
    """Merge the RAW frames of ``sources`` (bracket.json, a folder or files) into linear HDR.

    ``camera``: the profile's sensor (full well, read noise: the merge's noise model). ``darks``: dark frames
    (a bracket.json or folder) replacing the black level. ``camera_rgb``: keep camera RGB instead of linear
    sRGB. ``with_variance``: also the per-channel variance (demosaiced bilinearly whatever the image's method).
    ``demosaic_method``: one of ``hdrcam.io.demosaic.FLOAT_METHODS``. ``bad_pixels``: the sensor's known defects
    (a dcraw list), replaced in the merged mosaic by their same-colour neighbours before demosaicing (as of the
    first frame's capture time; a dark frame's subtraction leaves a dead pixel dark and a hot one noisy). Units:
    relative radiance, full wells per second at ISO 100.
    """
    if demosaic_method not in FLOAT_METHODS:  # before anything is read
        raise InputError(f"fuse's demosaic {demosaic_method!r}: one of {', '.join(FLOAT_METHODS)} (the merge is float "
                         "data)")
    frames = read_bracket(sources)
    if all(all_clipped(frame.bayer_dn, frame.clip_level_tile_dn) for frame in frames):
        raise InputError("every pixel is clipped in every frame: the bracket needs shorter exposures")
    merge = merge_bayer(frames, camera, darks=matching_darks(frames, darks), with_variance=with_variance)
    frame_metadata = [frame.metadata for frame in frames]
    del frames  # their LibRaw buffers (2 bytes per sample and frame) are freed before the RGB image is made
    meta = frame_metadata[0]
    repaired = _repair_listed(merge, bad_pixels, meta) if bad_pixels is not None else 0
    orientations = sorted({frame.orientation for frame in frame_metadata})
    if len(orientations) > 1:  # the merge is in sensor coordinates and unaffected; only the preview's turn is
        warnings.warn(f"the frames' EXIF orientations differ ({', '.join(map(str, orientations))}; the camera was "
                      f"tilted between shots): the preview is turned as {meta.path.name}'s ({meta.orientation})")
    rgb = demosaic(merge.rate, meta.cfa_pattern, demosaic_method)
    variance = demosaic(merge.variance.clip(max=1e30), meta.cfa_pattern, VARIANCE_DEMOSAIC) if with_variance else None
    clipped = cv2.dilate(merge.clipped_everywhere.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
    colour = "camera RGB"
    if not camera_rgb and not meta.has_colour_matrix:
        warnings.warn(f"{meta.path.name}: no usable colour matrix (LibRaw's and the DNG tags' are missing or "
                      "zero): the output stays in camera RGB")
    elif not camera_rgb:
        if meta.white_balance_source == DAYLIGHT_ASSUMED:
            warnings.warn(f"{meta.path.name}: the file records no as-shot white (DNG AsShotNeutral or "
                          "AsShotWhiteXY): the white balance is assumed to be daylight (D65)")
        _warn_if_whites_differ(frame_metadata)
        matrix = camera_to_srgb_matrix(meta.xyz_to_camera, meta.as_shot_neutral).astype(np.float32)
        transformed(rgb, matrix)
        if variance is not None:
            transformed(variance, matrix ** 2)
        colour = "linear sRGB (D65)"
    return FusedImage(rgb, clipped, variance, merge, frame_metadata, colour, repaired)


NEUTRAL_ROUNDING = 1e-3  # relative: as-shot neutrals that differ less are one white, written with other rounding


def _warn_if_whites_differ(frame_metadata: list[RawMetadata]) -> None:
    """Warn when the frames' as-shot whites (camera RGB of white) differ beyond rounding (auto white balance between
    shots): the colours follow the shortest frame's, the first of ``frame_metadata``."""
    groups: list[list[RawMetadata]] = []  # frames of one white (within rounding), in frame order
    for meta in frame_metadata:
        group = next((group for group in groups if np.allclose(meta.as_shot_neutral, group[0].as_shot_neutral,
                                                               rtol=NEUTRAL_ROUNDING, atol=0.0)), None)
        if group is None:
            groups.append([meta])
        else:
            group.append(meta)
    if len(groups) > 1:
        whites = "; ".join(f"{', '.join(meta.path.name for meta in group)}: "
                           f"{' '.join(f'{v:.4g}' for v in group[0].as_shot_neutral)}" for group in groups)
        first = frame_metadata[0].path.name
        warnings.warn(f"the frames' as-shot whites (camera RGB) differ ({whites}; auto white balance between "
                      f"shots?): the colours follow {first}'s, the shortest frame's")


def _repair_listed(merge: BayerMerge, bad_pixels: BadPixelList, meta: RawMetadata) -> int:
    """Replace the listed samples of ``merge`` (rate, variance and the clipped-everywhere mask: each the median of
    its same-colour neighbours) in place; how many were listed for the frame's time."""
    bad = bad_pixels.mask(merge.rate.shape, meta.timestamp)
    if bad.any():
        merge.rate, unrepaired = repair_mosaic(merge.rate, bad)
        if merge.variance is not None:
            merge.variance = repair_mosaic(merge.variance, bad)[0]
        merge.clipped_everywhere = repair_mosaic(merge.clipped_everywhere.view(np.uint8), bad)[0].view(bool)
        if unrepaired:
            warnings.warn(f"{meta.path.name}: {unrepaired} listed bad pixels have no good neighbour of their colour "
                          "and are left as merged")
    return int(bad.sum())


def transformed(pixels: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``pixels`` (H x W x 3 float32) replaced by ``pixels @ matrix.T``, a strip of rows at a time in a thread
    pool (no second full-size image), by OpenCV's 3 x 3 transform (SIMD; BLAS's own threads would spin beside
    the pool's: twice as long at 24 MP, to the same float32 rounding)."""
    def strip(rows: slice) -> None:
        pixels[rows] = cv2.transform(pixels[rows], matrix)

    with ThreadPoolExecutor(worker_threads()) as pool:
        list(pool.map(strip, strips(pixels.shape[0], COLOUR_STRIP_ROWS)))
    return pixels
