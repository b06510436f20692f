"""The usb client against behaviour libgphoto2 (camlibs/ptp2: usb.c, ptp.c, ptp-pack.c, library.c, config.c)
copes with or documents, beyond what the A7 faults in test_real_a7_behaviour cover. Frames are byte-exact
where the wire is the point."""

from __future__ import annotations

import dataclasses
import struct

import pytest

from hdrcam.capture.camera import CameraError
from hdrcam.capture.emulator import Latencies
from hdrcam.capture.ptp.codes import STARTUP_WAIT_S, DataType, Operation, Property
from hdrcam.capture.ptp.container import HEADER_SIZE, data, response
from hdrcam.capture.ptp.datasets import ObjectInfo, PropertyDescriptor, Reader, unpack_sony_properties
from hdrcam.capture.ptp.transport import UsbTransport
from tests.capture.helpers import emulated_a7 as emulated


def hex_bytes(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


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
                                   {"malformed_event": True}, {"whole_packet_images": True, "coalesce_response": True},
                                   {"unknown_length_objects": True},
                                   {"unknown_length_objects": True, "whole_packet_images": True},
                                   {"unknown_length_objects": True, "max_read_bytes": 512},
                                   {"unknown_length_objects": True, "split_header": True}])
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


def test_a_body_announcing_images_only_by_object_added_is_downloaded_when_the_wait_runs_out(tmp_path):
    """library.c camera_sony_capture ends its wait on ObjectAdded ("needed on older cameras like the a58"); a body
    leaving 0xD215 at 0 timed out with its image in memory. 0xFFFFC001 is asked for once the wait runs out."""
    camera, body = emulated(pending_images_unreported=True)
    with camera:
        frame = camera.capture(tmp_path, "f")
    assert frame.raw.bayer_dn.shape == (48, 64) and body.premature_requests == 0 and body.downloads == 1


def test_multi_frame_noise_reduction_is_refused_before_any_shot():
    camera, body = emulated(iso_multi_frame_nr=True)
    with pytest.raises(CameraError, match="Multi Frame Noise Reduction"):
        with camera:
            pass
    assert body.shots == []


def test_image_quality_0_is_read_as_its_factory_default(tmp_path):
    """library.c camera_sony_capture: a 0x5004 current value 0 stands for the descriptor's FactoryDefaultValue
    (0x10, RAW, on the emulated body); it was refused as JPEG only. A JPEG factory default is still refused."""
    camera, body = emulated(image_quality=0)
    with camera:
        frame = camera.capture(tmp_path, "f")
    assert frame.path.suffix == ".dng" and len(body.shots) == 1
    camera, body = emulated(image_quality=0)
    descriptors = body._descriptors
    body._descriptors = lambda: [dataclasses.replace(d, factory_default=0x03) if d.code == Property.IMAGE_QUALITY
                                 else d for d in descriptors()]
    with pytest.raises(CameraError, match=r"JPEG only \(quality 0x03\)"):
        with camera:
            pass


def test_descriptors_with_a_second_enumeration_list_are_read():
    camera, _ = emulated(secondary_enumerations=True)
    with camera:
        properties = camera.properties
        assert properties[Property.SONY_ISO].secondary_form == properties[Property.SONY_ISO].form
        assert properties[Property.SONY_PENDING_IMAGES].current == 0
        assert camera.set_exposure(iso=800).iso == 800


def test_an_iso_the_body_does_not_list_is_refused_before_any_step():
    """config.c _put_sony_value_u32 (useenumorder): a target missing from the descriptor's enumeration is refused
    before stepping ("Target value is not in enumeration."); hdrcam stepped up to 12800 and blamed the mode dial."""
    camera, body = emulated(iso_max=12800)
    with camera:
        with pytest.raises(CameraError, match=r"^ISO 25600 is not offered by this body \(the nearest it offers: "
                                              r"ISO 12800\)$"):
            camera.set_exposure(iso=25600)
        assert camera.settings().iso == 100 and body._step_count == 0
        assert camera.set_exposure(iso=12800).iso == 12800


def test_a_step_that_changes_nothing_at_the_end_of_the_bodys_list_says_the_value_is_not_offered():
    """A body listing ISOs it cannot set (config.c: Sony "seems to report values in an enum that are not actually
    supported") steps no higher than 12800: after steps that landed, that is no mode dial off M."""
    camera, _ = emulated(iso_max=12800, iso_listed_beyond_max=True)
    with camera:
        with pytest.raises(CameraError, match="^ISO 25600 is not offered by this body: it steps no further than "
                                              "ISO 12800$"):
            camera.set_exposure(iso=25600)


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


@pytest.mark.parametrize("strings, model", [(3, "Sony Corporation ILCE-7"), (0, "Sony camera")])
def test_device_info_without_its_trailing_strings(strings, model):
    """ptp-pack.c ptp_unpack_DI reads Manufacturer, Model, DeviceVersion and SerialNumber only while data remains
    (they are optional); a body leaving them out failed the handshake with 'dataset ends at byte ...'."""
    camera, body = emulated(device_info_strings=strings)
    with camera:
        assert camera.model == model and camera.firmware == ("3.20" if strings >= 3 else "")
    assert body.shots == []


def test_damaged_datasets_are_camera_errors():
    with pytest.raises(CameraError):
        unpack_sony_properties(hex_bytes("01000000 00000000 0dd2"))
    with pytest.raises(CameraError):
        Reader(b"\x01").value(DataType.UINT32)


class _ScriptedBulkIn:
    """A bulk-in endpoint that returns whole packets of queued transfers, a short packet ending each."""

    wMaxPacketSize = 512

    def __init__(self, transfers):
        self.transfers = [bytearray(transfer) for transfer in transfers]

    def read(self, size, timeout_ms):
        transfer = self.transfers[0]
        count = len(transfer) if len(transfer) <= size else size - size % self.wMaxPacketSize
        chunk = bytes(transfer[:count])
        del transfer[:count]
        if not transfer:
            self.transfers.pop(0)
        return chunk


def test_a_container_shorter_than_its_length_field_is_reported_at_once():
    """A data container 4 bytes short ends in a short packet: one line naming the sizes, not a read that runs
    on into the response and times out (3 x 20 s for a read-only operation)."""
    transport = object.__new__(UsbTransport)
    transport.bulk_in, transport._pending = _ScriptedBulkIn([data(0x1008, 5, bytes(1000)).pack()[:-4],
                                                             response(0x2001, 5).pack()]), b""
    with pytest.raises(CameraError, match="1008 bytes of a 1012-byte container"):
        transport.receive(1000)


def test_a_container_cut_short_after_a_12_byte_packet_is_reported_too():
    """Only a read of the header alone (the buffer exactly 12 bytes) may be followed by more of the container."""
    transport = object.__new__(UsbTransport)
    packed = data(0x1009, 6, bytes(1000)).pack()
    transport.bulk_in, transport._pending = _ScriptedBulkIn([packed[:524], response(0x2001, 6).pack()]), b""
    with pytest.raises(CameraError, match="524 bytes of a 1012-byte container"):
        transport.receive(1000)


def test_a_body_that_never_answers_the_priority_mode_still_completes_the_handshake():
    """libgphoto2 ignores every error of this call (LOG_ON_PTP_E): a timeout included."""
    camera, _ = emulated(silent_operation=Operation.SONY_SET_CONTROL_DEVICE_A)
    with camera:
        assert any("priority mode not set" in line for line in camera.session.log)


def test_a_list_shorter_than_its_count_says_so():
    good = PropertyDescriptor(Property.SONY_SHUTTER_SPEED, DataType.UINT32, 1, 1, 0, 0x0001007D)
    notes: list[str] = []
    unpack_sony_properties(struct.pack("<Q", 30) + good.pack(), notes)
    assert notes == ["property list holds 1 of the 30 descriptors it announces"]


def test_why_a_list_ended_early_is_logged_once_and_only_cited_while_it_holds():
    camera, body = emulated()
    answer = body._op_9209
    damaged = {"on": True}

    def op_9209(request, payload):
        data_, code = answer(request, payload)
        return (data_ + struct.pack("<HHBB", 0xD2FF, 0x7777, 1, 1) if damaged["on"] else data_), code

    body._op_9209 = op_9209
    with camera:
        for _ in range(3):
            camera.refresh()
        assert sum("property list read up to" in line for line in camera.session.log) == 1
        damaged["on"] = False
        camera.refresh()
        with pytest.raises(CameraError) as missing:
            camera._current(0xD2FE)
        assert "read up to" not in str(missing.value)


def test_a_property_missing_from_a_list_read_while_stepping_is_a_camera_error():
    """unpack_sony_properties keeps the descriptors before one it cannot read; the property being stepped may be
    among those left out, which raised a bare KeyError."""
    camera, body = emulated()
    with camera:
        descriptors = body._descriptors
        body._descriptors = lambda: [d for d in descriptors() if d.code != Property.SONY_SHUTTER_SPEED]
        with pytest.raises(CameraError, match="does not report property 0xD20D"):
            camera.set_exposure(exposure_s=1 / 125)


def test_a_damaged_descriptor_ends_the_list_and_says_why():
    good = PropertyDescriptor(Property.SONY_SHUTTER_SPEED, DataType.UINT32, 1, 1, 0, 0x0001007D)
    later = PropertyDescriptor(Property.EXPOSURE_PROGRAM_MODE, DataType.UINT16, 0, 1, 1, 1)
    notes: list[str] = []
    properties = unpack_sony_properties(struct.pack("<Q", 3) + good.pack() + struct.pack("<HHBB", 0xD2FF, 0x7777, 1, 1)
                                        + later.pack(), notes)
    assert set(properties) == {Property.SONY_SHUTTER_SPEED} and "0x7777" in notes[0]


@pytest.mark.parametrize("shots_before", [1, 0])
def test_raw_put_in_memory_after_the_jpeg_left_is_not_asked_for_early(tmp_path, shots_before):
    """RAW + JPEG on a body where 0xD215 = 0x8000 alone means memory empty: after the JPEG's download the RAW
    appears 0.5 s later; the wait for the RAW must not take 0x8000 as ready (asking 0xFFFFC001 early is the access
    libgphoto2 says can crash the firmware) - neither with 0x8000 read before the release nor on the session's
    first shot (0 before the release), where the JPEG announced with a count (0x8002) tells how 0x8000 reads."""
    camera, body = emulated(pending_flag_without_images=True, image_quality=0x13)
    read_bulk, advance, held = body.bulk_in, body._advance, {}

    def bulk_in(buffer):
        count = read_bulk(buffer)
        if body._image is not None and body.downloads % 2 == 1 and not held:  # the JPEG just left
            held.update(raw=(body._image, body._image_format, body._image_name), due=body.clock.monotonic() + 0.5)
            body._image = None
        return count

    def delayed_advance():
        advance()
        if "raw" in held and body.clock.monotonic() >= held["due"]:
            body._image, body._image_format, body._image_name = held.pop("raw")

    with camera:
        for k in range(shots_before):
            camera.capture(tmp_path, f"f{k}")  # 0xD215 reads 0x8000 from now on when memory is empty
        body.bulk_in, body._advance = bulk_in, delayed_advance
        camera.capture(tmp_path, "f")
    assert body.premature_requests == 0 and body.downloads == 2 * (shots_before + 1)


def test_a_body_that_needs_its_startup_time_gets_it_before_the_first_press(tmp_path):
    """library.c camera_sony_capture: the ILCE-7RM4 (and ZV-E10, ZV-1, RX100 VII, RX0 II, A7C) ignores a press in
    its first 2.5 s; libgphoto2 waits that out. Pressing at once lost the shot and then waited 35 s for it."""
    camera, body = emulated(model="ILCE-7RM4")
    with camera:
        frame = camera.capture(tmp_path, "f")
        assert body.clock.monotonic() - body.opened_at >= STARTUP_WAIT_S
    assert body.ignored_presses == 0 and len(body.shots) == 1 and frame.path.is_file()


def test_a_body_without_a_startup_time_is_pressed_at_once(tmp_path):
    """Only the models libgphoto2 names wait: an ILCE-7 shoots well inside 2.5 s of the session opening."""
    camera, body = emulated()
    with camera:
        opened = body.opened_at
        camera.capture(tmp_path, "f")
        assert body.shots and body.clock.monotonic() - opened < STARTUP_WAIT_S


def test_open_session_tries_the_next_ids_when_the_body_still_holds_one(tmp_path):
    """library.c camera_init: OpenSession answered InvalidTransactionID is asked again with session ids 2, 3, ...
    (up to 10), then after a device reset; the run ended at the first refusal."""
    camera, body = emulated(session_ids_in_use=2)
    with camera:
        assert camera.session.session_id == 3
        assert any("trying session id 3" in line for line in camera.session.log)
        camera.capture(tmp_path, "f")
    assert len(body.shots) == 1


def test_a_body_that_refuses_every_session_id_is_an_error_after_a_reset():
    camera, body = emulated(session_ids_in_use=99)
    with pytest.raises(CameraError, match="INVALID_TRANSACTION_ID"):
        with camera:
            pass
    assert body.session_open is False


@pytest.mark.parametrize("value, name", [(0x8004, "AF-C"), (0x8005, "AF-A"), (0x8006, "DMF"), (2, "AF-S"),
                                         (1, "MF")])
def test_focus_modes_are_named_as_libgphoto2_names_them(value, name):
    """config.c focusmodes[]: Sony's 0x8005 is AF-A and 0x8006 DMF (hdrcam named them DMF and AF-D, so a body on
    AF-A was warned about and recorded as DMF)."""
    from hdrcam.capture.ptp.codes import FOCUS_MODE_NAMES

    assert FOCUS_MODE_NAMES[value] == name


def test_a_body_that_splits_its_headers_gets_the_hosts_data_phases_split_too(tmp_path):
    """usb.c ptp_usb_getdata sets split_header_data when a data container's first read is its 12-byte header alone;
    ptp_usb_senddata then writes every data phase as that header alone, then the payload. A body that needs it
    (Faults.split_header_out) never read hdrcam's header-with-payload writes: no priority mode, no step, no press."""
    camera, body = emulated(split_header=True, split_header_out=True)
    writes = recording(body)
    with camera:
        assert body.priority_mode == 1
        camera.capture(tmp_path, "f")
    assert writes[6:9] == [hex_bytes(h) for h in (
        "10000000 0100 0592 06000000 5ad20000", "0d000000 0200 0592 06000000", "01")]
    assert body.downloads == 1 and body.premature_requests == 0


def test_a_body_sending_whole_containers_gets_whole_data_phases(tmp_path):
    """Without a split header from the body, a data phase stays one transfer (ptp_usb_senddata's default)."""
    camera, body = emulated()
    writes = recording(body)
    with camera:
        pass
    assert writes[7] == hex_bytes("0d000000 0200 0592 06000000 01")


@pytest.mark.parametrize("payload_bytes, zlp", [(1, False), (512, True), (1024, True), (500, False)])
def test_a_split_data_phase_ends_with_a_zlp_when_its_payload_is_whole_packets(payload_bytes, zlp):
    """ptp_usb_senddata, split: the header alone (a short packet ends it), then the payload, then a ZLP when the
    payload is a multiple of wMaxPacketSize (``written`` counts the payload only)."""
    camera, body = emulated(split_header=True)
    with camera:
        writes = recording(body)
        assert camera.session.transport.split_header_data
        camera.session.transport.send(data(Operation.SONY_SET_CONTROL_DEVICE_B, 99, bytes(payload_bytes)), 1000)
        sent = writes[:]
    header = struct.pack("<IHHI", HEADER_SIZE + payload_bytes, 2, Operation.SONY_SET_CONTROL_DEVICE_B, 99)
    assert sent == [header, bytes(payload_bytes)] + ([b""] if zlp else [])


def test_an_event_split_over_two_interrupt_transfers_is_read_whole():
    """usb.c ptp_usb_event: while an event container is longer than what was read, it reads on (the "incremental
    read"); the whole ObjectAdded comes back, and the pipe is left at the next event."""
    camera, body = emulated(split_events=True)
    with camera:
        body._queue_event(struct.pack("<IHHII", 16, 4, 0xC201, 0, 0xFFFFC001))
        body._queue_event(struct.pack("<IHHII", 16, 4, 0xC203, 0, 0xD20D))
        first, second = camera.session.transport.read_event(100), camera.session.transport.read_event(100)
    assert (first.code, first.params) == (0xC201, (0xFFFFC001,))
    assert (second.code, second.params) == (0xC203, (0xD20D,))


def test_a_body_announcing_images_by_split_object_added_events_is_downloaded(tmp_path):
    """An a58-style body (0xD215 stays 0, ObjectAdded alone says the image is there) whose events come in two
    interrupt transfers: the ObjectAdded must still be seen, or the shot is lost after the 35 s wait."""
    camera, body = emulated(pending_images_unreported=True, split_events=True)
    with camera:
        frame = camera.capture(tmp_path, "f")
    assert frame.raw.bayer_dn.shape == (48, 64) and body.premature_requests == 0 and body.downloads == 1


def test_a_body_announcing_images_only_by_object_added_is_not_waited_on_for_35_s(tmp_path):
    """camera_sony_capture ends its wait at the ObjectAdded; an a58-style body whose 0xD215 stays 0 took 35 s a
    frame (the whole timeout) before 0xFFFFC001 was asked for. Asked for once 0xD215 stayed 0 for 1 s after it."""
    camera, body = emulated(pending_images_unreported=True)
    with camera:
        started = body.clock.monotonic()
        camera.capture(tmp_path, "f")
        took_s = body.clock.monotonic() - started
    assert took_s < 5.0 and body.premature_requests == 0 and body.downloads == 1


def test_an_object_added_with_0xd215_counting_is_not_taken_for_an_unreported_image(tmp_path):
    """A body that counts its image in 0xD215 while writing (no flag: "also turns to 1") and sends ObjectAdded
    early is still waited on until 0xD215 says ready, however long the writing takes."""
    camera, body = emulated(Latencies(image_ready_s=6.0), early_object_added=True)
    with camera:
        camera.capture(tmp_path, "f")
    assert body.premature_requests == 0 and body.downloads == 1


def test_a_body_not_in_pc_remote_mode_is_told_so_before_any_sony_operation():
    """library.c fixup_cached_deviceinfo runs the SDIO handshake only when DeviceInfo lists 0x9202
    (GetSDIOGetExtDeviceInfo); a body that lists none of Sony's operations is not in PC Remote mode: one line that
    says what to do, and no 0x92xx command sent to it."""
    camera, body = emulated(not_pc_remote=True)
    writes = recording(body)
    with pytest.raises(CameraError, match="PC Remote"):
        camera.__enter__()
    assert not any(w[4:6] == b"\x01\x00" and w[7] == 0x92 for w in writes)


@pytest.mark.parametrize("jump, notches", [(b"\x03", 3), (b"\xfe", -2), (b"\x01", 1)])
def test_the_emulated_body_takes_libgphoto2s_multi_notch_jumps(jump, notches):
    """config.c _put_Sony_ShutterSpeed and _put_sony_value_* send a jump width (u8 posnew - posorig, 0x100 - n
    downwards) as their first step; a body that behaves as libgphoto2 expects moves that many notches."""
    camera, body = emulated()
    with camera:
        before = body.camera.notch.index
        camera.session.transact(Operation.SONY_SET_CONTROL_DEVICE_B, Property.SONY_SHUTTER_SPEED, data_out=jump)
        body.clock.sleep(body.latencies.step_s)
        camera.refresh()
        assert body.camera.notch.index == before + notches


@pytest.mark.parametrize("operation", [Operation.SONY_SET_CONTROL_DEVICE_B, Operation.SONY_GET_ALL_DEVICE_PROP_DATA])
def test_a_command_refused_by_a_stalled_out_pipe_is_sent_once_more_after_clearing_it(tmp_path, operation):
    """usb.c ptp_usb_sendreq: a request whose write fails (GP_ERROR_IO_WRITE) has the OUT endpoint's halt cleared
    and is written once more - the body never took it, so even a press is safe to send again. A stall at the half
    press ended the capture."""
    camera, body = emulated()
    with camera:
        body.faults.stall_out_operation = operation
        writes, original = [], body.bulk_out

        def bulk_out(chunk: bytes) -> None:  # the writes the body took
            original(chunk)
            writes.append(bytes(chunk))

        body.bulk_out = bulk_out
        camera.capture(tmp_path, "f")
    presses = [(struct.unpack_from("<I", w, 12)[0], struct.unpack_from("<H", writes[i + 1], 12)[0])
               for i, w in enumerate(writes) if w[6:8] == b"\x07\x92" and w[4:6] == b"\x01\x00"]
    assert presses == [(0xD2C1, 2), (0xD2C2, 2), (0xD2C2, 1), (0xD2C1, 1)] and body.downloads == 1
    assert len(body.shots) == 1


EXTENDED_ISOS = (50, 64, 80, 32000, 40000, 51200)  # what an A7 lists beyond 100-25600


def test_a_body_left_on_an_extended_iso_is_stepped_to_the_asked_one():
    """libgphoto2 config.c steps through the body's own list; hdrcam knew no notch for ISO 80 and refused ("ISO is
    on Auto or an extended value") a body the user had left there."""
    camera, body = emulated(extended_isos=EXTENDED_ISOS)
    body.camera.set_iso(80)
    with camera:
        assert camera.set_exposure(iso=200).iso == 200
        assert body._step_count == 4  # 80 -> 100 -> 125 -> 160 -> 200


def test_a_step_overshooting_onto_an_extended_iso_is_stepped_back():
    """A body that moves two notches on a step lands beyond 25600 on 32000: the capture ended there, with the body
    left on it, as 'ISO is on Auto or an extended value'."""
    camera, body = emulated(extended_isos=EXTENDED_ISOS, overshoot_every=2)
    body.camera.set_iso(16000)
    with camera:
        assert camera.set_exposure(iso=25600).iso == 25600
        assert body._step_count == 3  # 16000 -> 20000, -> 32000 (two notches), -> 25600
