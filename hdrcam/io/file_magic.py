"""Whether a file begins with a format's magic bytes: how a file is known whatever its name.

The readers (hdrcam.io.ldr_frame for frames, hdrcam.data.hdr_folder for scenes and photographs) choose by the
file's first bytes, and by its suffix only where they match no format here: a TIFF named .png went to OpenCV,
which scrambles planar TIFFs, and a Radiance file named .exr to OpenEXR, which refused it with its own stream name.
"""

from __future__ import annotations

from pathlib import Path

EXR_MAGIC = b"\x76\x2f\x31\x01"  # OpenEXR file layout, "Magic number"
RADIANCE_MAGIC = b"#?"  # Radiance file formats: the first line, "#?RADIANCE" and the like
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"  # PNG specification, 5.2
JPEG_MAGIC = b"\xff\xd8\xff"  # JPEG's SOI marker and the next marker's first byte
TIFF_MAGICS = (b"II*\0", b"MM\0*", b"II+\0", b"MM\0+")  # TIFF 6.0 section 2 (little-, big-endian); BigTIFF
# Format names as the readers name them, and each format's magic bytes
FORMAT_MAGICS = (("OpenEXR", (EXR_MAGIC,)), ("Radiance", (RADIANCE_MAGIC,)), ("TIFF", TIFF_MAGICS),
                 ("PNG", (PNG_MAGIC,)), ("JPEG", (JPEG_MAGIC,)))
_ARTICLES = {"OpenEXR": "an OpenEXR file", "Radiance": "a Radiance file", "TIFF": "a TIFF", "PNG": "a PNG",
             "JPEG": "a JPEG"}


def starts_with(path: Path, magic: bytes) -> bool:
    """True when the file at ``path`` begins with ``magic``."""
    with open(path, "rb") as handle:
        return handle.read(len(magic)) == magic


def file_format(path: Path) -> str | None:
    """"OpenEXR", "Radiance", "TIFF", "PNG" or "JPEG" for a file that begins with that format's magic bytes, else
    None (an empty file, a RAW file other than a TIFF-based one, another format)."""
    with open(path, "rb") as handle:
        start = handle.read(8)
    return next((name for name, magics in FORMAT_MAGICS if start.startswith(magics)), None)


def is_empty_file(path: Path) -> bool:
    """True for a regular file of 0 bytes (a copy or download that failed)."""
    return Path(path).stat().st_size == 0


def not_format_reason(path: Path, expected: str) -> str:
    """Why the file at ``path`` is not of the ``expected`` format (a name of FORMAT_MAGICS), for a message after
    its path: "an empty file (0 bytes)", "a JPEG, not an OpenEXR file", or "not an OpenEXR file (it does not
    start with OpenEXR's magic bytes)"."""
    if is_empty_file(path):
        return "an empty file (0 bytes)"
    found = file_format(path)
    if found is not None and found != expected:
        return f"{_ARTICLES[found]}, not {_ARTICLES[expected]}"
    return f"not {_ARTICLES[expected]} (it does not start with {expected}'s magic bytes)"
