"""PNG output for previews and fabrication masks (8 or 16 bit, grey or RGB), written atomically; the transfer
curve a PNG input declares in its colour chunks."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np

from hdrcam.io.atomic import write_bytes_atomic
from hdrcam.io.icc_profile import tone_curve_encoding


def write_png(path: Path, image: np.ndarray, *, overwrite: bool = False) -> Path:
    """Write an H x W (grey) or H x W x 3 (RGB order) uint8/uint16 image."""
    return write_bytes_atomic(Path(path), encoded_png(image, path), overwrite=overwrite)


def encoded_png(image: np.ndarray, path: Path | str = "image") -> bytes:
    """The PNG file of an H x W (grey) or H x W x 3 (RGB order) uint8/uint16 image (``path`` names it in errors)."""
    image = np.asarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"PNG needs uint8 or uint16 pixels, got {image.dtype}")
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise ValueError(f"could not encode {path} as PNG")
    return encoded.tobytes()


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_LINEAR_GAMMA = 100_000  # gAMA stores 100000 / the encoding exponent: 100000 is linear
PNG_CICP_LINEAR = 8  # cICP transfer characteristics (ITU-T H.273): 8 is linear


PNG_GREY_COLOUR_TYPES = {0: "grey", 4: "grey and alpha"}  # IHDR colour types (PNG specification, 11.2.2)


def png_size_px(path: Path) -> tuple[int, int] | None:
    """(width, height) that a PNG's IHDR declares, or None for a file that is not a PNG."""
    header = _ihdr(path)
    return None if header is None else header[:2]


def grey_png_kind(path: Path) -> str | None:
    """"grey" or "grey and alpha" for a PNG whose IHDR declares no colour (OpenCV expands grey and alpha to four
    channels, which read as RGB), else None (a colour PNG, or not a PNG)."""
    header = _ihdr(path)
    return None if header is None else PNG_GREY_COLOUR_TYPES.get(header[2])


def _ihdr(path: Path) -> tuple[int, int, int] | None:
    """(width, height, colour type) from a PNG's IHDR chunk, or None for a file that does not start as a PNG."""
    with open(path, "rb") as file:
        start = file.read(len(PNG_SIGNATURE) + 18)  # the signature, IHDR's length and type, width, height, depth,
    if not start.startswith(PNG_SIGNATURE) or start[12:16] != b"IHDR" or len(start) < len(PNG_SIGNATURE) + 18:
        return None  # ... and colour type
    width, height = struct.unpack(">II", start[16:24])
    return width, height, start[25]


def declared_nonlinear_encoding(path: Path) -> str | None:
    """What a PNG's colour chunks (those before its image data) say of a non-linear encoding, by the PNG
    specification's precedence (cICP over iCCP over sRGB over gAMA): a cICP transfer other than linear, an ICC
    profile whose tone curves are not the identity (hdrcam.io.icc_profile), an sRGB chunk, a gAMA other than 1.0
    - or None (no such chunk, a linear one, not a PNG). 16-bit PNGs from photo editors and RAW converters carry
    these. Chunk lengths are not trusted: only the colour chunks are read (an ICC profile up to ICC_MAX_BYTES,
    compressed or not), the others skipped."""
    said: dict[bytes, str | None] = {}
    with open(path, "rb") as file:
        if file.read(len(PNG_SIGNATURE)) != PNG_SIGNATURE:
            return None
        while len(header := file.read(8)) == 8:
            length, kind = struct.unpack(">I4s", header)
            if kind in (b"IDAT", b"IEND"):
                break
            if (kind in (b"cICP", b"sRGB", b"gAMA") and length <= COLOUR_CHUNK_MAX_BYTES) or \
                    (kind == b"iCCP" and length <= ICC_MAX_BYTES):
                said.setdefault(kind, _nonlinear(kind, file.read(length)))
                file.seek(4, 1)  # the chunk's CRC
            else:
                said.setdefault(kind, "an ICC profile (iCCP) larger than hdrcam reads" if kind == b"iCCP" else None)
                file.seek(length + 4, 1)
    for kind in (b"cICP", b"iCCP", b"sRGB", b"gAMA"):
        if kind in said:
            return said[kind]
    return None


COLOUR_CHUNK_MAX_BYTES = 16  # cICP holds 4 bytes, gAMA 4, sRGB 1
ICC_MAX_BYTES = 1 << 22  # an ICC profile, compressed or not: a matrix/TRC profile takes a few kB, LUT-based ones
# up to a few hundred


def _nonlinear(kind: bytes, body: bytes) -> str | None:
    """What one colour chunk says of a non-linear encoding, or None when it says the samples are linear."""
    if kind == b"sRGB":
        return "an sRGB chunk"
    if kind == b"gAMA" and len(body) == 4:
        value = struct.unpack(">I", body)[0]
        if value and abs(value - PNG_LINEAR_GAMMA) > PNG_LINEAR_GAMMA // 100:
            return f"gAMA {value / PNG_LINEAR_GAMMA:.5g} (encoding exponent {PNG_LINEAR_GAMMA / value:.3g})"
    if kind == b"cICP" and len(body) >= 2 and body[1] != PNG_CICP_LINEAR:
        return f"cICP transfer {body[1]}"
    if kind == b"iCCP":
        what = tone_curve_encoding(_iccp_profile(body))
        return f"an ICC profile (iCCP: {what})" if what else None
    return None


def _iccp_profile(body: bytes) -> bytes:
    """The ICC profile of an iCCP chunk (a name, a zero byte, compression method 0, the zlib stream), inflated to
    at most ICC_MAX_BYTES; b"" when the chunk is damaged (read as a damaged profile)."""
    name_end = body.find(b"\0")
    if name_end < 1 or len(body) < name_end + 2 or body[name_end + 1] != 0:
        return b""
    try:
        return zlib.decompressobj().decompress(body[name_end + 2:], ICC_MAX_BYTES)
    except zlib.error:
        return b""
