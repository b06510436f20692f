"""Radiance's 4-byte pixels (RGBE / XYZE): the scanline encodings and the decode to floats, after "Radiance File
Formats" (G. Ward) and Radiance's own reader (src/common/color.c: freadcolrs, oldreadcolrs, colr_color).

A scanline is stored in one of three ways, chosen per scanline:

- flat: 4 bytes per pixel (mantissas of the three channels, a shared exponent);
- new-style run-length: the bytes 2, 2, then the scanline length (two bytes, big-endian, below 32768), then each
  of the four byte planes in turn as records: a count above 128 repeats the next byte (count - 128) times, a count
  of 128 or less is followed by that many literal bytes. Only scanlines 8 to 32767 pixels long use it;
- old-style run-length: flat pixels among which a pixel 1, 1, 1, n repeats the previous pixel n times (the count
  shifted 8 bits further for each consecutive such record).

A mantissa m with exponent e is m * 2 ** (e - 136), e = 0 black: OpenCV's and stb_image's decode, which
hdrcam.io.radiance's OpenCV path gives. Radiance's own colr_color decodes (m + 0.5) * 2 ** (e - 136), the middle
of the interval its truncating encoder (setcolr) maps to m: 0.2 to 0.4 % higher in a pixel's largest channel,
at most half a quantisation step.
"""

from __future__ import annotations

import numpy as np

MIN_RUN_LENGTH_SCANLINE, MAX_RUN_LENGTH_SCANLINE = 8, 0x7FFF  # new-style run-length scanlines' lengths (color.h)


class DamagedPixels(ValueError):
    """The pixel data end early or do not follow any scanline encoding; the message says where."""


def decode_scanlines(data: bytes, count: int, length: int) -> np.ndarray:
    """``count`` scanlines of ``length`` pixels from ``data`` (the bytes after the resolution line) as a
    count x length x 4 uint8 array of mantissas and exponents, in the order stored. DamagedPixels when they end
    early or are damaged."""
    buffer = np.frombuffer(data, np.uint8)
    pixels = np.empty((count, length, 4), np.uint8)
    position = 0
    for row in range(count):
        new_style = (MIN_RUN_LENGTH_SCANLINE <= length <= MAX_RUN_LENGTH_SCANLINE and data[position:position + 2]
                     == b"\x02\x02" and position + 4 <= len(data) and data[position + 2] < 128)
        try:
            if new_style:
                position = _run_length_scanline(data, position, pixels[row])
            else:
                previous = pixels[row - 1, -1] if row else None
                position = _old_style_scanline(buffer, position, pixels[row], previous)
        except DamagedPixels as error:
            raise DamagedPixels(f"scanline {row + 1} of {count}: {error}") from None
    return pixels


def _run_length_scanline(data: bytes, position: int, scanline: np.ndarray) -> int:
    """Decode one new-style run-length scanline starting at ``position`` (its 2, 2 marker) into ``scanline``
    (length x 4); the position after it. Plain bytes operations: a numpy call per record took 10 times OpenCV's
    time."""
    length = scanline.shape[0]
    stated = data[position + 2] << 8 | data[position + 3]
    if stated != length:
        raise DamagedPixels(f"says it is {stated} pixels long, not {length}")
    position += 4
    for plane in range(4):
        pieces, filled = [], 0
        while filled < length:
            if position >= len(data):
                raise DamagedPixels("the file ends inside it (truncated)")
            code = data[position]
            count = code & 127 if code > 128 else code
            if filled + count > length:
                raise DamagedPixels("a run goes past its end (damaged)")
            end = position + 1 + (1 if code > 128 else count)
            if end > len(data):
                raise DamagedPixels("the file ends inside it (truncated)")
            pieces.append(data[position + 1:end] * count if code > 128 else data[position + 1:end])
            filled += count
            position = end
        scanline[:, plane] = np.frombuffer(b"".join(pieces), np.uint8)
    return position


def _old_style_scanline(buffer: np.ndarray, position: int, scanline: np.ndarray, previous) -> int:
    """Decode one flat or old-style run-length scanline starting at ``position`` into ``scanline`` (length x 4);
    ``previous``: the last pixel of the scanline before (a run at the start repeats it), None for the first; the
    position after it. The records are taken in windows of as many as the pixels still to fill (each gives one,
    but a repeat record of count 0): a window's repeat records are found in one pass, the flat stretches between
    them copied whole."""
    length, filled, shift = scanline.shape[0], 0, 0
    while filled < length:
        records = buffer[position:position + 4 * (length - filled)]
        records = records[:records.size // 4 * 4].reshape(-1, 4)
        if not records.size:
            raise DamagedPixels("the file ends inside it (truncated)")
        used = 0
        for index in np.flatnonzero((records[:, 0] == 1) & (records[:, 1] == 1) & (records[:, 2] == 1)).tolist():
            flat = min(index - used, length - filled)  # the flat pixels before this repeat record
            scanline[filled:filled + flat] = records[used:used + flat]
            filled, used = filled + flat, used + flat
            if filled == length:  # the record belongs to the next scanline
                break
            shift = shift if flat == 0 else 0  # consecutive repeat records count in higher bytes
            count = int(records[used, 3]) << shift
            source = scanline[filled - 1] if filled else previous
            if source is None or filled + count > length:
                raise DamagedPixels("a repeat record has no pixel to repeat or goes past its end (damaged)")
            scanline[filled:filled + count] = source
            filled, used, shift = filled + count, used + 1, shift + 8
        else:  # the window's records after its last repeat record are flat pixels
            flat = min(records.shape[0] - used, length - filled)
            scanline[filled:filled + flat] = records[used:used + flat]
            filled, used, shift = filled + flat, used + flat, shift if flat == 0 else 0
        position += 4 * used
    return position


def colr_values(pixels: np.ndarray) -> np.ndarray:
    """... x 3 float32 values of ... x 4 mantissas and exponents: m * 2 ** (e - 136), black where e = 0.
    Units: those of the file (watts/steradian/m^2 for Radiance's own renderings)."""
    exponents = pixels[..., 3:4].astype(np.int32)
    values = np.ldexp(pixels[..., :3].astype(np.float32), exponents - 136)
    return np.where(exponents > 0, values, np.float32(0.0)).astype(np.float32)
