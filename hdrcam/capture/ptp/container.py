"""PTP USB containers: u32 length, u16 type, u16 code, u32 transaction id, then u32 parameters or a payload.

Little-endian throughout. Commands and responses carry up to 5 parameters, events up to 3; data
containers carry the dataset bytes.
"""

from __future__ import annotations

import dataclasses
import struct

from hdrcam.capture.camera import CameraError
from hdrcam.capture.ptp.codes import ContainerType

HEADER = struct.Struct("<IHHI")
HEADER_SIZE = HEADER.size  # 12 bytes
_MAX_PARAMETERS = {ContainerType.COMMAND: 5, ContainerType.RESPONSE: 5, ContainerType.EVENT: 3}


class ContainerError(CameraError, ValueError):
    """Bytes that are not a valid PTP container (a CameraError: the user sees one line and exit status 1)."""


@dataclasses.dataclass(frozen=True)
class Container:
    kind: ContainerType
    code: int
    transaction_id: int
    params: tuple[int, ...] = ()
    payload: bytes = b""

    def pack(self) -> bytes:
        if self.kind == ContainerType.DATA:
            body = bytes(self.payload)
        else:
            if len(self.params) > _MAX_PARAMETERS[self.kind]:
                raise ContainerError(f"a {self.kind.name.lower()} has at most {_MAX_PARAMETERS[self.kind]} parameters")
            body = struct.pack(f"<{len(self.params)}I", *self.params)
        return HEADER.pack(HEADER_SIZE + len(body), self.kind, self.code, self.transaction_id) + body

    @classmethod
    def unpack(cls, data: bytes) -> "Container":
        length, kind, code, transaction_id = parse_header(data)
        if length != len(data):
            raise ContainerError(f"container says {length} bytes, got {len(data)}")
        body = bytes(data[HEADER_SIZE:])
        if kind == ContainerType.DATA:
            return cls(kind, code, transaction_id, (), body)
        if len(body) % 4 or len(body) // 4 > _MAX_PARAMETERS[kind]:
            raise ContainerError(f"a {kind.name.lower()} container cannot carry {len(body)} parameter bytes")
        return cls(kind, code, transaction_id, struct.unpack(f"<{len(body) // 4}I", body))


def parse_header(data: bytes) -> tuple[int, ContainerType, int, int]:
    """(length, type, code, transaction id) of the first 12 bytes."""
    if len(data) < HEADER_SIZE:
        raise ContainerError(f"{len(data)} bytes is shorter than a container header")
    length, kind, code, transaction_id = HEADER.unpack_from(data)
    try:
        kind = ContainerType(kind)
    except ValueError:
        raise ContainerError(f"unknown container type {kind}") from None
    if length < HEADER_SIZE:
        raise ContainerError(f"container length {length} is shorter than its header")
    return length, kind, code, transaction_id


def command(code: int, transaction_id: int, *params: int) -> Container:
    return Container(ContainerType.COMMAND, code, transaction_id, tuple(params))


def data(code: int, transaction_id: int, payload: bytes) -> Container:
    return Container(ContainerType.DATA, code, transaction_id, (), payload)


def response(code: int, transaction_id: int, *params: int) -> Container:
    return Container(ContainerType.RESPONSE, code, transaction_id, tuple(params))


def event(code: int, transaction_id: int, *params: int) -> Container:
    return Container(ContainerType.EVENT, code, transaction_id, tuple(params))
