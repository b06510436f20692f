"""Sony bodies newer than the A7 that set shutter and ISO absolutely, as libgphoto2 handles them (config.c
have_prop on ShutterSpeed2 0xD229 / ISO2 0xD226 from the 0x9202 code list, _put_Sony_ShutterSpeed "new style",
_put_Sony_ISO2: one 0x9205 SetControlDeviceA with a UINT32, no stepping and no fallback). The emulated body is
Faults.absolute_exposure; the A7 (neither code listed) is stepped as before. Frames are byte-exact."""

from __future__ import annotations

import struct

import pytest

from hdrcam.capture.camera import CameraError
from hdrcam.capture.ptp.codes import Operation, Property
from hdrcam.capture.ptp.datasets import unpack_sony_vendor_codes
from tests.capture.helpers import emulated_a7 as emulated
from tests.capture.test_libgphoto2_conformance import hex_bytes, recording


def _commands(writes: list[bytes], operation: int) -> list[int]:
    """The indexes of the command containers of ``operation`` among ``writes``."""
    return [i for i, w in enumerate(writes) if w[4:6] == b"\x01\x00" and struct.unpack_from("<H", w, 6)[0] == operation]


def _tid(frame: bytes) -> str:
    return frame[8:12].hex()


def test_vendor_code_lists_are_read_as_ptp_sony_get_vendorpropcodes():
    """u16 version, a u32-counted u16 list, a second list when the data goes on; a cut list keeps what it holds."""
    answer = struct.pack("<HI2HI3H", 0x12C, 2, 0x9201, 0xC201, 3, 0xD20D, 0xD229, 0xD226)
    assert unpack_sony_vendor_codes(answer) == (0x12C, (0x9201, 0xC201, 0xD20D, 0xD229, 0xD226))
    assert unpack_sony_vendor_codes(answer[:-2]) == (0x12C, (0x9201, 0xC201, 0xD20D, 0xD229))
    assert unpack_sony_vendor_codes(b"") == (0, ())


def test_newer_body_sets_shutter_and_iso_with_one_9205_each():
    """A body listing 0xD229 and 0xD226 in its 0x9202 answer (protocol 0x12C) gets 0x9205 on 0xD229 with the UINT32
    (1 << 16) | 125 and 0x9205 on 0xD226 with 400, no 0x9207 step, and reads back the values set."""
    camera, body = emulated(absolute_exposure=True, sdio_protocol_version=0x12C)
    with camera:
        assert camera.protocol_version == 0x12C
        assert {Property.SONY_SHUTTER_SPEED_2, Property.SONY_ISO_2} <= camera.vendor_properties
        writes = recording(body)
        settings = camera.set_exposure(1 / 125, 400)
    assert (settings.exposure_label, settings.iso) == ("1/125", 400.0)
    assert body.absolute_sets == [(0xD229, 0x0001007D), (0xD226, 400)]
    assert _commands(writes, Operation.SONY_SET_CONTROL_DEVICE_B) == []
    sets = _commands(writes, Operation.SONY_SET_CONTROL_DEVICE_A)
    assert len(sets) == 2
    frames = [writes[i + k] for i in sets for k in (0, 1)]
    assert frames == [hex_bytes(h) for h in (
        f"10000000 0100 0592 {_tid(frames[0])} 29d20000",
        f"10000000 0200 0592 {_tid(frames[0])} 7d000100",
        f"10000000 0100 0592 {_tid(frames[2])} 26d20000",
        f"10000000 0200 0592 {_tid(frames[2])} 90010000",
    )]


def test_newer_body_long_time_is_sent_as_the_listed_tenths():
    """30 s goes out as 0xD229's enumeration lists it: 300/10 (0x012C000A), as config.c notes Sony reports it."""
    camera, body = emulated(absolute_exposure=True)
    with camera:
        settings = camera.set_exposure(30.0)
    assert settings.exposure_label == '30"'
    assert body.absolute_sets == [(0xD229, 0x012C000A)]


def test_newer_body_at_the_target_already_gets_no_write():
    camera, body = emulated(absolute_exposure=True)
    with camera:
        start = camera.settings()
        camera.set_exposure(start.exposure_s, start.iso)
    assert body.absolute_sets == []


def test_refused_absolute_set_is_an_error_and_is_not_stepped():
    """libgphoto2 returns the 0x9205 error (translate_ptp_result) and does not fall back to 0x9207 steps."""
    camera, body = emulated(absolute_exposure=True, absolute_set_refused=True)
    with camera:
        writes = recording(body)
        with pytest.raises(CameraError, match=r"refused shutter 1/125 \(0x9205 on 0xD229"):
            camera.set_exposure(1 / 125)
    assert _commands(writes, Operation.SONY_SET_CONTROL_DEVICE_B) == []


def test_ignored_absolute_set_is_an_error_once_the_wait_runs_out():
    camera, body = emulated(absolute_exposure=True, absolute_set_ignored=True)
    with camera:
        with pytest.raises(CameraError, match=r"ISO 800 was taken .* still reads ISO 100"):
            camera.set_exposure(iso=800)
    assert body.absolute_sets == [(0xD226, 800)]


def test_newer_body_refuses_a_time_its_enumeration_lacks_before_any_write():
    camera, body = emulated(absolute_exposure=True, iso_max=3200)
    with camera:
        with pytest.raises(CameraError, match="ISO 6400 is not offered"):
            camera.set_exposure(iso=6400)
    assert body.absolute_sets == []


def test_a7_lists_neither_code_and_is_stepped_as_before():
    camera, body = emulated()
    with camera:
        assert not {Property.SONY_SHUTTER_SPEED_2, Property.SONY_ISO_2} & camera.vendor_properties
        writes = recording(body)
        assert camera.set_exposure(1 / 125).exposure_label == "1/125"
    assert _commands(writes, Operation.SONY_SET_CONTROL_DEVICE_A) == [] and body.absolute_sets == []
    assert _commands(writes, Operation.SONY_SET_CONTROL_DEVICE_B)
