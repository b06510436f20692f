"""The usb client against behaviour libgphoto2 (camlibs/ptp2: usb.c, ptp.c, ptp-pack.c, library.c, config.c)
copes with or documents, beyond what the A7 faults in test_real_a7_behaviour cover. Frames are byte-exact
where the wire is the point."""

from __future__ import annotations

import struct

import pytest

from hdrcam.capture.camera import CameraError
from hdrcam.capture.emulator import Faults
from hdrcam.capture.ptp.codes import DataType, Operation, Property
from hdrcam.capture.ptp.datasets import ObjectInfo, Reader, unpack_sony_properties
from tests.capture.helpers import small_camera


def hex_bytes(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


def emulated(**faults):
    camera, _ = small_camera("sim-usb", faults=Faults(**faults))
    return camera, camera._device.backend.camera


def recording(body) -> list[bytes]:
    """Every bulk-out write the host makes, in order."""
    writes: list[bytes] = []
    original = body.bulk_out

    def bulk_out(chunk: bytes) -> None:
        writes.append(bytes(chunk))
        original(chunk)

    body.bulk_out = bulk_out
    return writes


def test_handshake_frames_are_libgphoto2s_sequence():
    """OpenSession(1) with transaction 0, GetDeviceInfo, 0x9201(1), 0x9201(2), 0x9202(0xC8), 0x9201(3), then the
    priority mode 0xD25A = 1 (INT8) by 0x9205 (library.c fixup_cached_deviceinfo), then 0x9209."""
    camera, body = emulated()
    writes = recording(body)
    with camera:
        assert body.priority_mode == 1
    assert writes[:9] == [hex_bytes(h) for h in (
        "10000000 0100 0210 00000000 01000000",
        "0c000000 0100 0110 01000000",
        "18000000 0100 0192 02000000 01000000 00000000 00000000",
        "18000000 0100 0192 03000000 02000000 00000000 00000000",
        "10000000 0100 0292 04000000 c8000000",
        "18000000 0100 0192 05000000 03000000 00000000 00000000",
        "10000000 0100 0592 06000000 5ad20000",
        "0d000000 0200 0592 06000000 01",
        "0c000000 0100 0992 07000000",
    )]


def test_mf_capture_presses_and_releases_like_camera_sony_capture(tmp_path):
    """0x9207 0xD2C1 = 2, 0xD2C2 = 2, 0xD2C2 = 1, 0xD2C1 = 1, each value a UINT16 data phase."""
    camera, body = emulated()
    with camera:
        writes = recording(body)
        camera.capture(tmp_path, "f")
    presses = [(struct.unpack_from("<I", w, 12)[0], struct.unpack_from("<H", writes[i + 1], 12)[0])
               for i, w in enumerate(writes) if w[6:8] == b"\x07\x92" and w[4:6] == b"\x01\x00"]
    assert presses == [(0xD2C1, 2), (0xD2C2, 2), (0xD2C2, 1), (0xD2C1, 1)]


@pytest.mark.parametrize("fault", [{"coalesce_response": True}, {"max_read_bytes": 512}, {"split_header": True},
                                   {"stale_response_operation": Operation.SONY_GET_ALL_DEVICE_PROP_DATA},
                                   {"malformed_event": True}, {"whole_packet_images": True, "coalesce_response": True}])
def test_transport_quirks_libgphoto2_copes_with_do_not_stop_a_capture(tmp_path, fault):
    camera, body = emulated(**fault)
    with camera:
        frame = camera.capture(tmp_path, "f")
    assert frame.raw.bayer_dn.shape == (48, 64) and body.premature_requests == 0


def test_a_late_response_is_dropped_and_logged():
    camera, body = emulated()
    with camera:
        body.faults.stale_response_operation = Operation.SONY_GET_ALL_DEVICE_PROP_DATA
        camera.refresh()
        assert any("dropped a late response" in line for line in camera.session.log)


def test_focus_found_3_is_focus_found(tmp_path):
    camera, body = emulated(focus_mode=2, focus_found_value=3)
    with camera:
        camera.capture(tmp_path, "f")
    assert body.shots and all(shot["focused"] for shot in body.shots)


def test_0xd215_flag_without_images_is_not_an_image(tmp_path):
    """0xD215 = 0x8000 | images waiting: 0x8000 alone (memory empty) must not make the client ask for 0xFFFFC001."""
    camera, body = emulated(pending_flag_without_images=True, image_quality=0x13)
    with camera:
        for k in range(3):
            camera.capture(tmp_path, f"f{k}")
    assert body.premature_requests == 0 and body.downloads == 6


@pytest.mark.parametrize("image_quality", [0x10, 0x13])
def test_0xd215_flag_alone_as_ready_is_an_image(tmp_path, image_quality):
    """libgphoto2's capture path takes 0xD215 >= 0x8000 as ready: a body that reads 0x8000 (no count) while its
    image waits must still be downloaded, each shot, RAW only or RAW + JPEG."""
    camera, body = emulated(pending_flag_alone_when_ready=True, image_quality=image_quality)
    with camera:
        for k in range(3):
            camera.capture(tmp_path, f"f{k}")
    assert body.premature_requests == 0 and body.downloads == 3 * (1 + (image_quality == 0x13))


def test_multi_frame_noise_reduction_is_refused_before_any_shot():
    camera, body = emulated(iso_multi_frame_nr=True)
    with pytest.raises(CameraError, match="Multi Frame Noise Reduction"):
        with camera:
            pass
    assert body.shots == []


def test_descriptors_with_a_second_enumeration_list_are_read():
    camera, _ = emulated(secondary_enumerations=True)
    with camera:
        properties = camera.properties
        assert properties[Property.SONY_ISO].secondary_form == properties[Property.SONY_ISO].form
        assert properties[Property.SONY_PENDING_IMAGES].current == 0
        assert camera.set_exposure(iso=800).iso == 800


def test_second_enumeration_list_byte_exact():
    iso = hex_bytes("1ed2 0600 01 01 64000000 90010000 02 0200 64000000 90010000 0300 64000000 c8000000 90010000")
    shutter = hex_bytes("0dd2 0600 01 01 00000000 7d000100 00")
    properties = unpack_sony_properties(hex_bytes("02000000 00000000") + iso + shutter)
    assert properties[0xD21E].form == (100, 400) and properties[0xD21E].secondary_form == (100, 200, 400)
    assert properties[0xD20D].current == 0x0001007D


def test_property_list_is_read_to_its_end_not_to_its_count():
    """libgphoto2 ptp_sony_getalldevicepropdesc skips the 8-byte count and reads descriptors until the data ends."""
    shutter = hex_bytes("0dd2 0600 01 01 00000000 7d000100 00")
    focus = hex_bytes("13d2 0200 00 01 01 02 00")
    assert set(unpack_sony_properties(hex_bytes("01000000 00000000") + shutter + focus)) == {0xD20D, 0xD213}


def test_object_info_without_its_trailing_strings():
    info = ObjectInfo(0x10001, 0xB101, 0, 1234, 0, 0, 0, 0, 6000, 4000, 16, 0, 0, 0, 0, "DSC00001.ARW", "", "", "")
    packed = info.pack()
    assert ObjectInfo.unpack(packed[:-3]) == info  # dates and keywords left out


def test_damaged_datasets_are_camera_errors():
    with pytest.raises(CameraError):
        unpack_sony_properties(hex_bytes("01000000 00000000 0dd2"))
    with pytest.raises(CameraError):
        Reader(b"\x01").value(DataType.UINT32)
