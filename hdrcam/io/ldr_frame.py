"""Captured LDR frames for reconstruction, as H x W x 3 float32 camera RGB relative to white (0 .. 1).

- RAW (any file LibRaw opens): black level subtracted per CFA position and clipped to [0, clip - black] in
  digital numbers, with the clip level measured from the data (the lowest of the CFA positions': a pile-up
  below the metadata white level maps to 1, so those pixels count as clipped), demosaiced (hdrcam.io.demosaic;
  OpenCV's bilinear by default, on the integers when the levels are whole numbers), divided by (clip - black).
  No white balance or colour matrix: the network works in camera RGB, the space in which the PSF is measured.
  The frame stays in the sensor's orientation, as the PSF; ``read_ldr_frame_and_orientation`` also gives the
  file's EXIF Orientation code, for previews.
- EXR: linear RGB taken as is (1.0 = white), in the primaries it was stored in (a ``chromaticities``
  attribute is not applied: the frame is clipped per stored channel, which a matrix would mix, and the network
  works in the camera's RGB; TIFF and PNG primaries are not applied either). A frame whose lossy compression
  (DWAA, DWAB, B44, ...) rang past white or black is refused naming the codec.
- Radiance .hdr: linear RGB as EXR (hdrcam.io.radiance), in its stored primaries too (``PRIMARIES=`` and XYZE
  not applied; EXPOSURE and COLORCORR, scale factors, divided out).
- 16-bit TIFF / PNG: linear values / 65535, a TIFF's of fewer bits / the white its BitsPerSample states (4095 for
  12 bits; refused where a MaxSampleValue tag says another: hdrcam.io.tiff_image.tiff_white_level), with a
  warning when the brightest value, below white, holds many pixels: clipping at a lower white; float TIFF:
  linear, as EXR. 8-bit files, JPEGs, PNGs whose colour chunks declare a non-linear transfer (sRGB, a gAMA other
  than 1, a cICP transfer other than linear) and TIFFs and PNGs whose ICC profile's tone curves are not the
  identity (hdrcam.io.icc_profile: gamma, tables, LUT-based or damaged profiles) are refused (gamma-encoded, or
  not known to be linear). A file is known by its first bytes (EXR, Radiance, JPEG, PNG, TIFF) whatever its
  name, by its suffix where they match none (:func:`frame_format`); an empty file is refused as one.
Frames with NaN/Inf or values above 1 (an HDR image, not a capture) are one-line errors. ``read_ldr_capture`` also
repairs a camera's listed sensor defects (hdrcam.io.bad_pixels): a RAW file's in its mosaic before demosaicing.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import cv2
import numpy as np

from hdrcam.errors import InputError, not_a_file_reason
from hdrcam.io.bad_pixels import BadPixelList, repair_mosaic, repair_rgb
from hdrcam.io.demosaic import DEFAULT_METHOD, demosaic
from hdrcam.io.exr import exr_orientation, lossy_compression, read_exr
from hdrcam.io.file_magic import file_format, is_empty_file
from hdrcam.io.opencv_image import opencv_image
from hdrcam.io.png import declared_nonlinear_encoding, grey_png_kind
from hdrcam.io.radiance import read_radiance
from hdrcam.io.raw import RawFrame, read_raw, warn_shading_not_applied
from hdrcam.io.raw_clipping import tiled
from hdrcam.io.tiff_image import read_tiff_rgb, tiff_nonlinear_encoding, tiff_white_level

LDR_TOLERANCE = 1.001  # values up to this are rounding; above it the file is not an LDR capture
NEGATIVE_LDR_TOLERANCE = 0.01  # of white below black: read noise is ~1e-4 of white, so further is not a capture


def read_ldr_frame(path: Path, demosaic_method: str = DEFAULT_METHOD) -> np.ndarray:
    """H x W x 3 float32 camera RGB relative to white (0 .. 1) of a RAW, EXR or 16-bit TIFF/PNG frame;
    ``demosaic_method`` (RAW only): one of ``hdrcam.io.demosaic.METHODS``."""
    return read_ldr_frame_and_orientation(path, demosaic_method)[0]


def read_ldr_frame_and_orientation(path: Path, demosaic_method: str = DEFAULT_METHOD) -> tuple[np.ndarray, int]:
    """``read_ldr_frame``'s frame and the EXIF Orientation code (1 to 8) that displays it upright: a RAW file's
    (its frame stays in the sensor's orientation), an EXR's ``orientation`` attribute (hdrcam's own outputs of
    a RAW carry it), else 1 (TIFF and PNG are taken as stored)."""
    capture = read_ldr_capture(path, demosaic_method)
    return capture.rgb, capture.orientation


@dataclasses.dataclass(frozen=True)
class LdrCapture:
    """A captured frame as :func:`read_ldr_capture` reads it."""

    rgb: np.ndarray  # H x W x 3 float32 camera RGB relative to white (0 .. 1)
    orientation: int  # the EXIF Orientation code that displays it upright
    repaired_pixels: int = 0  # listed bad pixels that apply to the frame, replaced by their neighbours' median
    # (a warning names any left as read: no good neighbour)
    neutral_rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)  # what a grey surface records in ``rgb``: a RAW
    # file's as-shot neutral (camera RGB, max 1); equal channels for an EXR, TIFF or PNG (taken as white-balanced)


def read_ldr_capture(path: Path, demosaic_method: str = DEFAULT_METHOD,
                     bad_pixels: BadPixelList | None = None) -> LdrCapture:
    """``read_ldr_frame_and_orientation``'s frame and orientation, with the sensor defects of ``bad_pixels`` (a
    dcraw list, :mod:`hdrcam.io.bad_pixels`) repaired: a RAW file's in its Bayer mosaic before demosaicing,
    counted for the frame's capture time; an EXR's, TIFF's or PNG's per pixel after it (every listed pixel)."""
    path = Path(path)
    if path.exists() and not path.is_file() and not path.is_dir():  # /dev/null, a FIFO: not "does not exist"
        raise InputError(f"{path}: {not_a_file_reason(path, 'an image file')}")
    if not path.is_file():
        raise InputError(f"{path} is a folder; give the frames in it" if path.is_dir() else f"{path} does not exist")
    suffix, orientation, exr, bad, neutral = path.suffix.lower(), 1, False, None, (1.0, 1.0, 1.0)
    if (kind := frame_format(path, suffix)) == "OpenEXR":  # by its first bytes, whatever its name
        image = read_exr(path, to_rec709=False)  # clipped per stored channel: a matrix would unclip them
        rgb, orientation, exr = image.rgb(), exr_orientation(image.attributes), True
    elif kind == "Radiance":  # linear; an HDR photograph is refused below (values above white)
        rgb = read_radiance(path, to_rec709=False)  # in its stored primaries, as an EXR
    elif kind == "JPEG":
        raise InputError(f"{path}: a JPEG is 8-bit and gamma-encoded, not linear; give a RAW file, an EXR or a "
                         "16-bit TIFF/PNG")
    elif kind in ("TIFF", "PNG"):
        image = _rgb_samples(path, kind)
        if image.dtype.kind == "f":
            rgb = image.astype(np.float32)  # linear, as EXR
        elif image.dtype == np.uint16:
            white = tiff_white_level(path) if kind == "TIFF" else 65535  # 4095 for a 12-bit TIFF
            rgb = image.astype(np.float32) / float(white)
            _warn_plateau_below_white(path, image, white)
        elif image.dtype == np.uint8:
            raise InputError(f"{path}: uint8 pixels are gamma-encoded, not linear; give a 16-bit TIFF/PNG, "
                             "an EXR or a RAW file")
        else:  # signed or 32-bit integers: no camera or converter writes frames so; their white is unknown
            raise InputError(f"{path}: {image.dtype} samples, whose white level is unknown; give a 16-bit unsigned "
                             "or float TIFF/PNG, an EXR or a RAW file")
    else:
        raw = read_raw(path)
        bad = bad_pixels.mask(raw.bayer_dn.shape, raw.metadata.timestamp) if bad_pixels is not None else None
        rgb, orientation = raw_relative_rgb(raw, demosaic_method, bad=bad), raw.metadata.orientation
        neutral = tuple(float(value) for value in raw.metadata.as_shot_neutral)
    if not np.isfinite(rgb).all():
        raise InputError(f"{path}: frame has NaN or Inf pixels")
    lowest, highest = float(rgb.min()), float(rgb.max())
    lossy = lossy_compression(path) if exr and (lowest < -NEGATIVE_LDR_TOLERANCE or highest > LDR_TOLERANCE) else None
    if lowest < -NEGATIVE_LDR_TOLERANCE:
        raise InputError(f"{path}: values down to {lowest:.4g} of white; " + (_lossy_advice(lossy, -lowest) or
                         f"a captured frame's noise stays within {NEGATIVE_LDR_TOLERANCE:g} of black - check how the "
                         "file was made"))
    if highest > LDR_TOLERANCE:
        raise InputError(f"{path}: values reach {highest:.4g}, above white (1.0): " + (
            _lossy_advice(lossy, highest - 1.0) or "this is not an LDR capture (give the camera frame, not an HDR "
                                                   "image)"))
    rgb = np.clip(rgb, 0.0, 1.0).astype(np.float32)
    if bad_pixels is None:
        return LdrCapture(rgb, orientation, neutral_rgb=neutral)
    if bad is None:  # a demosaiced file: each pixel's own neighbours
        bad = bad_pixels.mask(rgb.shape[:2])
        rgb, unrepaired = repair_rgb(rgb, bad)
        _warn_unrepaired(path, unrepaired)
    return LdrCapture(rgb, orientation, int(bad.sum()), neutral)


SUFFIX_FORMATS = {".exr": "OpenEXR", ".hdr": "Radiance", ".pic": "Radiance", ".tif": "TIFF", ".tiff": "TIFF",
                  ".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}  # a frame's format where its first bytes say none


def frame_format(path: Path, suffix: str) -> str | None:
    """The format the frame file at ``path`` (a regular file; ``suffix`` its suffix, lower case) is read as, a name
    of hdrcam.io.file_magic.FORMAT_MAGICS: the one its first bytes show, whatever its name, else the one its suffix
    names (SUFFIX_FORMATS; that reader then says what is wrong); None for a RAW file (LibRaw's). A TIFF is read as
    one only where its suffix is an image format's: DNG and most RAW formats are TIFF files, for LibRaw. InputError
    for an empty file."""
    if is_empty_file(path):
        raise InputError(f"{path}: an empty file (0 bytes)")
    found, named = file_format(path), SUFFIX_FORMATS.get(suffix)
    return named if found is None or (found == "TIFF" and named is None) else found


def _warn_unrepaired(path: Path, unrepaired: int) -> None:
    if unrepaired:
        warnings.warn(f"{path}: {unrepaired} listed bad pixels have no good neighbour of their colour (a cluster "
                      "wider than the repair reaches) and are left as read")


LOSSY_RINGING = 0.1  # of white: how far beyond black or white a lossy codec's ringing is taken to reach


def _lossy_advice(compression: str | None, beyond: float) -> str:
    """What to do about a frame ``beyond`` (of white) past black or white whose EXR ``compression`` is lossy: its
    codec's ringing, not the capture, put the values there (DWAA measured 2 % above white); "" for a lossless
    file or values further out (an HDR image)."""
    if compression is None or beyond > LOSSY_RINGING:
        return ""
    return (f"the EXR is {compression}-compressed, a lossy codec whose ringing passes white and black and whose "
            "clipped pixels are no longer exact; save the frame losslessly (ZIP, PIZ or none)")


def _rgb_samples(path: Path, kind: str) -> np.ndarray:
    """A TIFF's or PNG's (``kind``) H x W x 3 samples in R, G, B order and their stored type (extra samples
    dropped)."""
    encoding = declared_nonlinear_encoding(path) if kind == "PNG" else tiff_nonlinear_encoding(path)
    if encoding:
        raise InputError(f"{path}: the {kind} declares {encoding}: hdrcam reads linear values only (these are "
                         "gamma-encoded, or not known to be linear); give a linear 16-bit TIFF/PNG, an EXR or the RAW "
                         "file")
    if kind == "TIFF":
        return read_tiff_rgb(path)
    if grey := grey_png_kind(path):
        raise InputError(f"{path}: a {grey} PNG (no colour samples): not an RGB image")
    image = opencv_image(path, cv2.IMREAD_UNCHANGED)
    if image is None or image.ndim != 3 or image.shape[2] < 3:
        raise InputError(f"{path}: cannot read as an RGB image")
    return cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2RGB)


PLATEAU_MIN_PIXELS = 16  # pixels sharing the brightest value, below white, that look like clipping
PLATEAU_BELOW_WHITE = 0.99  # of white: brighter maxima count as white (reconstruct's clip level)


def _warn_plateau_below_white(path: Path, image: np.ndarray, white: int = 65535) -> None:
    """Warn when an integer frame's brightest value, below ``white``, holds many pixels: clipping at a lower white
    (14-bit data in a 16-bit file reaches 16383), which reconstruct does not see as clipped."""
    brightest = int(image.max())
    count = int(np.count_nonzero(image.max(axis=-1) == brightest))
    if brightest < PLATEAU_BELOW_WHITE * white and count >= PLATEAU_MIN_PIXELS:
        warnings.warn(f"{path}: {count} pixels share the brightest value, {brightest} of {white} - clipping below "
                      f"white? hdrcam takes {white} as white, so they are not treated as clipped; rescale the file "
                      f"so white is {white}")


def raw_relative_rgb(frame: RawFrame, demosaic_method: str = DEFAULT_METHOD, bad: np.ndarray | None = None
                     ) -> np.ndarray:
    """A RAW frame as camera RGB relative to its measured clip level (1 = clipped), demosaiced; the samples
    ``bad`` marks (H x W bool) repaired before (:func:`hdrcam.io.bad_pixels.repair_mosaic`)."""
    warn_shading_not_applied([frame])
    height, width = frame.bayer_dn.shape
    black_tile = frame.metadata.black_level_tile()
    scale_dn = float((frame.clip_level_tile_dn - black_tile).min())
    if not scale_dn > 0:
        raise InputError(f"{frame.metadata.path}: its black level ({black_tile.max():g} DN) is not below its clip "
                         f"level ({frame.clip_level_tile_dn.min():g} DN): the file's levels are wrong")
    signal_dn = np.clip(frame.bayer_dn.astype(np.float32) - tiled(black_tile, height, width), 0.0, scale_dn)
    if np.all(black_tile == np.round(black_tile)) and scale_dn == round(scale_dn) and scale_dn < 65536:
        signal_dn = signal_dn.astype(np.uint16)  # exact: OpenCV's integer demosaicing
    if bad is not None and bad.any():
        signal_dn, unrepaired = repair_mosaic(signal_dn, bad)
        _warn_unrepaired(frame.metadata.path, unrepaired)
    return demosaic(signal_dn, frame.metadata.cfa_pattern, demosaic_method) / np.float32(scale_dn)
