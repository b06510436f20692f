"""Whether an embedded ICC profile says a file's values are linear: its tone curves (rTRC, gTRC, bTRC).

A matrix/TRC profile maps each stored value through a tone curve before its matrix (ICC.1:2010, 10.6 curveType
'curv' - identity, one gamma, or a table - and 10.18 parametricCurveType 'para', functions 0 to 4); 16-bit TIFF
and PNG files exported by RAW converters carry one: gamma-encoded (sRGB, Adobe RGB, ProPhoto's 1.8) or linear
(a converter's "linear" output profile). A profile whose three curves are the identity stores linear values; any
other curve, a profile with LUTs (A2Bn, D2Bn: colour management applies them instead of the curves, and this
module does not evaluate them), one without the three curves (grey, CMYK) or a damaged one is not known to be
linear.
"""

from __future__ import annotations

import struct

import numpy as np

HEADER_BYTES = 128
TAG_ENTRY_BYTES = 12
PROFILE_SIGNATURE = b"acsp"  # at byte 36 of every ICC profile
TONE_CURVE_TAGS = (b"rTRC", b"gTRC", b"bTRC")
LUT_TAGS = (b"A2B0", b"A2B1", b"A2B2", b"D2B0", b"D2B1", b"D2B2")  # colour management uses these before the curves
IDENTITY_TOLERANCE = 1e-3  # of white, anywhere on the curve: a gamma within 1 +- 0.0027 stays within it, a
# table's 16-bit rounding (1.5e-5) far within
CURVE_SAMPLES = np.linspace(0.0, 1.0, 257)
PARAMETER_COUNTS = {0: 1, 1: 3, 2: 4, 3: 5, 4: 7}  # parametricCurveType's function type -> its parameters


def tone_curve_encoding(profile: bytes) -> str | None:
    """None when ``profile`` (an ICC profile's bytes) maps every stored value to itself through its three tone
    curves - the values are linear; otherwise what it does instead, for a message ("gamma 2.2", "a 1024-point
    tone curve", "a LUT-based profile", "damaged")."""
    if len(profile) < HEADER_BYTES + 4 or profile[36:40] != PROFILE_SIGNATURE:
        return "damaged"
    (tag_count,) = struct.unpack_from(">I", profile, HEADER_BYTES)
    if HEADER_BYTES + 4 + tag_count * TAG_ENTRY_BYTES > len(profile):
        return "damaged"
    tags = {}
    for index in range(tag_count):
        signature, offset, size = struct.unpack_from(">4sII", profile, HEADER_BYTES + 4 + index * TAG_ENTRY_BYTES)
        tags.setdefault(signature, profile[offset:offset + size] if offset + size <= len(profile) else b"")
    if any(tag in tags for tag in LUT_TAGS):  # littleCMS reads a profile's LUT first, its curves only without one
        return "a LUT-based profile"
    if not all(tag in tags for tag in TONE_CURVE_TAGS):
        return "no RGB tone curves: a grey, CMYK or LUT-based profile"
    for tag in TONE_CURVE_TAGS:
        curve = _evaluated(tags[tag])
        if curve is None:
            return "damaged"
        values, what = curve
        if not np.all(np.abs(values - CURVE_SAMPLES) <= IDENTITY_TOLERANCE):
            return what
    return None


def _evaluated(tag: bytes) -> tuple[np.ndarray, str] | None:
    """A tone curve tag's values at CURVE_SAMPLES and what it is, or None when it is neither 'curv' nor 'para'
    or is cut short."""
    kind = tag[:4]
    if kind == b"curv" and len(tag) >= 12:
        (count,) = struct.unpack_from(">I", tag, 8)
        if count == 0:
            return CURVE_SAMPLES, "the identity"
        if count == 1 and len(tag) >= 14:
            gamma = struct.unpack_from(">H", tag, 12)[0] / 256.0  # u8Fixed8Number
            return CURVE_SAMPLES ** gamma, f"gamma {_shown(gamma)}"
        if count > 1 and len(tag) >= 12 + 2 * count:
            table = np.frombuffer(tag, ">u2", count, 12).astype(np.float64) / 65535.0
            return np.interp(CURVE_SAMPLES, np.linspace(0.0, 1.0, count), table), f"a {count}-point tone curve"
        return None
    if kind == b"para" and len(tag) >= 12:
        (function,) = struct.unpack_from(">H", tag, 8)
        count = PARAMETER_COUNTS.get(function)
        if count is None or len(tag) < 12 + 4 * count:
            return None
        parameters = [value / 65536.0 for value in struct.unpack_from(f">{count}i", tag, 12)]  # s15Fixed16Number
        return _parametric(function, parameters), f"gamma {_shown(parameters[0])}" + (", piecewise" if function else "")
    return None


def _shown(gamma: float) -> str:
    """A gamma to three digits (2.19921875, Adobe RGB's u8Fixed8 2.2, as 2.2), to four where three would read 1
    for a curve that is not the identity."""
    shown = f"{gamma:.3g}"
    return f"{gamma:.4g}" if shown == "1" and gamma != 1.0 else shown


def _parametric(function: int, parameters: list[float]) -> np.ndarray:
    """parametricCurveType's function (ICC.1:2010 table 65) at CURVE_SAMPLES."""
    x = CURVE_SAMPLES
    g, a, b, c, d, e, f = parameters + [0.0] * (7 - len(parameters))  # those a function lacks go unused
    with np.errstate(invalid="ignore", divide="ignore"):
        power = np.power(np.clip(a * x + b, 0.0, None), g)
        start = -b / a if a else -np.inf  # functions 1 and 2: the power applies from x = -b / a
        if function == 0:
            return x ** g
        if function == 1:
            return np.where(x >= start, power, 0.0)
        if function == 2:
            return np.where(x >= start, power + c, c)
        if function == 3:
            return np.where(x >= d, power, c * x)
        return np.where(x >= d, power + e, c * x + f)
