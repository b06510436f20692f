"""What a user checks before trusting a RAW capture: one dictionary per file, for ``hdrcam inspect``.

Levels are digital numbers per position of the 2 x 2 CFA tile, row-major like ``cfa``; the clip level is
measured from the data (hdrcam.io.raw_clipping) and ``clipped_fraction`` is the share of samples at or above
it. ``orientation`` is the EXIF Orientation code that displays the frame upright (6: turn 90 degrees
clockwise); the sizes are the sensor's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hdrcam.io.raw import read_raw
from hdrcam.io.raw_clipping import clipped_samples


def raw_summary(path: str | Path) -> dict:
    """make, model, format, size, orientation, CFA, exposure, ISO, aperture, black, metadata white, measured clip
    level, clipped fraction, the colour matrix's source and any DNG lens shading left out of one RAW file;
    InputError if it cannot be read."""
    frame = read_raw(path)
    meta = frame.metadata
    clip = frame.clip_level_tile_dn
    return {
        "file": str(meta.path), "make": meta.make, "model": meta.camera_model, "format": meta.file_format,
        "width_px": meta.width_px, "height_px": meta.height_px, "orientation": meta.orientation,
        "cfa": meta.cfa_pattern, "exposure_s": meta.exposure_s, "iso": meta.iso, "f_number": meta.f_number,
        "timestamp": meta.timestamp.isoformat() if meta.timestamp else None,
        "black_level_dn": [round(float(v), 3) for v in meta.black_level_dn],
        "white_level_dn": meta.white_level_dn,
        "clip_level_dn": [float(v) for v in clip.ravel()],
        "clip_below_white": bool((clip < meta.white_level_dn).any()),
        "clipped_fraction": float(np.count_nonzero(clipped_samples(frame.bayer_dn, clip)) / frame.bayer_dn.size),
        "max_dn": int(frame.bayer_dn.max()),
        "colour_matrix_source": meta.colour_matrix_source,
        "shading_not_applied": list(meta.shading_not_applied),
    }
