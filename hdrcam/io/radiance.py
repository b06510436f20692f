"""Radiance RGBE / XYZE (.hdr, .pic) images as linear Rec. 709 / D65 radiance.

This module reads the header (Radiance's file format, "Radiance File Formats", G. Ward): the magic line
``#?...``, variable lines up to an empty line, then the resolution string ``<sign><axis> N1 <sign><axis> N2``
(the first axis the scanlines' order, the second the pixels' within one; ``-Y N +X M`` is top to bottom, left
to right). The pixels are decoded by OpenCV behind a standard header (OpenCV reads no orientation but the
standard one, no file without a FORMAT line and no XYZE) where they start new-style run-length, else, and where
OpenCV fails, by hdrcam.io.rgbe (flat and old-style run-length scanlines, which OpenCV refused), both as
m * 2 ** (e - 136), then turned and mirrored into the image, then:

- ``FORMAT=32-bit_rle_xyze``: CIE XYZ with Radiance's equal-energy white, converted to Rec. 709 / D65;
- ``EXPOSURE=`` (all such lines multiply) and ``COLORCORR=`` (per channel): the file's values are radiance
  times them, so they are divided out;
- ``PRIMARIES=``: RGB in those primaries, converted to Rec. 709 / D65 (all-zero primaries, as some writers store,
  count as absent; absent means Rec. 709, as files in the wild are).

``to_rec709=False`` keeps the values in the primaries they were stored in (XYZE as XYZ), as hdrcam.io.exr does for
a captured frame: its samples are clipped per stored channel, which a matrix would mix (a red light clipped in red
alone read as -0.47 in green and was refused as damaged). :func:`read_radiance_stored` gives the stored values and
their chromaticities, for a caller that converts them itself (hdrcam.data.hdr_folder, after its finite checks).
"""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from hdrcam.colorimetry import EQUAL_ENERGY_XYZ_CHROMATICITIES, in_rec709
from hdrcam.errors import InputError
from hdrcam.io.c_stderr import c_stderr_silenced
from hdrcam.io.file_magic import RADIANCE_MAGIC, starts_with
from hdrcam.io.rgbe import (MAX_RUN_LENGTH_SCANLINE, MIN_RUN_LENGTH_SCANLINE, DamagedPixels, colr_values,
                            decode_scanlines)
from hdrcam.limits import check_image_size

RADIANCE_SUFFIXES = (".hdr", ".pic")  # .pic: Radiance's own
FORMATS = ("32-bit_rle_rgbe", "32-bit_rle_xyze")
_RESOLUTION = re.compile(rb"([-+])([XY])\s+(\d+)\s+([-+])([XY])\s+(\d+)")
DECODED_BYTES_PER_PIXEL = 36  # OpenCV's float BGR image, its RGB copy and the corrected one (float32 each)
LARGEST_CORRECTION = 1e30  # EXPOSURE and COLORCORR, each line and their product, between its inverse and it
MAX_HEADER_BYTES = 1 << 16  # a header is a few lines; a file without an end to it within this is not Radiance


def is_radiance_file(path: Path) -> bool:
    """True for a file that begins with Radiance's magic ``#?``."""
    return starts_with(path, RADIANCE_MAGIC)


def read_radiance(path: Path, *, to_rec709: bool = True) -> np.ndarray:
    """H x W x 3 float32 linear Rec. 709 / D65 radiance of a Radiance file (module docstring), or with
    ``to_rec709`` False in the primaries it was stored in; InputError naming the file and what is wrong with it
    otherwise."""
    values, chromaticities = read_radiance_stored(path)
    return in_rec709(values, chromaticities) if to_rec709 else values


def read_radiance_stored(path: Path) -> tuple[np.ndarray, tuple[float, ...] | None]:
    """H x W x 3 float32 linear radiance of a Radiance file in the primaries it was stored in (EXPOSURE and
    COLORCORR divided out), and those primaries' chromaticities (red x, y, green x, y, blue x, y, white x, y:
    PRIMARIES=, Radiance's equal-energy XYZ for XYZE, None for neither: Rec. 709)."""
    data = Path(path).read_bytes()
    header_end = data.find(b"\n\n", 0, MAX_HEADER_BYTES)
    crlf_end = data.find(b"\r\n\r\n", 0, header_end if header_end >= 0 else MAX_HEADER_BYTES)
    if not data.startswith(RADIANCE_MAGIC) or header_end < 0 or crlf_end >= 0:
        raise InputError(f"{path}: {_not_radiance_reason(data, crlf_end >= 0)}")
    lines = data[:header_end].split(b"\n")[1:]
    variables = [line.split(b"=", 1) for line in lines if b"=" in line and not line.startswith(b"#")]
    resolution_end = data.find(b"\n", header_end + 2)
    match = _RESOLUTION.fullmatch(data[header_end + 2:resolution_end].strip()) if resolution_end > 0 else None
    if match is None or match.group(2) == match.group(5):
        shown = data[header_end + 2:header_end + 42].split(b"\n")[0].decode("ascii", "replace")
        raise InputError(f"{path}: Radiance resolution line {shown!r} is not '<+|-><X|Y> N <+|-><Y|X> M'")
    image_format = _format(path, variables)
    major_sign, major_axis, major, minor_sign, _, minor = match.groups()
    height, width = (int(major), int(minor)) if major_axis == b"Y" else (int(minor), int(major))
    check_image_size(str(path), height, width, DECODED_BYTES_PER_PIXEL, "give a smaller image")
    values = _pixel_values(path, data[resolution_end + 1:], int(major), int(minor))
    x_sign, y_sign = (minor_sign, major_sign) if major_axis == b"Y" else (major_sign, minor_sign)
    if major_axis == b"X":  # scanlines run down the columns
        values = values.transpose(1, 0, 2)
    if y_sign == b"+":  # +Y: the first scanline is the bottom one
        values = values[::-1]
    if x_sign == b"-":
        values = values[:, ::-1]
    return _corrected(path, np.ascontiguousarray(values), image_format, variables)


def _not_radiance_reason(data: bytes, crlf: bool) -> str:
    """Why ``data`` (a file's bytes) is not read as Radiance: no magic line, a header ending in CR LF CR LF
    (``crlf``; the LF LF that ends a header may then turn up in the pixels), or no empty line ending it."""
    if not data.startswith(RADIANCE_MAGIC):
        return "not a Radiance file (it does not start with the '#?' magic line)"
    if crlf:
        return ("Radiance header lines end in CR LF, not LF: a copy made in text mode, which also changes the binary "
                "pixel data; copy the original file in binary mode")
    return "not a Radiance file (no empty line ends its header)"


def _pixel_values(path: Path, pixels: bytes, count: int, length: int) -> np.ndarray:
    """``count`` scanlines of ``length`` pixels as count x length x 3 float32 values (m * 2 ** (e - 136)), in the
    order stored: by OpenCV (C speed) when the first scanline is new-style run-length, as in files of Radiance and
    most writers, and it decodes them; by hdrcam.io.rgbe otherwise (flat and old-style run-length scanlines,
    which OpenCV refused, mixed encodings) and to name the damage of a file OpenCV cannot decode."""
    if MIN_RUN_LENGTH_SCANLINE <= length <= MAX_RUN_LENGTH_SCANLINE and pixels[:2] == b"\x02\x02" and \
            len(pixels) > 2 and pixels[2] < 128:
        standard = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (count, length)
        with c_stderr_silenced():  # OpenCV prints its own lines for damaged data
            decoded = cv2.imdecode(np.frombuffer(standard + pixels, np.uint8), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
        if decoded is not None:
            return cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB).astype(np.float32)
    try:
        return colr_values(decode_scanlines(pixels, count, length))
    except DamagedPixels as error:
        raise InputError(f"{path}: Radiance pixel data cannot be decoded: {error}") from None


def _format(path: Path, variables: list[list[bytes]]) -> str:
    formats = [value.strip().decode("ascii", "replace") for name, value in variables if name.strip() == b"FORMAT"]
    image_format = formats[-1] if formats else FORMATS[0]  # no FORMAT line: Radiance's default
    if image_format not in FORMATS:
        raise InputError(f"{path}: Radiance FORMAT={image_format} is not one of {', '.join(FORMATS)}")
    return image_format


def _corrected(path: Path, values: np.ndarray, image_format: str, variables: list[list[bytes]]
               ) -> tuple[np.ndarray, tuple[float, ...] | None]:
    """The decoded values as radiance (exposure and colour corrections divided out) and their primaries'
    chromaticities (read_radiance_stored)."""
    divisor = np.ones(3)
    primaries = None
    for name, value in variables:
        name = name.strip()
        if name not in (b"EXPOSURE", b"COLORCORR", b"PRIMARIES"):
            continue
        try:
            numbers = np.array(value.split(), np.float64)
        except ValueError:
            raise InputError(f"{path}: Radiance {name.decode()}={value.decode('ascii', 'replace').strip()} is not "
                             "numbers") from None
        expected = {b"EXPOSURE": 1, b"COLORCORR": 3, b"PRIMARIES": 8}[name]
        scale = name != b"PRIMARIES"
        usable = np.all(np.isfinite(numbers)) and (not scale or np.all((numbers >= 1 / LARGEST_CORRECTION) &
                                                                       (numbers <= LARGEST_CORRECTION)))
        if numbers.size != expected or not usable:
            raise InputError(f"{path}: Radiance {name.decode()}= needs {expected} "
                             f"{'positive ' if scale else ''}finite numbers"
                             f"{f' from {1 / LARGEST_CORRECTION:g} to {LARGEST_CORRECTION:g}' if scale else ''}, "
                             f"got {value.decode('ascii', 'replace').strip()!r}")
        if name == b"PRIMARIES":
            primaries = numbers
        else:
            divisor *= numbers
    if not np.array_equal(divisor, np.ones(3)):
        corrected = values / divisor  # float64: no overflow on the way
        if not (np.all(divisor <= LARGEST_CORRECTION) and np.all(divisor >= 1 / LARGEST_CORRECTION)
                and float(corrected.max(initial=0.0)) <= np.finfo(np.float32).max):
            raise InputError(f"{path}: Radiance EXPOSURE and COLORCORR lines multiply to "
                             f"{', '.join(f'{value:.3g}' for value in divisor)}, which put its radiance beyond "
                             "float32 (or below it); check the header")
        values = corrected.astype(np.float32)
    if image_format == FORMATS[1]:
        return values, EQUAL_ENERGY_XYZ_CHROMATICITIES
    return values, None if primaries is None else tuple(float(number) for number in primaries)
