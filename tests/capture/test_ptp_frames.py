"""PTP bytes on the wire, checked byte for byte.

No USB capture of an A7 ships with this repository, so the expected frames are written out by hand from
the container and dataset layouts in REFERENCE.md sec. 4 (PIMA 15740 USB transport; libgphoto2's Sony
descriptor layout): little-endian u32 length, u16 type, u16 code, u32 transaction id, u32 parameters.
"""

from __future__ import annotations

import pytest

from hdrcam.capture.notches import ISO_AUTO, SHUTTER_NOTCHES, shutter_from_ptp
from hdrcam.capture.ptp.codes import ContainerType, DataType, Operation, Property
from hdrcam.capture.ptp.container import Container, ContainerError, command, data, event, response
from hdrcam.capture.ptp.datasets import (FORM_ENUMERATION, DeviceInfo, ObjectInfo, PropertyDescriptor, Reader,
                                         Writer, pack_sony_properties, unpack_sony_properties)


def hex_bytes(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


@pytest.mark.parametrize("container, wire", [
    (command(Operation.OPEN_SESSION, 0, 1), "10000000 0100 0210 00000000 01000000"),
    (command(Operation.GET_DEVICE_INFO, 1), "0c000000 0100 0110 01000000"),
    (command(Operation.SONY_SDIO_CONNECT, 2, 1, 0, 0), "18000000 0100 0192 02000000 01000000 00000000 00000000"),
    (command(Operation.SONY_GET_SDIO_EXT_DEVICE_INFO, 4, 0xC8), "10000000 0100 0292 04000000 c8000000"),
    (command(Operation.SONY_SET_CONTROL_DEVICE_B, 7, Property.SONY_SHUTTER_SPEED),
     "10000000 0100 0792 07000000 0dd20000"),
    (data(Operation.SONY_SET_CONTROL_DEVICE_B, 7, b"\x01"), "0d000000 0200 0792 07000000 01"),
    (data(Operation.SONY_SET_CONTROL_DEVICE_B, 8, b"\xff"), "0d000000 0200 0792 08000000 ff"),
    (command(Operation.SONY_SET_CONTROL_DEVICE_B, 9, Property.SONY_FULL_PRESS), "10000000 0100 0792 09000000 c2d20000"),
    (data(Operation.SONY_SET_CONTROL_DEVICE_B, 9, b"\x02\x00"), "0e000000 0200 0792 09000000 0200"),
    (command(Operation.GET_OBJECT, 12, 0xFFFFC001), "10000000 0100 0910 0c000000 01c0ffff"),
    (response(0x2001, 12), "0c000000 0300 0120 0c000000"),
    (response(0x2019, 3), "0c000000 0300 1920 03000000"),
    (event(0xC201, 0, 0xFFFFC001), "10000000 0400 01c2 00000000 01c0ffff"),
])
def test_containers_pack_and_unpack_byte_exact(container, wire):
    assert container.pack() == hex_bytes(wire)
    assert Container.unpack(hex_bytes(wire)) == container


@pytest.mark.parametrize("wire", ["0c000000 0300 0120", "0d000000 0300 0120 0c000000",
                                  "0c000000 0900 0120 0c000000", "10000000 0300 0120 0c000000 01"])
def test_malformed_containers_are_refused(wire):
    with pytest.raises(ContainerError):
        Container.unpack(hex_bytes(wire))


def test_too_many_parameters_are_refused():
    with pytest.raises(ContainerError):
        Container(ContainerType.EVENT, 0x4002, 0, (1, 2, 3, 4)).pack()


def test_shutter_and_iso_encodings():
    by_label = {notch.label: notch for notch in SHUTTER_NOTCHES}
    assert by_label["1/125"].ptp_value == 0x0001007D
    assert by_label["1/8000"].ptp_value == 0x00011F40
    assert by_label['30"'].ptp_value == 0x012C000A and by_label['0.8"'].ptp_value == 0x0008000A
    assert shutter_from_ptp(0x0001007D).true_s == 2.0 ** -7  # 1/125 is really 1/128
    with pytest.raises(ValueError, match="Bulb"):
        shutter_from_ptp(0)
    assert shutter_from_ptp((30 << 16) | 1) == by_label['30"']  # 30/1 and 300/10 are the same 30 s
    assert ISO_AUTO == 0xFFFFFF


def test_ptp_strings_are_counted_utf16_with_nul():
    assert Writer().string("A7").bytes() == hex_bytes("03 4100 3700 0000")
    assert Writer().string("").bytes() == b"\x00"
    assert Reader(hex_bytes("03 4100 3700 0000")).string() == "A7"


def test_sony_property_descriptor_layout():
    shutter = PropertyDescriptor(Property.SONY_SHUTTER_SPEED, DataType.UINT32, 1, 1, 0, 0x0001007D)
    assert shutter.pack() == hex_bytes("0dd2 0600 01 01 00000000 7d000100 00")
    iso = PropertyDescriptor(Property.SONY_ISO, DataType.UINT32, 1, 1, 100, 400, FORM_ENUMERATION, (100, 200))
    assert iso.pack() == hex_bytes("1ed2 0600 01 01 64000000 90010000 02 0200 64000000 c8000000")
    payload = pack_sony_properties([shutter, iso])
    assert payload[:8] == hex_bytes("02000000 00000000")
    assert unpack_sony_properties(payload) == {shutter.code: shutter, iso.code: iso}


def test_device_and_object_info_round_trip():
    info = DeviceInfo(100, 0x11, 100, "Sony PTP Extensions", 0, (0x1001, 0x9209), (0xC201,), (0xD20D,), (0xB101,),
                      (0xB101,), "Sony Corporation", "ILCE-7", "1.00", "0001")
    assert DeviceInfo.unpack(info.pack()) == info
    assert info.pack()[:6] == hex_bytes("6400 11000000")
    obj = ObjectInfo(0x10001, 0xB101, 0, 123456, 0, 0, 0, 0, 6000, 4000, 16, 0, 0, 0, 0, "DSC00001.ARW", "", "", "")
    packed = obj.pack()
    assert packed[8:12] == (123456).to_bytes(4, "little") and packed[52] == 13  # size at 8, filename at 52
    assert ObjectInfo.unpack(packed) == obj
