"""Write Bayer RAW frames as DNG files (Adobe DNG 1.4) that LibRaw/rawpy reads back bit-exactly.

Only what a linear RAW needs is written: the CFA layout, black and white levels, the XYZ -> camera colour
matrix for D65 (ColorMatrix1), the as-shot neutral, and exposure metadata (EXIF ExposureTime, FNumber,
ISO, DateTime). LibRaw does not read the ISO tag from DNGs (REFERENCE.md sec. 5), so capture manifests
carry ISO as well.
"""

from __future__ import annotations

import datetime as dt
import io
from fractions import Fraction
from pathlib import Path

import numpy as np
import tifffile

from hdrcam.io.atomic import write_bytes_atomic

CFA_CODES = {"R": 0, "G": 1, "B": 2}
_DNG_VERSION = (1, 4, 0, 0)
_SCALE = 10000  # denominator for rational colour values


def _rational(value: float, limit: int = 1_000_000) -> tuple[int, int]:
    fraction = Fraction(value).limit_denominator(limit)
    return fraction.numerator, fraction.denominator


def _rationals(values) -> tuple[int, ...]:
    flat: list[int] = []
    for value in values:
        flat.extend((round(float(value) * _SCALE), _SCALE))
    return tuple(flat)


def dng_bytes(bayer_dn: np.ndarray, *, cfa_pattern: str, black_level_dn: int, white_level_dn: int,
              xyz_to_camera: np.ndarray, as_shot_neutral: tuple[float, float, float], exposure_s: float,
              f_number: float, iso: int, timestamp: dt.datetime, make: str, model: str) -> bytes:
    """A uint16 Bayer frame (H x W digital numbers) as the bytes of an uncompressed DNG file.

    ``xyz_to_camera`` is the 3 x 3 DNG ColorMatrix1 (CIE XYZ, D65 -> camera RGB); ``as_shot_neutral`` the
    camera response to white, each channel <= 1.
    """
    bayer_dn = np.ascontiguousarray(bayer_dn)
    if bayer_dn.dtype != np.uint16 or bayer_dn.ndim != 2:
        raise ValueError(f"a DNG frame is a 2-D uint16 array, got {bayer_dn.dtype} {bayer_dn.shape}")
    if len(cfa_pattern) != 4 or set(cfa_pattern) - set(CFA_CODES):
        raise ValueError(f"unknown CFA pattern {cfa_pattern!r}")
    numerator, denominator = _rational(exposure_s)
    f_numerator, f_denominator = _rational(f_number, 1000)
    tags = [
        (33421, "H", 2, (2, 2), True),  # CFARepeatPatternDim
        (33422, "B", 4, tuple(CFA_CODES[c] for c in cfa_pattern), True),  # CFAPattern
        (50706, "B", 4, _DNG_VERSION, True),  # DNGVersion
        (50707, "B", 4, _DNG_VERSION, True),  # DNGBackwardVersion
        (50708, "s", 0, model, True),  # UniqueCameraModel
        (50714, "H", 1, (int(black_level_dn),), True),  # BlackLevel
        (50717, "H", 1, (int(white_level_dn),), True),  # WhiteLevel
        (50721, "2i", 9, _rationals(np.asarray(xyz_to_camera, float).ravel()), True),  # ColorMatrix1
        (50778, "H", 1, (21,), True),  # CalibrationIlluminant1 = D65
        (50728, "2I", 3, _rationals(as_shot_neutral), True),  # AsShotNeutral
        (33434, "2I", 1, (numerator, denominator), True),  # ExposureTime
        (33437, "2I", 1, (f_numerator, f_denominator), True),  # FNumber
        (34855, "H", 1, (min(int(iso), 65535),), True),  # ISOSpeedRatings
        (271, "s", 0, make, True),  # Make
        (272, "s", 0, model, True),  # Model
    ]
    buffer = io.BytesIO()
    tifffile.imwrite(buffer, bayer_dn, photometric=tifffile.PHOTOMETRIC.CFA, compression=None, subfiletype=0,
                     software="hdrcam", datetime=timestamp.strftime("%Y:%m:%d %H:%M:%S"), extratags=tags,
                     metadata=None)
    return buffer.getvalue()


def write_dng(path: str | Path, bayer_dn: np.ndarray, *, overwrite: bool = False, **metadata) -> Path:
    """Write a frame as a DNG file atomically; ``metadata`` as for ``dng_bytes``."""
    return write_bytes_atomic(Path(path), dng_bytes(bayer_dn, **metadata), overwrite=overwrite)
