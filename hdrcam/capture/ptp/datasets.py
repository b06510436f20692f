"""PTP datasets: integers, strings and arrays; DeviceInfo, ObjectInfo and Sony property descriptors.

Every PTP data type is read: integers of 8 to 128 bits (a 128-bit value is two u64 halves, low first), arrays
of any of them (type 0x4000 | element type: a u32 count and the elements; read as tuples) and strings.
A PTP string is a u8 count of UTF-16LE code units including the terminating NUL (0 for the empty
string), then the code units. An array is a u32 count and its elements. Sony's 0x9209 answer is a u64
count of descriptors, then per descriptor: u16 code, u16 data type, u8 get/set, u8 enabled, the factory
default and current values, a u8 form flag and the form (range: min, max, step; enumeration: u16 count and
values; newer bodies follow an enumeration with a second u16-counted list) - libgphoto2's
ptp_unpack_Sony_DPD, which also reads descriptors until the data ends rather than trusting the count.
ObjectInfo's trailing strings may be left out (libgphoto2's ptp_unpack_OI reads them only while data remains).
Damaged datasets raise DatasetError, a CameraError (one line for the user, exit status 1).
"""

from __future__ import annotations

import dataclasses
import struct

from hdrcam.capture.camera import CameraError
from hdrcam.capture.ptp.codes import DataType

_FORMATS = {DataType.INT8: "b", DataType.UINT8: "B", DataType.INT16: "h", DataType.UINT16: "H",
            DataType.INT32: "i", DataType.UINT32: "I", DataType.INT64: "q", DataType.UINT64: "Q"}
FORM_NONE, FORM_RANGE, FORM_ENUMERATION = 0, 1, 2


class DatasetError(CameraError, ValueError):
    """A dataset that ends early or holds an impossible value."""


class Reader:
    def __init__(self, payload: bytes):
        self.payload, self.offset = bytes(payload), 0

    def _take(self, fmt: str):
        size = struct.calcsize("<" + fmt)
        if self.offset + size > len(self.payload):
            raise DatasetError(f"dataset ends at byte {len(self.payload)}, needed {self.offset + size}")
        value = struct.unpack_from("<" + fmt, self.payload, self.offset)[0]
        self.offset += size
        return value

    def value(self, data_type: int):
        if data_type == DataType.STRING:
            return self.string()
        if data_type in (DataType.INT128, DataType.UINT128):
            low, high = self._take("Q"), self._take("Q")
            number = low | high << 64
            return number - (1 << 128) if data_type == DataType.INT128 and high >> 63 else number
        if data_type & DataType.ARRAY and data_type != DataType.STRING:
            element = data_type & ~DataType.ARRAY
            if element not in _FORMATS and element not in (DataType.INT128, DataType.UINT128):
                raise DatasetError(f"unknown PTP data type 0x{data_type:04X}")
            count = self.u32()
            if count > len(self.payload):
                raise DatasetError(f"an array of {count} elements is longer than the dataset")
            return tuple(self.value(element) for _ in range(count))
        if data_type not in _FORMATS:
            raise DatasetError(f"unknown PTP data type 0x{data_type:04X}")
        return self._take(_FORMATS[data_type])

    def u8(self) -> int:
        return self._take("B")

    def u16(self) -> int:
        return self._take("H")

    def u32(self) -> int:
        return self._take("I")

    def u64(self) -> int:
        return self._take("Q")

    def string(self) -> str:
        count = self.u8()
        if count == 0:
            return ""
        end = self.offset + 2 * count
        if end > len(self.payload):
            raise DatasetError("a string runs past the end of the dataset")
        text = self.payload[self.offset:end].decode("utf-16-le")
        self.offset = end
        return text.rstrip("\x00")

    def u16_array(self) -> tuple[int, ...]:
        return tuple(self.u16() for _ in range(self.u32()))

    @property
    def remaining(self) -> int:
        return len(self.payload) - self.offset

    def peek_u16(self) -> int | None:
        """The next u16 without consuming it; None at the end of the data."""
        if self.remaining < 2:
            return None
        return struct.unpack_from("<H", self.payload, self.offset)[0]


class Writer:
    def __init__(self):
        self.parts: list[bytes] = []

    def value(self, data_type: int, value) -> "Writer":
        if data_type == DataType.STRING:
            return self.string(value)
        if data_type in (DataType.INT128, DataType.UINT128):
            number = value % (1 << 128)
            self.parts.append(struct.pack("<QQ", number & (1 << 64) - 1, number >> 64))
            return self
        if data_type & DataType.ARRAY:
            self.u32(len(value))
            for element in value:
                self.value(data_type & ~DataType.ARRAY, element)
            return self
        self.parts.append(struct.pack("<" + _FORMATS[DataType(data_type)], value))
        return self

    def u8(self, value: int) -> "Writer":
        return self.value(DataType.UINT8, value)

    def u16(self, value: int) -> "Writer":
        return self.value(DataType.UINT16, value)

    def u32(self, value: int) -> "Writer":
        return self.value(DataType.UINT32, value)

    def u64(self, value: int) -> "Writer":
        return self.value(DataType.UINT64, value)

    def string(self, text: str) -> "Writer":
        if not text:
            return self.u8(0)
        units = (text + "\x00").encode("utf-16-le")
        if len(units) // 2 > 255:
            raise DatasetError("a PTP string holds at most 254 characters")
        self.parts.append(bytes([len(units) // 2]) + units)
        return self

    def u16_array(self, values) -> "Writer":
        self.u32(len(values))
        for value in values:
            self.u16(value)
        return self

    def bytes(self) -> bytes:
        return b"".join(self.parts)


@dataclasses.dataclass(frozen=True)
class DeviceInfo:
    standard_version: int
    vendor_extension_id: int
    vendor_extension_version: int
    vendor_extension_desc: str
    functional_mode: int
    operations: tuple[int, ...]
    events: tuple[int, ...]
    properties: tuple[int, ...]
    capture_formats: tuple[int, ...]
    image_formats: tuple[int, ...]
    manufacturer: str
    model: str
    device_version: str
    serial_number: str

    def pack(self) -> bytes:
        writer = Writer().u16(self.standard_version).u32(self.vendor_extension_id)
        writer.u16(self.vendor_extension_version).string(self.vendor_extension_desc).u16(self.functional_mode)
        for codes in (self.operations, self.events, self.properties, self.capture_formats, self.image_formats):
            writer.u16_array(codes)
        for text in (self.manufacturer, self.model, self.device_version, self.serial_number):
            writer.string(text)
        return writer.bytes()

    @classmethod
    def unpack(cls, payload: bytes) -> "DeviceInfo":
        """Manufacturer, Model, DeviceVersion and SerialNumber are read while data remains ("" after its end):
        libgphoto2's ptp_unpack_DI takes them as optional."""
        reader = Reader(payload)
        head = (reader.u16(), reader.u32(), reader.u16(), reader.string(), reader.u16())
        arrays = tuple(reader.u16_array() for _ in range(5))
        texts = tuple(reader.string() if reader.remaining else "" for _ in range(4))
        return cls(*head, *arrays, *texts)


@dataclasses.dataclass(frozen=True)
class ObjectInfo:
    storage_id: int
    object_format: int
    protection_status: int
    compressed_size: int
    thumb_format: int
    thumb_compressed_size: int
    thumb_width_px: int
    thumb_height_px: int
    image_width_px: int
    image_height_px: int
    image_bit_depth: int
    parent_object: int
    association_type: int
    association_desc: int
    sequence_number: int
    filename: str
    capture_date: str
    modification_date: str
    keywords: str

    _LAYOUT = "u32 u16 u16 u32 u16 u32 u32 u32 u32 u32 u32 u32 u16 u32 u32".split()

    def pack(self) -> bytes:
        writer = Writer()
        values = dataclasses.astuple(self)
        for kind, value in zip(self._LAYOUT, values):
            getattr(writer, kind)(value)
        for text in values[len(self._LAYOUT):]:
            writer.string(text)
        return writer.bytes()

    @classmethod
    def unpack(cls, payload: bytes) -> "ObjectInfo":
        reader = Reader(payload)
        numbers = [getattr(reader, kind)() for kind in cls._LAYOUT]
        texts = [reader.string() if reader.remaining else "" for _ in range(4)]  # trailing strings are optional
        return cls(*numbers, *texts)


@dataclasses.dataclass(frozen=True)
class PropertyDescriptor:
    """One Sony device property as 0x9209 reports it."""

    code: int
    data_type: int
    get_set: int
    enabled: int
    factory_default: object
    current: object
    form_flag: int = FORM_NONE
    form: tuple = ()  # range: (min, max, step); enumeration: the allowed values
    secondary_form: tuple | None = None  # newer bodies: a second enumeration list after the first

    def pack(self) -> bytes:
        writer = Writer().u16(self.code).u16(self.data_type).u8(self.get_set).u8(self.enabled)
        writer.value(self.data_type, self.factory_default).value(self.data_type, self.current).u8(self.form_flag)
        if self.form_flag == FORM_RANGE:
            for value in self.form:
                writer.value(self.data_type, value)
        elif self.form_flag == FORM_ENUMERATION:
            for values in (self.form,) if self.secondary_form is None else (self.form, self.secondary_form):
                writer.u16(len(values))
                for value in values:
                    writer.value(self.data_type, value)
        return writer.bytes()

    @classmethod
    def read(cls, reader: Reader) -> "PropertyDescriptor":
        code, data_type, get_set, enabled = reader.u16(), reader.u16(), reader.u8(), reader.u8()
        default, current = reader.value(data_type), reader.value(data_type)
        form_flag = reader.u8()
        if form_flag == FORM_RANGE:
            form = tuple(reader.value(data_type) for _ in range(3))
        elif form_flag == FORM_ENUMERATION:
            form = tuple(reader.value(data_type) for _ in range(reader.u16()))
        elif form_flag == FORM_NONE:
            form = ()
        else:
            raise DatasetError(f"property 0x{code:04X} has unknown form flag {form_flag}")
        secondary = None
        following = reader.peek_u16()
        # libgphoto2: a u16 below 0x200 where the next property code (0x5xxx, 0xDxxx) would be is the count of
        # a second enumeration list (newer Sony bodies)
        if form_flag == FORM_ENUMERATION and following is not None and following < 0x200:
            secondary = tuple(reader.value(data_type) for _ in range(reader.u16()))
        return cls(code, data_type, get_set, enabled, default, current, form_flag, form, secondary)


def pack_sony_properties(descriptors) -> bytes:
    """The 0x9209 payload for these descriptors."""
    return Writer().u64(len(descriptors)).bytes() + b"".join(d.pack() for d in descriptors)


def unpack_sony_properties(payload: bytes, notes: list[str] | None = None) -> dict[int, PropertyDescriptor]:
    """Property code -> descriptor from a 0x9209 payload.

    As libgphoto2's ptp_sony_getalldevicepropdesc: the 8-byte count is skipped and descriptors are read
    until the data ends; a descriptor that cannot be read ends the list (the ones before it are kept, and why
    it ended is appended to ``notes``, as is a list shorter than its count) unless none could be read at all."""
    reader = Reader(payload)
    count = reader.u64()
    descriptors = []
    while reader.remaining:
        try:
            descriptors.append(PropertyDescriptor.read(reader))
        except DatasetError as error:
            if not descriptors:
                raise
            if notes is not None:
                notes.append(f"property list read up to 0x{descriptors[-1].code:04X} only: {error}")
            break
    if notes is not None and descriptors and len(descriptors) < count and not notes:
        notes.append(f"property list holds {len(descriptors)} of the {count} descriptors it announces")
    if count and not descriptors:
        raise DatasetError(f"the property list announces {count} descriptors but holds none")
    return {descriptor.code: descriptor for descriptor in descriptors}


def unpack_sony_vendor_codes(payload: bytes) -> tuple[int, tuple[int, ...]]:
    """(protocol version, codes) from a 0x9202 answer, read as libgphoto2's ptp.c ptp_sony_get_vendorpropcodes
    reads it: a u16 version, then a u32-counted list of u16 codes, then a second such list if the data goes on
    past the first. An answer too short for a list gives the version alone (0 when there is none: "No special
    operations sent?"); a list cut short keeps the codes before the cut."""
    reader = Reader(payload)
    if reader.remaining < 2:
        return 0, ()
    version = reader.u16()
    codes: list[int] = []
    for _ in range(2):
        if reader.remaining < 4:
            break
        count = reader.u32()
        for _ in range(min(count, reader.remaining // 2)):
            codes.append(reader.u16())
    return version, tuple(codes)
