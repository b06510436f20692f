"""ICC profiles built byte by byte from ICC.1:2010 (header, tag table, 'curv' and 'para' tone curves), for tests of
what hdrcam reads from them."""

from __future__ import annotations

import struct

import numpy as np

SRGB_PARAMETERS = (2.4, 1 / 1.055, 0.055 / 1.055, 1 / 12.92, 0.04045)  # IEC 61966-2-1 as a type 3 'para' curve


def curv(gamma: float | None = None, table: np.ndarray | None = None) -> bytes:
    """A 'curv' tag: the identity (neither given), one gamma (u8Fixed8Number) or a 16-bit table over [0, 1]."""
    if table is not None:
        values = np.round(np.asarray(table) * 65535).astype(">u2")
        return b"curv" + bytes(4) + struct.pack(">I", len(values)) + values.tobytes()
    if gamma is None:
        return b"curv" + bytes(4) + struct.pack(">I", 0)
    return b"curv" + bytes(4) + struct.pack(">IH", 1, round(gamma * 256)) + bytes(2)


def para(function: int, *parameters: float) -> bytes:
    """A 'para' tag: function type and its parameters as s15Fixed16Number."""
    return b"para" + bytes(4) + struct.pack(">HH", function, 0) + b"".join(
        struct.pack(">i", round(value * 65536)) for value in parameters)


def profile(tags: dict[bytes, bytes]) -> bytes:
    """A display-class RGB profile holding ``tags`` (signature -> tag data), each 4-byte aligned."""
    table_bytes = 4 + 12 * len(tags)
    offset, entries, data = 128 + table_bytes, b"", b""
    for signature, tag in tags.items():
        entries += struct.pack(">4sII", signature, offset + len(data), len(tag))
        data += tag + bytes(-len(tag) % 4)
    size = 128 + table_bytes + len(data)
    header = struct.pack(">I4sI4s4s4s", size, b"none", 0x04300000, b"mntr", b"RGB ", b"XYZ ") + bytes(12) + \
        b"acsp" + bytes(128 - 40)
    return header + struct.pack(">I", len(tags)) + entries + data


def rgb_curves(red: bytes, green: bytes | None = None, blue: bytes | None = None) -> bytes:
    """A profile whose rTRC, gTRC and bTRC are the given tags (green and blue default to red's)."""
    return profile({b"rTRC": red, b"gTRC": green or red, b"bTRC": blue or red})
