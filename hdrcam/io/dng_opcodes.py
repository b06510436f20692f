"""DNG opcode lists that change a frame's radiometry, which LibRaw (as rawpy builds it, without Adobe's DNG SDK)
does not apply: lens-shading corrections that phones and drones write instead of correcting the data.

Adobe DNG spec 1.4, chapter 7: OpcodeList1/2/3 (tags 51008, 51009, 51022) hold a big-endian u32 count, then
per opcode a u32 ID, u32 DNG version, u32 flags, u32 parameter byte count and the parameters. GainMap (ID 9,
OpcodeList2: per-position gains on the raw data after linearisation) and FixVignetteRadial (ID 3, OpcodeList3:
radial gains after demosaicing) multiply the light the pixels recorded; a frame read without them keeps the
lens's vignetting and colour shading.
"""

from __future__ import annotations

import struct

OPCODE_LISTS = {51008: "OpcodeList1", 51009: "OpcodeList2", 51022: "OpcodeList3"}
SHADING_OPCODES = {9: "GainMap", 3: "FixVignetteRadial"}


def shading_opcodes(tags) -> list[str]:
    """'GainMap (OpcodeList2)'-style names of the shading opcodes in a TIFF page's tags (tifffile TiffTags), each
    once; an opcode list that cannot be parsed is skipped."""
    found = []
    for code, list_name in OPCODE_LISTS.items():
        if code in tags:
            found += [f"{SHADING_OPCODES[opcode]} ({list_name})" for opcode in _opcode_ids(bytes(tags[code].value))
                      if opcode in SHADING_OPCODES]
    return list(dict.fromkeys(found))  # phones write a GainMap per Bayer plane: each name once


def _opcode_ids(data: bytes) -> list[int]:
    """The opcode IDs of one opcode list, in order; as many as can be read."""
    if len(data) < 4:
        return []
    count, offset, ids = struct.unpack_from(">I", data)[0], 4, []
    for _ in range(count):
        if offset + 16 > len(data):
            break
        opcode, _version, _flags, size = struct.unpack_from(">IIII", data, offset)
        ids.append(opcode)
        offset += 16 + size
    return ids
