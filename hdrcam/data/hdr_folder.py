"""HDR images from a folder of OpenEXR (.exr) and Radiance (.hdr, .pic) files, linear RGB float32."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np

from hdrcam.colorimetry import in_rec709
from hdrcam.errors import InputError, failure_message, not_a_file_reason
from hdrcam.io.exr import read_exr
from hdrcam.io.file_magic import file_format, is_empty_file
from hdrcam.io.opencv_image import opencv_image
from hdrcam.io.radiance import RADIANCE_SUFFIXES, is_radiance_file, read_radiance_stored
from hdrcam.io.tiff_image import read_tiff_rgb

HDR_SUFFIXES = (".exr", *RADIANCE_SUFFIXES)
SUFFIX_FORMATS = {".exr": "OpenEXR", ".hdr": "Radiance", ".pic": "Radiance", ".tif": "TIFF", ".tiff": "TIFF"}
# an image's format where its first bytes match none (file_magic.file_format): that format's reader names the fault


def read_hdr_image(path: Path, *, warn_negative: bool = False, infinite_as_peak: bool = False) -> np.ndarray:
    """H x W x 3 float32 linear Rec. 709 RGB from an OpenEXR, Radiance (hdrcam.io.radiance) or float TIFF file,
    each known by its first bytes whatever its name (by its suffix where they match no format: that reader says
    what is wrong; hdrcam.io.file_magic); NaN/Inf and negatives are refused/zeroed, 8/16-bit images (display
    images) refused, and so are values that the conversion from a file's primaries takes beyond float32.
    A luminance-only photograph (an EXR whose only colour data is Y, e.g. OpenEXR's Fog
    and Garden) is read as grey, R = G = B = Y. ``infinite_as_peak``: +Inf pixels (light beyond the format: a
    half-float sun above 65504 is stored as Inf) are taken as the image's largest finite value, with a warning,
    instead of refused."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {not_a_file_reason(path, 'an image file')}")
    if is_empty_file(path):
        raise InputError(f"{path}: an empty file (0 bytes)")
    kind = file_format(path) or SUFFIX_FORMATS.get(path.suffix.lower())
    primaries = None  # converted to Rec. 709 after +Inf is dealt with (a matrix turns it into NaN)
    if kind == "OpenEXR":
        exr = read_exr(path, to_rec709=False)
        if "Y" not in exr.channels or {"R", "G", "B"} <= set(exr.channels):
            image, primaries = exr.rgb(), exr.attributes.get("chromaticities")
        else:
            image = np.repeat(exr.channels["Y"][..., None], 3, axis=-1)
    elif kind == "TIFF":
        image = read_tiff_rgb(path)
        _refuse_display_image(path, image)
        image = image.astype(np.float32)
    elif kind == "Radiance":
        image, primaries = read_radiance_stored(path)
    else:  # PNG, JPEG and the other formats OpenCV reads: display images, refused below, or named
        image = opencv_image(path, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
        if image is None:
            raise InputError(f"{path}: cannot read as an HDR image (OpenEXR, Radiance .hdr or a float TIFF)")
        _refuse_display_image(path, image)
        image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB).astype(np.float32)
    finite = np.isfinite(image)
    if not finite.all():
        if not infinite_as_peak or not np.all(finite | (image == np.inf)):
            raise InputError(f"{path}: image has NaN or {'-' if infinite_as_peak else ''}Inf pixels")
        peak = float(image.max(where=finite, initial=0.0))
        warnings.warn(f"{path}: {np.count_nonzero(~finite)} values are +Inf (light beyond the file format's range); "
                      f"taken as the image's largest finite value, {peak:.6g}")
        image = np.where(finite, image, np.float32(peak))
    if primaries is not None:
        image = _in_rec709_within_float32(path, image, primaries)
    if warn_negative:
        warn_negative_radiance(path, image)
    return np.clip(image, 0.0, None)  # negatives (resampling ringing, out-of-gamut colours) are not light


def _in_rec709_within_float32(path: Path, image: np.ndarray, primaries) -> np.ndarray:
    """``image`` converted from ``primaries`` to Rec. 709 (hdrcam.colorimetry.in_rec709); InputError naming the
    file where the conversion takes values beyond float32 (3.4e38): a wide-gamut value near the limit overflowed
    to Inf with numpy's own warning, and evaluate then failed with an internal error on the NaN it made."""
    with np.errstate(over="ignore", invalid="ignore"):
        converted = in_rec709(image, primaries)
    if converted is not image and not np.isfinite(converted).all():
        raise InputError(f"{path}: its values (up to {float(np.abs(image).max()):.4g}) leave float32's range "
                         f"({np.finfo(np.float32).max:.3g}) once its primaries are converted to Rec. 709; scale the "
                         "image down (its absolute scale does not matter to hdrcam)")
    return converted


def _refuse_display_image(path: Path, image: np.ndarray) -> None:
    if image.dtype.kind in "ui":
        raise InputError(f"{path}: {8 * image.dtype.itemsize}-bit pixels: a display image, gamma-encoded and "
                         "clipped, not linear radiance; give an OpenEXR, Radiance .hdr or float TIFF")


NEGATIVE_TOLERANCE = 0.01  # of the image's peak: resampling filters ring a little below zero


def warn_negative_radiance(path: Path, image: np.ndarray) -> None:
    """Warn when a scene has pixels further below zero than resampling ringing explains: they are taken as 0
    (out-of-gamut colours of a wide-gamut photograph do this; a sign error in the file would too)."""
    lowest, peak = float(image.min(initial=0.0)), float(image.max(initial=0.0))
    if lowest < -NEGATIVE_TOLERANCE * max(peak, np.finfo(np.float32).tiny):
        share = float(np.mean(image.min(axis=-1) < 0))
        warnings.warn(f"{path}: {100 * share:.2g} % of the pixels are negative (down to {lowest:.4g}, peak "
                      f"{peak:.4g}); they are taken as 0 - check the file if it should hold none")


def hdr_files(folder: Path) -> list[Path]:
    """The HDR files in ``folder`` (sorted; hidden files - macOS's ._NAME.exr resource forks beside copied
    photographs - and folders named like them left out, a link to a missing file kept, to be named when read; a
    .pic only when it is a Radiance file: Apple's PICT pictures share the suffix); an error when there are none.
    Subfolders are not read: a warning names those that hold HDR files."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder} is not a folder of HDR images")
    nested = sorted(p.name for p in folder.iterdir() if not p.name.startswith(".") and p.is_dir() and _holds_hdr(p))
    if nested:
        warnings.warn(f"{folder}: HDR files in its subfolders {', '.join(nested)} are not read (only the folder's "
                      "own files are): give a subfolder as the folder, or move its files up")
    files = sorted(p for p in folder.iterdir()
                   if p.suffix.lower() in HDR_SUFFIXES and not p.name.startswith(".") and not p.is_dir()
                   and (p.suffix.lower() != ".pic" or not p.is_file() or is_radiance_file(p)))  # .pic: also PICT
    if not files:
        raise InputError(f"{folder} holds no .exr or .hdr files")
    return files


def _holds_hdr(folder: Path) -> bool:
    """Whether ``folder`` itself (not its subfolders) holds a file with an HDR suffix; False where it cannot be
    listed."""
    try:
        return any(p.suffix.lower() in HDR_SUFFIXES and not p.name.startswith(".") for p in folder.iterdir())
    except OSError:
        return False


SAFE_PEAK = 2.0 ** 64  # far above any photograph's radiance, far below float32's 3.4e38


def within_safe_range(image: np.ndarray) -> np.ndarray:
    """``image`` divided by its peak where the peak exceeds SAFE_PEAK, else unchanged. Training and testing scale
    every crop by its own brightest pixels, so a photograph's absolute scale never matters to them; near float32's
    limit, though, augmentation's colour gains would overflow to Inf."""
    peak = float(image.max(initial=0.0))
    return image / np.float32(peak) if peak > SAFE_PEAK else image


class HdrFolder:
    """The images of a folder, read once and kept in memory (float32). ``lenient`` (evaluation): a file that
    cannot be read is left out with a warning naming it and why, and kept in ``skipped`` as (path, reason), and
    +Inf pixels are taken as the image's largest finite value (read_hdr_image); an error only when no file can
    be read. Otherwise (training) either is an error. ``progress``: a tqdm-like bar, its total raised by the
    number of files, each named as it is read (a folder of large photographs takes minutes)."""

    def __init__(self, folder: Path, *, lenient: bool = False, progress=None):
        self.files, self.images, self.skipped = [], [], []
        paths = hdr_files(folder)
        if progress is not None:
            progress.total = (progress.total or 0) + len(paths)
        for path in paths:
            if progress is not None:
                progress.set_postfix_str(path.name)
            try:
                image = read_hdr_image(path, infinite_as_peak=lenient)
            except (InputError, OSError) as error:
                if not lenient:
                    raise
                message = failure_message(error)
                reason = message.removeprefix(f"{path}: ").removeprefix(f"{path} ")  # the path, named once
                warnings.warn(f"{path}: not evaluated - {reason}")
                self.skipped.append((path, reason))
            else:
                self.files.append(path)
                self.images.append(within_safe_range(image))
            if progress is not None:
                progress.update()
        if not self.files:
            raise InputError(f"{folder}: none of its {len(self.skipped)} HDR files could be read; nothing to evaluate")

    def __len__(self) -> int:
        return len(self.images)
