"""The usb code path against the emulated A7: handshake, ZLPs, notch stepping, capture, and injected faults."""

from __future__ import annotations

import struct

import pytest
import usb.backend

from hdrcam.capture.camera import CameraError, CameraNotFound
from hdrcam.capture.emulator import BULK_PACKET_BYTES, Faults
from hdrcam.capture.notches import SHUTTER_NOTCHES
from hdrcam.capture.ptp.codes import ClassRequest, Operation, Response
from hdrcam.capture.ptp.container import HEADER_SIZE, data, response
from hdrcam.capture.ptp.session import ProtocolError, ResponseError
from hdrcam.capture.ptp.transport import READ_CHUNK_BYTES, Disconnected, Stalled, TransportTimeout
from hdrcam.capture.sony import find_sony_camera
from tests.capture.helpers import emulated_a7, small_camera


def emulated(**faults):
    camera, _ = small_camera("sim-usb", faults=Faults(**faults))
    return camera


def test_handshake_reads_model_protocol_and_properties():
    with emulated() as camera:
        assert camera.model == "Sony Corporation ILCE-7"
        assert camera.protocol_version == 0xC8
        assert camera.settings().exposure_label == "1/60"


@pytest.mark.parametrize("overshoot_every, reversed_shutter_steps", [(0, False), (2, False), (0, True), (2, True)])
def test_notch_stepping_lands_on_the_target_despite_reversed_direction_and_overshoot(overshoot_every,
                                                                                      reversed_shutter_steps):
    with emulated(overshoot_every=overshoot_every, reversed_shutter_steps=reversed_shutter_steps) as camera:
        assert camera.set_exposure(exposure_s=1 / 4000).exposure_label == "1/4000"
        assert camera.set_exposure(exposure_s=2.0).exposure_label == '2"'
        assert camera.set_exposure(iso=400).iso == 400


@pytest.mark.parametrize("payload_bytes", [1, BULK_PACKET_BYTES - HEADER_SIZE, 2 * BULK_PACKET_BYTES - HEADER_SIZE,
                                           READ_CHUNK_BYTES - HEADER_SIZE, READ_CHUNK_BYTES + 100])
def test_receive_handles_short_packets_and_zero_length_packets(payload_bytes):
    """Containers of whole packets end with a ZLP; the next container must still be read intact."""
    with emulated() as camera:
        transport, emulator = camera.session.transport, emulator_of(camera)
        payload = bytes(range(256)) * (payload_bytes // 256) + bytes(payload_bytes % 256)
        for container in (data(0x1009, 42, payload), response(Response.OK, 42)):
            packed = container.pack()
            emulator.in_pipe.queue(packed)
            if len(packed) % BULK_PACKET_BYTES == 0:
                emulator.in_pipe.queue(b"")  # the device's ZLP
        assert transport.receive(1000).payload == payload
        assert transport.receive(1000) == response(Response.OK, 42)
        assert not emulator.in_pipe.transfers


@pytest.mark.parametrize("max_read_bytes", [None, BULK_PACKET_BYTES])
@pytest.mark.parametrize("payload_bytes", [1, BULK_PACKET_BYTES - HEADER_SIZE, BULK_PACKET_BYTES,
                                           3 * BULK_PACKET_BYTES, 3 * BULK_PACKET_BYTES + 7])
def test_unknown_length_data_ends_only_at_a_short_packet_or_a_zlp(payload_bytes, max_read_bytes):
    """Length 0xFFFFFFFF: libgphoto2's ptp_usb_getdata reads on until a read under one packet. A header sent alone
    and reads of one whole packet each (the backend's limit) do not end the container; a ZLP after whole packets
    does, and the response after it is still read intact."""
    with emulated(max_read_bytes=max_read_bytes) as camera:
        transport, emulator = camera.session.transport, emulator_of(camera)
        payload = bytes(range(256)) * (payload_bytes // 256) + bytes(payload_bytes % 256)
        packed = data(0x1009, 42, payload).pack()
        emulator.in_pipe.queue(struct.pack("<I", 0xFFFFFFFF) + packed[4:HEADER_SIZE])
        emulator.in_pipe.queue(packed[HEADER_SIZE:])
        if payload_bytes % BULK_PACKET_BYTES == 0:
            emulator.in_pipe.queue(b"")  # the device's ZLP
        emulator.in_pipe.queue(response(Response.OK, 42).pack())
        assert transport.receive(1000).payload == payload
        assert transport.receive(1000) == response(Response.OK, 42)
        assert not emulator.in_pipe.transfers


def test_capture_downloads_the_in_memory_image(tmp_path):
    with emulated() as camera:
        frame = camera.capture(tmp_path, "frame")
        assert frame.path.suffix == ".dng" and frame.raw.bayer_dn.shape == (48, 64)
        assert frame.raw.metadata.black_level_dn == (512.0,) * 4


def test_device_busy_is_retried(tmp_path):
    with emulated(busy=3) as camera:
        assert camera.capture(tmp_path, "frame").path.is_file()
        assert sum("device busy" in line for line in camera.session.log) == 3


def test_a_lost_read_only_answer_is_cancelled_and_retried(tmp_path):
    with emulated(silent_operation=Operation.GET_OBJECT_INFO) as camera:
        assert camera.capture(tmp_path, "frame").path.is_file()
        assert any("cancelled and retried" in line for line in camera.session.log)


def test_a_lost_answer_to_a_command_that_changes_state_is_a_clear_timeout():
    with emulated(silent_operation=Operation.SONY_SET_CONTROL_DEVICE_B) as camera:
        with pytest.raises(TransportTimeout, match="did not answer"):
            camera.set_exposure(exposure_s=1 / 125)


def test_a_usb_io_error_is_cleared_and_a_read_only_operation_retried(tmp_path):
    """libgphoto2 usb.c (ptp_usb_getdata, ptp_usb_getpacket) clears the IN halt after an I/O error and reads again:
    EIO (the device is still there) is no disconnect."""
    with emulated(io_error_operation=Operation.SONY_GET_ALL_DEVICE_PROP_DATA) as camera:
        assert camera.capture(tmp_path, "frame").path.is_file()
        assert any("I/O error" in line and "cleared the halt and retried" in line for line in camera.session.log)


def test_a_usb_io_error_on_a_command_that_changes_state_is_not_repeated():
    with emulated() as camera:
        emulator_of(camera).faults.io_error_operation = Operation.SONY_SET_CONTROL_DEVICE_B
        with pytest.raises(Stalled, match="I/O error"):
            camera.set_exposure(exposure_s=1 / 125)


def test_an_io_error_mid_data_phase_cancels_the_transaction_and_is_not_retried(tmp_path):
    """libgphoto2's ptp_usb_getdata retries a read "only once and only if we did not read anything yet", then fails
    with PTP_ERROR_IO: an EIO after part of GetObject's data arrived must not re-send the transaction (the rest of
    the old data would be read as a container); the transaction is cancelled (class request 0x64) and raised."""
    camera, body = emulated_a7(io_error_mid_data_operation=Operation.GET_OBJECT)
    requests = []
    class_request = body.class_request
    body.class_request = lambda request, payload: requests.append(request) or class_request(request, payload)
    with pytest.raises(CameraError, match="I/O error .* after 512 bytes of a container"):
        with camera:
            log = camera.session.log
            camera.capture(tmp_path, "frame")
    assert ClassRequest.CANCEL in requests and not body.in_pipe.transfers
    assert not any("retried" in line for line in log)
    assert list(tmp_path.iterdir()) == []


def test_disconnect_during_download_leaves_no_file(tmp_path):
    with pytest.raises(Disconnected, match="disconnected"):
        with emulated(disconnect_during_download=True) as camera:
            camera.capture(tmp_path, "frame")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("when, unplug_eio_calls", [("disconnect_during_download", 8),
                                                    ("disconnect_waiting_for_image", 1)])
def test_an_unplug_reported_as_an_io_error_is_a_disconnect(tmp_path, when, unplug_eio_calls):
    """The transfer in flight at an unplug (and, for a while, the calls after it: the status request too, before
    the kernel sees the device go) fail with EIO, not ENODEV: the device's status request tells a disconnect from
    a transfer error, on the bulk and the interrupt pipe alike."""
    with pytest.raises(Disconnected, match="disconnected while"):
        with emulated(**{when: True}, unplug_eio_calls=unplug_eio_calls) as camera:
            camera.capture(tmp_path, "frame")
    assert list(tmp_path.iterdir()) == []


def test_a_transient_io_error_on_the_event_pipe_clears_its_halt_and_reads_as_no_event(tmp_path):
    """Events are hints (libgphoto2's ptp_usb_event): an EIO on the interrupt pipe of a device still there must
    not stop the capture; the endpoint's halt is cleared (the emulated pipe answers EPIPE until then)."""
    with emulated(io_error_events=2) as camera:
        assert camera.capture(tmp_path, "frame").path.is_file()
        body = emulator_of(camera)
        assert body.faults.io_error_events == 0 and not body.interrupt_halted


def test_io_errors_on_the_event_pipe_do_not_make_the_capture_poll_back_to_back(tmp_path):
    """An EIO returns read_event at once: the poll interval was skipped, so a failing interrupt pipe made the host
    read properties back to back (500 EIOs: 513 transactions where a sound pipe takes 14; endless when it never
    recovers). What is left of the interval is slept."""
    counts = []
    for failures in (0, 500):
        with emulated(io_error_events=failures) as camera:
            session, calls = camera.session, []
            transact = session.transact
            session.transact = lambda *args, **kwargs: calls.append(1) or transact(*args, **kwargs)
            assert camera.capture(tmp_path / str(failures), "frame").path.is_file()
            counts.append(len(calls))
    assert counts[1] <= counts[0] + 5, counts


def test_answer_for_another_transaction_is_a_protocol_error(tmp_path):
    with emulated(wrong_transaction_operation=Operation.GET_OBJECT_INFO) as camera:
        with pytest.raises(ProtocolError, match="transaction"):
            camera.capture(tmp_path, "frame")
    assert list(tmp_path.iterdir()) == []


def emulator_of(camera):
    return camera.session.transport.device._ctx.backend.camera


def test_busy_forever_gives_up_with_the_response_code():
    with emulated() as camera:
        emulator_of(camera).faults.busy = 100
        with pytest.raises(ResponseError, match="DEVICE_BUSY"):
            camera.refresh()


class _NoDevices(usb.backend.IBackend):
    def enumerate_devices(self):
        return iter(())


def test_missing_camera_is_a_clear_error():
    with pytest.raises(CameraNotFound, match="no Sony camera found"):
        find_sony_camera(_NoDevices())


def test_every_notch_has_a_distinct_encoding():
    values = [notch.ptp_value for notch in SHUTTER_NOTCHES]
    assert len(set(values)) == len(values) == 55


def test_send_ends_a_transfer_of_whole_packets_with_a_zlp():
    """The device only sees a 512-byte container once the ZLP arrives; without it the transfer stays open."""
    container = data(Operation.SONY_SET_CONTROL_DEVICE_B, 99, bytes(BULK_PACKET_BYTES - HEADER_SIZE))
    with emulated() as camera:
        transport, emulator = camera.session.transport, emulator_of(camera)
        transport.bulk_out.write(container.pack())
        assert len(emulator._out_transfer) == BULK_PACKET_BYTES  # still waiting for the end of the transfer
        transport.bulk_out.write(b"")
        assert len(emulator._out_transfer) == 0
        transport.send(container, 1000)
        assert len(emulator._out_transfer) == 0


def test_an_answer_that_takes_15_s_is_waited_for_as_libgphoto2_waits():
    """library.c camera_init sets the post-init timeout to USB_NORMAL_TIMEOUT, 20 s ("We have cameras where a
    response takes 15 seconds(!)"); a half press answered after 15 s was a TransportTimeout after 10 s."""
    camera, body = emulated_a7(slow_operation=Operation.SONY_SET_CONTROL_DEVICE_B)
    with camera:
        camera._press(0xD2C1, 2)
        camera._press(0xD2C1, 1)
        assert not any("cancelled" in line for line in camera.session.log)
    assert body.clock.monotonic() >= 15.0


def test_an_answer_slower_than_the_timeout_is_still_a_clear_timeout():
    camera, body = emulated_a7(slow_operation=Operation.SONY_SET_CONTROL_DEVICE_B, slow_answer_s=25.0)
    with camera, pytest.raises(TransportTimeout, match="within 20 s"):
        camera._press(0xD2C1, 2)
