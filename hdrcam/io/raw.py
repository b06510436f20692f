"""Read RAW frames (ARW, DNG and whatever LibRaw reads) with rawpy.

``read_raw_metadata`` gives what a bracket needs to know (exposure, ISO, aperture, time, levels, colour);
``read_raw`` adds the Bayer data: the visible area in digital numbers (uint16), untouched - no black
subtraction, no demosaicing. LibRaw does not report ISO for DNGs, nor the camera model; both are read
from the TIFF tags (ARW and DNG are TIFF files) when LibRaw has nothing, and a capture manifest can
override ISO.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import os
import sys
from pathlib import Path

import numpy as np
import tifffile

from hdrcam.errors import InputError

RAW_SUFFIXES = (".arw", ".dng", ".nef", ".cr2", ".cr3", ".raf", ".orf", ".rw2", ".pef", ".srw")
_CFA_LETTERS = "RGBG"  # LibRaw colour indices: 0 R, 1 G, 2 B, 3 second G


@dataclasses.dataclass(frozen=True)
class RawMetadata:
    """What is known about one RAW exposure without its pixels."""

    path: Path
    width_px: int
    height_px: int
    cfa_pattern: str  # the 2 x 2 tile starting at the top-left visible pixel, e.g. "RGGB"
    black_level_dn: tuple[float, float, float, float]  # per tile position, row-major like cfa_pattern
    white_level_dn: float
    xyz_to_camera: np.ndarray  # 3 x 3, D65 (DNG ColorMatrix1 or LibRaw's table for the model)
    as_shot_neutral: np.ndarray  # camera RGB of white, max 1
    exposure_s: float
    iso: float | None
    f_number: float | None
    timestamp: dt.datetime | None
    camera_model: str

    def black_level_tile(self) -> np.ndarray:
        """The 2 x 2 tile of black levels (float32), row-major like ``cfa_pattern``."""
        return np.asarray(self.black_level_dn, dtype=np.float32).reshape(2, 2)


@dataclasses.dataclass(frozen=True)
class RawFrame:
    metadata: RawMetadata
    bayer_dn: np.ndarray  # H x W uint16


def read_raw_metadata(path: str | Path) -> RawMetadata:
    """Metadata of a RAW file; InputError for a missing, damaged or non-Bayer file."""
    return _read(Path(path), with_pixels=False)[0]


def read_raw(path: str | Path) -> RawFrame:
    """A RAW file's metadata and Bayer digital numbers."""
    metadata, bayer = _read(Path(path), with_pixels=True)
    return RawFrame(metadata, bayer)


def _read(path: Path, with_pixels: bool) -> tuple[RawMetadata, np.ndarray | None]:
    import rawpy

    if not path.is_file():
        raise InputError(f"{path}: no such RAW file")
    try:
        with _libraw_stderr_silenced(), rawpy.imread(str(path)) as raw:
            if raw.raw_type != rawpy.RawType.Flat or raw.num_colors != 3:
                raise InputError(f"{path}: not a Bayer RAW file (LibRaw: {raw.raw_type}, {raw.num_colors} colours)")
            tile = raw.raw_pattern[:2, :2].ravel()
            black = [float(b) for b in raw.black_level_per_channel]
            other = raw.other
            bayer = np.array(raw.raw_image_visible, dtype=np.uint16) if with_pixels else None
            tiff_model, tiff_iso = _tiff_tags(path)
            metadata = RawMetadata(
                path=path, width_px=int(raw.sizes.width), height_px=int(raw.sizes.height),
                cfa_pattern="".join(_CFA_LETTERS[i] for i in tile),
                black_level_dn=tuple(black[i] for i in tile), white_level_dn=float(raw.white_level),
                xyz_to_camera=np.array(raw.rgb_xyz_matrix[:3, :3], dtype=np.float64),
                as_shot_neutral=_neutral_from_multipliers(np.array(raw.camera_whitebalance[:3], np.float64)),
                exposure_s=float(f"{other.shutter_speed:.7g}"),  # LibRaw keeps float32
                iso=float(other.iso_speed) if other.iso_speed > 0 else tiff_iso,
                f_number=float(f"{other.aperture:.4g}") if other.aperture > 0 else None,  # float32 in LibRaw
                timestamp=other.timestamp if isinstance(other.timestamp, dt.datetime) else None,
                camera_model=tiff_model or "unknown")
    except InputError:
        raise
    except Exception as error:  # LibRaw raises many types for damaged or unsupported files
        raise InputError(f"{path}: cannot read as RAW ({type(error).__name__}: {error})") from None
    if not metadata.exposure_s > 0:
        raise InputError(f"{path}: the file has no exposure time; give the exposures in a bracket.json")
    return metadata, bayer


@contextlib.contextmanager
def _libraw_stderr_silenced():
    """Send file descriptor 2 to /dev/null while LibRaw runs: its C code prints its own lines (e.g.
    "Unexpected end of file") for damaged files, which hdrcam already reports in one line of its own."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _tiff_tags(path: Path) -> tuple[str | None, float | None]:
    """(Make + Model, ISO) from the first IFD and its EXIF IFD; (None, None) for non-TIFF RAW formats."""
    try:
        with tifffile.TiffFile(path) as tiff:
            tags = tiff.pages[0].tags
            name = " ".join(str(tags[code].value).strip() for code in (271, 272) if code in tags) or None
            exif = tags[34665].value if 34665 in tags else {}
            iso_value = tags[34855].value if 34855 in tags else (exif or {}).get("ISOSpeedRatings")
    except Exception:
        return None, None
    if isinstance(iso_value, (tuple, list)):
        iso_value = iso_value[0] if iso_value else None
    return name, float(iso_value) if iso_value else None


def _neutral_from_multipliers(multipliers: np.ndarray) -> np.ndarray:
    """LibRaw white-balance multipliers -> as-shot neutral (their reciprocals, max 1); ones if unknown."""
    if not np.all(multipliers > 0):
        return np.ones(3)
    neutral = 1.0 / multipliers
    return neutral / neutral.max()
