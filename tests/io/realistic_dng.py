"""DNG files with realistic sensor statistics, for what the one real ARW in ../shared/data/raw does not cover:
a clip pile-up below the metadata white level (with lossy-compression scatter above it), other CFA layouts and
per-channel black levels, X-Trans, zero or missing colour matrices, other makes.

Written with tifffile directly (not hdrcam.io.dng) so the reader is tested against files it did not write
itself, with the tag layouts other converters use (BlackLevelRepeatDim, a 6 x 6 CFARepeatPatternDim).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import tifffile

_CFA_CODES = {"R": 0, "G": 1, "B": 2}
XYZ_TO_CAMERA = np.array([[0.664, -0.1847, -0.0503], [-0.5238, 1.301, 0.2474], [-0.0993, 0.1673, 0.6527]])
XTRANS = ("GGRGGB" "GGBGGR" "BRGRBG" "GGBGGR" "GGRGGB" "RBGBRG")


def sensor_dn(radiance: np.ndarray, exposure_s: float, rng: np.random.Generator, *,
              black_dn=(512, 512, 512, 512), clip_dn: float = 13500, electrons_per_dn: float = 1.5,
              read_noise_dn: float = 3.0, scatter_dn: int = 0) -> np.ndarray:
    """A Bayer frame in DN: shot noise (Poisson in electrons) and Gaussian read noise on ``radiance`` (DN per
    second above black, H x W), black added per CFA position, clipped at ``clip_dn`` as the sensor does (a
    pile-up), ``scatter_dn`` > 0 scattering clipped samples up to that far above it (lossy compression),
    never above the 14-bit range."""
    height, width = radiance.shape
    black = np.tile(np.asarray(black_dn, float).reshape(2, 2), (height // 2 + 1, width // 2 + 1))[:height, :width]
    electrons = rng.poisson(np.maximum(radiance * exposure_s, 0.0) * electrons_per_dn)
    dn = black + electrons / electrons_per_dn + rng.normal(0.0, read_noise_dn, radiance.shape)
    clipped = dn >= clip_dn
    dn = np.minimum(np.round(dn), clip_dn)
    if scatter_dn:  # one clipped sample in ten lands 32, 64, ... DN above the pile-up, as in Sony's cRAW
        count = int(clipped.sum())
        dn[clipped] += rng.integers(0, scatter_dn // 32 + 1, count) * 32 * (rng.random(count) < 0.1)
    return np.clip(dn, 0, 2 ** 14 - 1).astype(np.uint16)


def write_dng(path: Path, bayer_dn: np.ndarray, *, cfa: str = "RGGB", black_dn=(512, 512, 512, 512),
              white_dn: int = 16383, exposure_s: float = 0.01, iso: int | None = 100, colour_matrix=XYZ_TO_CAMERA,
              as_shot_neutral=(0.5, 1.0, 0.7),
              make: str = "Acme", model: str = "Testbody 1", datetime: str = "2026:11:24 12:00:00",
              truncate_to: int | None = None, orientation: int | None = None, extra_tags=()) -> Path:
    """An uncompressed DNG; ``cfa`` of 4 letters (2 x 2), 16 (4 x 4) or 36 (6 x 6 X-Trans); ``colour_matrix`` None
    to leave ColorMatrix1 out; ``truncate_to`` cuts the file to that many bytes (a copy that broke off);
    ``orientation`` the EXIF Orientation code (6: a portrait shot, turn 90 degrees clockwise to display), None to
    leave the tag out; ``iso`` None to leave ISOSpeedRatings out; ``as_shot_neutral`` the camera RGB of white;
    ``extra_tags`` more tags, as tifffile's extratags."""
    side = round(len(cfa) ** 0.5)
    tags = [
        (33421, "H", 2, (side, side), True),
        (33422, "B", len(cfa), tuple(_CFA_CODES[c] for c in cfa), True),
        (50706, "B", 4, (1, 4, 0, 0), True),
        (50708, "s", 0, f"{make} {model}", True),
        (50713, "H", 2, (2, 2), True),  # BlackLevelRepeatDim
        (50714, "H", 4, tuple(int(b) for b in black_dn), True),
        (50717, "H", 1, (white_dn,), True),
        (50778, "H", 1, (21,), True),
        (50728, "2I", 3, tuple(v for value in as_shot_neutral for v in (round(value * 10000), 10000)), True),
        (33434, "2I", 1, (round(exposure_s * 1_000_000), 1_000_000), True),
        (33437, "2I", 1, (40, 10), True),
        *([(34855, "H", 1, (iso,), True)] if iso is not None else []),
        (271, "s", 0, make, True),
        (272, "s", 0, model, True),
    ]
    if orientation is not None:
        tags.append((274, "H", 1, (orientation,), True))
    if colour_matrix is not None:
        flat = []
        for value in np.asarray(colour_matrix, float).ravel():
            flat.extend((round(value * 10000), 10000))
        tags.append((50721, "2i", 9, tuple(flat), True))
    tifffile.imwrite(path, np.ascontiguousarray(bayer_dn), photometric=tifffile.PHOTOMETRIC.CFA, compression=None,
                     subfiletype=0, datetime=datetime, extratags=tags + list(extra_tags), metadata=None)
    if truncate_to is not None:
        content = path.read_bytes()
        path.write_bytes(content[:truncate_to])
    return path
