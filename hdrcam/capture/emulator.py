"""``--camera sim-usb``: an emulated Sony A7 that speaks PTP over a pyusb backend (usb.backend.IBackend).

The real ``usb`` code path - device discovery, descriptors, endpoints, containers and ZLPs, the Sony
handshake, notch stepping, focus, capture and download - runs against it unchanged. Its behaviour follows
libgphoto2 (camlibs/ptp2: camera_sony_capture, ptp_sony_*, ptp_unpack_Sony_DPD), not hdrcam's client:
FocusFound (0xD213) turns 2 some time after a half press in AF modes; the image is announced by 0xD215 >=
0x8000 once it is ready, and asking for it earlier is answered InvalidObjectHandle (and counted: libgphoto2
warns that premature access can crash a real body). Frames come from a ``SimulatedCamera``, so the same seed
gives the same RAW data as ``--camera sim``. ``Latencies`` hold the timings; by default they model an A7
and time is virtual (a clock that advances when the host sleeps or a read times out), so tests run fast and
deterministically; with a real clock (e.g. behind HDRCAM_USB_BACKEND) scale them down.

``Faults`` make the camera misbehave on purpose, each as a real body can: DeviceBusy answers, a response that
never comes, a disconnect in the middle of a download or while waiting for the image (its first calls failing
with EIO, as before the kernel sees the device go), a response for the wrong transaction, steps that overshoot, a
stale or early ObjectAdded event, a stalled bulk-in or bulk-out pipe, I/O errors on the bulk-in and interrupt
pipes, images of whole USB packets (ZLPs), properties of every PTP type, empty SDIO answers, and a body set up
wrongly (not M, ISO Auto, JPEG only, AF).
Transport faults that libgphoto2's usb.c copes with: data and response in one transfer (no ZLP), one packet per
read, a header sent alone (and a body that then takes the host's data phases only split so), a late response of
an earlier transaction, a malformed event packet, an event split over two interrupt transfers. Sony details
libgphoto2 documents: 0x9207 +1 moves the shutter one notch shorter (libgphoto2 config.c _put_Sony_ShutterSpeed
sends 0x01 when the target is shorter; ``reversed_shutter_steps`` flips it), 0xD215 counts images without the
0x8000 flag while the body is still writing ("also turns to 1") and may read 0x8000 alone either for "none"
(camera_wait_for_event) or for "ready" (camera_sony_capture), 0xD213 = 3 as focus found (RX0), 0x9202 answers a
version and u32-counted code lists (ptp_sony_get_vendorpropcodes), and descriptors with a second enumeration list
(ptp_unpack_Sony_DPD, 2024 bodies).
The emulator serves DNG files (format code 0xB101 like the A7's ARW).
"""

from __future__ import annotations

import collections
import dataclasses
import datetime as dt
import errno
import struct
from types import SimpleNamespace

import usb.backend
import usb.core

from hdrcam.capture.notches import ISO_VALUES, SHUTTER_NOTCHES
from hdrcam.capture.notches import ISO_AUTO
from hdrcam.capture.ptp.codes import (SONY_A7_PC_REMOTE_PRODUCT_ID, SONY_ABSOLUTE_EXPOSURE_PROPERTIES,
                                      SONY_EXPOSURE_MODE_M, SONY_FOCUS_FOUND, SONY_FOCUS_MANUAL,
                                      SONY_IN_MEMORY_OBJECT, SONY_PENDING_IMAGE_FLAG, SONY_PROTOCOL_MODE_2,
                                      SONY_RAW_FORMAT, SONY_USB_VENDOR_ID, SONY_VENDOR_EXTENSION_ID, ClassRequest,
                                      STARTUP_WAIT_MODELS, STARTUP_WAIT_S, ContainerType, DataType, Event, Operation,
                                      Property, Response)
from hdrcam.capture.ptp.container import HEADER_SIZE, Container, ContainerError, data, event, response
from hdrcam.capture.ptp.datasets import (FORM_ENUMERATION, FORM_NONE, FORM_RANGE, DeviceInfo, ObjectInfo,
                                         PropertyDescriptor, Writer, pack_sony_properties)
from hdrcam.capture.ptp.session import Clock
from hdrcam.capture.simulated import SimulatedCamera

JPEG_FORMAT = 0x3801  # PTP EXIF/JPEG
RAW_AND_JPEG_QUALITIES = (0x12, 0x13, 0x14)  # 0x5004: RAW + JPEG standard, fine, extra fine (libgphoto2)
_FAKE_JPEG = b"\xff\xd8\xff\xe0" + bytes(1020) + b"\xff\xd9"  # a stand-in JPEG: only its format code is read
BULK_PACKET_BYTES = 512  # USB 2.0 high speed
INTERRUPT_PACKET_BYTES = 64
BULK_IN_ENDPOINT, BULK_OUT_ENDPOINT, INTERRUPT_ENDPOINT = 0x81, 0x02, 0x83
_DATA_OUT_OPERATIONS = {Operation.SONY_SET_CONTROL_DEVICE_A, Operation.SONY_SET_CONTROL_DEVICE_B,
                        Operation.SET_DEVICE_PROP_VALUE}


class VirtualClock(Clock):
    """Seconds that pass only when someone sleeps or waits."""

    def __init__(self):
        self.now_s = 0.0

    def monotonic(self) -> float:
        return self.now_s

    def sleep(self, seconds: float) -> None:
        self.now_s += max(seconds, 0.0)


@dataclasses.dataclass(frozen=True)
class Latencies:
    """How long the emulated body takes, in seconds of its clock."""

    step_s: float = 0.7  # a notch lands ~0.7 s after 0x9207 (REFERENCE.md sec. 4, measured on A7s by others)
    image_ready_s: float = 0.4  # after the exposure ends; an assumption (RAW processing time varies by body)
    focus_s: float = 0.3  # from the half press to FocusFound in AF-S; an assumption (lens and light dependent)

    def scaled(self, factor: float) -> "Latencies":
        return Latencies(*(value * factor for value in dataclasses.astuple(self)))


@dataclasses.dataclass
class Faults:
    """Misbehaviour to inject (and how the body is set up); each counter is consumed as the fault fires."""

    busy: int = 0  # answer the next N operations (after the handshake) with DeviceBusy
    silent_operation: int | None = None  # never answer the next command with this code
    slow_operation: int | None = None  # answer the next command with this code only after slow_answer_s (library.c
    slow_answer_s: float = 15.0  # camera_init: "We have cameras where a response takes 15 seconds(!)")
    disconnect_during_download: bool = False  # unplug after the first chunk of the next GetObject
    disconnect_after_downloads: int | None = None  # unplug mid-download once this many images were downloaded
    disconnect_waiting_for_image: bool = False  # unplug at the first event read after the shutter release
    unplug_eio_calls: int = 0  # after an unplug, this many USB calls fail with EIO before the rest fail with ENODEV
    # (the kernel has not yet seen the device go: Linux URB -EPROTO, libusb LIBUSB_ERROR_IO)
    wrong_transaction_operation: int | None = None  # answer the next command with this code for another transaction
    overshoot_every: int = 0  # every Nth notch step moves two notches
    stale_object_added: bool = False  # an extra ObjectAdded after each download (as for a RAW+JPEG pair)
    early_object_added: bool = False  # ObjectAdded when the exposure ends, before 0xD215 says the image is ready
    stalls_during_download: int = 0  # stall (EPIPE) the bulk-in pipe mid-download this many times
    stall_out_operation: int | None = None  # the next command with this code is not taken: its write fails with
    # EPIPE and bulk-out stays halted until the host clears it (libgphoto2 usb.c ptp_usb_sendreq clears the OUT
    # endpoint's halt and sends the request once more)
    io_error_operation: int | None = None  # the first read of the next answer to this command fails with EIO
    # (LIBUSB_ERROR_IO: a transfer error, the device still there; libgphoto2 usb.c clears the IN halt, reads again)
    io_error_mid_data_operation: int | None = None  # the second read of the next data phase of this command fails
    # with EIO, the rest of the transfer still queued (a transfer error: nothing tells the body to stop sending)
    io_error_events: int = 0  # the next N interrupt-in reads fail with EIO, the device still there; the interrupt
    # endpoint then answers EPIPE until its halt is cleared (an assumption: the endpoint out of step after a
    # transfer error, which is why libgphoto2 usb.c clears the IN halt after GP_ERROR_IO_READ)
    whole_packet_images: bool = False  # pad images so their data container is whole packets (a ZLP ends it)
    odd_property_types: bool = False  # 0x9209 also lists properties of array, 128-bit and string types
    empty_sdio_answers: int = 0  # answer the first N GetSDIOGetExtDeviceInfo with no data
    never_focus: bool = False  # in AF modes FocusFound never turns 2
    focus_mode: int = SONY_FOCUS_MANUAL  # 0x500A: 1 MF, 2 AF-S
    exposure_mode: int = SONY_EXPOSURE_MODE_M  # 0x500E: 1 M, 2 P, 3 A, 4 S
    iso_auto: bool = False  # 0xD21E reports Auto (0xFFFFFF)
    iso_multi_frame_nr: bool = False  # 0xD21E has Multi Frame Noise Reduction in its high byte
    iso_max: int | None = None  # the body offers ISO up to this only: 0xD21E lists no more, a step stops there
    extended_isos: tuple[int, ...] = ()  # ISOs beyond 100-25600 the body also lists and steps through (an A7's 50,
    # 64, 80 below, 32000-51200 above: libgphoto2 config.c steps through the body's own list)
    iso_listed_beyond_max: bool = False  # with iso_max, 0xD21E still lists the ISOs above it (config.c: Sony
    # "seems to report values in an enum that are not actually supported under certain configurations (e.g. ISO)")
    image_quality: int = 0x10  # 0x5004: 0x10 RAW, 0x13 RAW + JPEG (two objects per shot), 0x03 JPEG fine only;
    # 0 as some bodies read it: the factory default (0x10) applies (library.c camera_sony_capture)
    reversed_shutter_steps: bool = False  # 0x9207 +1 makes the shutter longer (libgphoto2: +1 = shorter)
    focus_found_value: int = SONY_FOCUS_FOUND  # what 0xD213 reads once focused: 2, or 3 as on the RX0
    pending_flag_without_images: bool = False  # 0xD215 reads 0x8000 (flag, no images) once memory is empty
    pending_flag_alone_when_ready: bool = False  # 0xD215 reads 0x8000 (no count) while an image is ready
    pending_images_unreported: bool = False  # 0xD215 stays 0: only ObjectAdded announces an image (library.c
    # camera_sony_capture: "needed on older cameras like the a58")
    secondary_enumerations: bool = False  # enumerated descriptors carry a second list (newer bodies)
    coalesce_response: bool = False  # a data phase and its response go out as one transfer (no ZLP)
    max_read_bytes: int | None = None  # a bulk read returns at most this many bytes
    split_header: bool = False  # the 12-byte header of a data container goes out as its own transfer
    split_header_out: bool = False  # the body takes a host's data phase only with its 12-byte header in a transfer
    # of its own, then the payload (what libgphoto2 usb.c ptp_usb_senddata sends once ptp_usb_getdata saw the body
    # split a header: params->split_header_data); a header sent together with its payload is not read
    unknown_length_objects: bool = False  # GetObject's data container says length 0xFFFFFFFF (size not known in
    # advance; libgphoto2 usb.c ptp_usb_getdata reads it until a short packet)
    stale_response_operation: int | None = None  # before answering this command, send a late response of the one before
    malformed_event: bool = False  # a 4-parameter event packet at the next full press
    split_events: bool = False  # each event goes out as two interrupt transfers, its 12-byte header then its
    # parameters (libgphoto2 usb.c ptp_usb_event reads on while the container is longer than what it read)
    damaged_image: int | None = None  # the Nth image (1-based) downloads with its data zeroed after the header
    drive_mode: int = 1  # 0x5013: 1 single shot, 2 continuous, 0x8337 bracket
    vendor_extension_id: int = SONY_VENDOR_EXTENSION_ID  # 0xFFFFFFFF (MTP) as some Sony bodies report it
    not_pc_remote: bool = False  # USB Connection not on PC Remote: DeviceInfo lists no Sony operation (0x92xx) and
    # each is answered OperationNotSupported (library.c fixup_cached_deviceinfo then skips the SDIO handshake)
    lens_reports_aperture: bool = True  # False: a lens without electronic contacts (no 0x5007)
    device_info_strings: int = 4  # DeviceInfo's trailing strings sent (Manufacturer, Model, DeviceVersion,
    # SerialNumber, in that order): optional to libgphoto2's ptp_unpack_DI
    model: str = "ILCE-7"  # DeviceInfo's model; one of STARTUP_WAIT_MODELS ignores full presses made within
    # STARTUP_WAIT_S of OpenSession (library.c camera_sony_capture: "need around 3 seconds startup time")
    session_ids_in_use: int = 0  # OpenSession with an id up to this is answered InvalidTransactionID (an id the
    # body still holds for an earlier host; library.c camera_init tries the next ids)
    absolute_exposure: bool = False  # a newer body: its 0x9202 answer (and DeviceInfo) lists ShutterSpeed2 (0xD229)
    # and ISO2 (0xD226), 0x9209 reports both (0xD229 enumerating its shutter times again), and 0x9205 on either with
    # a listed u32 value sets it (landing after Latencies.step_s) - libgphoto2 config.c _put_Sony_ShutterSpeed
    # ("new style") and _put_Sony_ISO2, chosen by have_prop on those codes; 0xD20D/0xD21E still step with 0x9207
    absolute_set_refused: bool = False  # with absolute_exposure: 0x9205 on 0xD229/0xD226 is answered
    # DevicePropNotSupported
    absolute_set_ignored: bool = False  # with absolute_exposure: 0x9205 on 0xD229/0xD226 answered OK, nothing changes
    sdio_protocol_version: int = SONY_PROTOCOL_MODE_2  # 0x9202's version (0x12C on bodies of Sony's protocol 300;
    # libgphoto2 does not look at it to choose absolute setting)


def _is_split_data_header(transfer: bytes) -> bool:
    """Whether ``transfer`` is the 12-byte header alone of a data container that carries a payload."""
    if len(transfer) != HEADER_SIZE:
        return False
    length, kind = struct.unpack_from("<IH", transfer)
    return kind == ContainerType.DATA and length > HEADER_SIZE


class _InPipe:
    """A bulk-in pipe: queued transfers read with USB semantics (a read ends at a short packet or a full buffer)."""

    def __init__(self, packet_bytes: int):
        self.packet_bytes = packet_bytes
        self.transfers: collections.deque[list] = collections.deque()  # [bytes, offset]

    def queue(self, payload: bytes) -> None:
        self.transfers.append([payload, 0])

    def clear(self) -> None:
        self.transfers.clear()

    def read_into(self, buffer) -> int | None:
        """Bytes copied into ``buffer``, or None if nothing is waiting."""
        if not self.transfers:
            return None
        transfer = self.transfers[0]
        payload, offset = transfer
        remaining = len(payload) - offset
        size = len(buffer)
        if remaining > size:
            count = size - size % self.packet_bytes
        else:
            count = remaining
            self.transfers.popleft()
            if remaining == size and len(payload) % self.packet_bytes == 0 and len(payload):
                self.transfers.appendleft([b"", 0])  # the ZLP did not fit in this read: it comes next
        memoryview(buffer).cast("B")[:count] = payload[offset:offset + count]
        transfer[1] = offset + count
        return count


class EmulatedSonyA7:
    """The camera side of PTP: a Sony A7 in PC-remote mode (protocol mode 2)."""

    def __init__(self, camera: SimulatedCamera, *, clock: Clock | None = None, faults: Faults | None = None,
                 latencies: Latencies | None = None):
        self.camera = camera
        self.clock = clock or VirtualClock()
        self.faults = faults or Faults()
        self.latencies = latencies or Latencies()
        self.shots: list[dict] = []  # per full press: {"focused": bool, "exposure_s": float}
        self.premature_requests = 0  # GetObjectInfo/GetObject before 0xD215 announced the image
        self.opened_at: float | None = None  # when OpenSession last succeeded
        self.ignored_presses = 0  # full presses made while the body was starting up (Faults.model)
        self.halted = False  # bulk-in stalled until the host clears the halt
        self.out_halted = False  # bulk-out stalled until the host clears the halt (Faults.stall_out_operation)
        self.interrupt_halted = False  # interrupt-in halted until the host clears it (Faults.io_error_events)
        self._unplug_eio_calls = 0  # USB calls left that fail with EIO after an unplug (Faults.unplug_eio_calls)
        self._io_error_due = False  # the next bulk-in read fails with EIO (Faults.io_error_operation)
        self._io_error_mid_data_due = False  # a read within a transfer fails (Faults.io_error_mid_data_operation)
        self.downloads = 0  # images downloaded whole
        self.in_pipe = _InPipe(BULK_PACKET_BYTES)
        self.events: collections.deque[bytes] = collections.deque()
        self.connected = True
        self.lens_covered = False
        self.priority_mode = 0  # 0xD25A: 0 camera, 1 application (set by the host with 0x9205)
        self.absolute_sets: list[tuple[int, int]] = []  # (property, value) of each 0x9205 taken on 0xD229/0xD226
        self._out_transfer = bytearray()
        self._out_header = b""  # a data container's header that came in a transfer of its own
        self._answer_due_s: float | None = None  # when a slow answer (Faults.slow_operation) may be read
        self.read_timeout_ms = 0  # the timeout of the bulk-in read under way (ms)
        self._awaiting_data: Container | None = None
        self._reset_state()
        self._handshake_done = False

    def _reset_state(self) -> None:
        self.session_open = False
        self._steps: list[tuple[float, int, int]] = []  # (due time, property, notches)
        self._step_count = 0
        self._buttons = {Property.SONY_HALF_PRESS: 1, Property.SONY_FULL_PRESS: 1}
        self._image: bytes | None = None  # the object 0xFFFFC001 holds now
        self._image_format, self._image_name = SONY_RAW_FORMAT, ""
        self._queued_images: list[tuple[bytes, int, str]] = []  # (bytes, format, name) after it: RAW+JPEG
        self._image_due_s: float | None = None
        self._image_number = 0
        self._downloading = False
        self._half_pressed_at: float | None = None
        self._early_event_s: float | None = None
        self.in_pipe.clear()

    # -- USB side --------------------------------------------------------------------------------------------
    def bulk_out(self, chunk: bytes) -> None:
        """Bytes the host wrote; a transfer ends with a short packet or a ZLP."""
        self._require_connected()
        if not self._out_transfer and len(chunk) >= HEADER_SIZE and self.faults.stall_out_operation is not None \
                and struct.unpack_from("<HH", chunk, 4) == (ContainerType.COMMAND, self.faults.stall_out_operation):
            self.faults.stall_out_operation, self.out_halted = None, True
        if self.out_halted:
            raise usb.core.USBError("Pipe error", errno=errno.EPIPE)
        self._out_transfer += chunk
        if len(chunk) and len(chunk) % BULK_PACKET_BYTES == 0:
            return  # a full packet: the transfer goes on
        transfer, self._out_transfer = bytes(self._out_transfer), bytearray()
        if not transfer:
            return
        header, self._out_header = self._out_header, b""
        if not header and _is_split_data_header(transfer):
            self._out_header = transfer  # its payload follows as the next transfer (usb.c split_header_data)
            return
        if self.faults.split_header_out and not header and len(transfer) > HEADER_SIZE and \
                struct.unpack_from("<H", transfer, 4)[0] == ContainerType.DATA:
            return  # a header sent with its payload: this body does not read it (the host times out)
        transfer = header + transfer
        try:
            container = Container.unpack(transfer)
        except ContainerError:
            return  # garbage: a real camera ignores it and the host times out
        if self._awaiting_data is not None:
            request, self._awaiting_data = self._awaiting_data, None
            if container.kind == ContainerType.DATA and container.transaction_id == request.transaction_id:
                self._answer(request, container.payload)
            return
        if container.kind != ContainerType.COMMAND:
            return
        if container.code in _DATA_OUT_OPERATIONS:
            self._awaiting_data = container
            return
        self._answer(container, None)

    def bulk_in(self, buffer) -> int:
        """A bulk-in read into ``buffer`` (bytes copied); an answer not yet due (Faults.slow_operation) arrives
        within a read whose timeout (``read_timeout_ms``, set by the backend) reaches it, else the read times out."""
        self._require_connected()
        if self._answer_due_s is not None:
            wait_s = self._answer_due_s - self.clock.monotonic()
            if wait_s > self.read_timeout_ms / 1000:
                raise usb.core.USBTimeoutError("Operation timed out", errno=errno.ETIMEDOUT)
            self.clock.sleep(wait_s)
            self._answer_due_s = None
        self._advance()
        if self.faults.max_read_bytes:
            buffer = memoryview(buffer).cast("B")[:self.faults.max_read_bytes]
        if self.halted:
            raise usb.core.USBError("Pipe error", errno=errno.EPIPE)
        if self._io_error_due:
            self._io_error_due = False
            raise usb.core.USBError("Input/output error", errno=errno.EIO)
        if self._io_error_mid_data_due and self.in_pipe.transfers and self.in_pipe.transfers[0][1]:
            self._io_error_mid_data_due = False
            raise usb.core.USBError("Input/output error", errno=errno.EIO)
        count = self.in_pipe.read_into(buffer)
        if count is None:
            raise usb.core.USBTimeoutError("Operation timed out", errno=errno.ETIMEDOUT)
        if self._downloading and (self.faults.disconnect_during_download
                                  or self.faults.disconnect_after_downloads == self.downloads):
            self.faults.disconnect_during_download, self.faults.disconnect_after_downloads = False, None
            self._unplug()
        elif self._downloading and self.faults.stalls_during_download and self.in_pipe.transfers:
            self.faults.stalls_during_download -= 1
            self.in_pipe.clear()  # the rest of the transfer is lost; the image stays in memory
            self._downloading, self.halted = False, True
            raise usb.core.USBError("Pipe error", errno=errno.EPIPE)
        if self._downloading and not self.in_pipe.transfers:  # the whole image and its response went out
            self._downloading, self._image = False, None
            if self._queued_images:
                self._image, self._image_format, self._image_name = self._queued_images.pop(0)
            self.downloads += 1
            if self.faults.stale_object_added:
                self._queue_event(event(Event.SONY_OBJECT_ADDED, 0, SONY_IN_MEMORY_OBJECT).pack())
        return count

    def clear_halt(self, endpoint: int) -> None:
        self._require_connected()
        if endpoint == INTERRUPT_ENDPOINT:
            self.interrupt_halted = False
        elif endpoint == BULK_IN_ENDPOINT:
            self.halted = False
        elif endpoint == BULK_OUT_ENDPOINT:
            self.out_halted = False

    def interrupt_in(self, buffer) -> int:
        if self.faults.disconnect_waiting_for_image and self._image_due_s is not None:
            self.faults.disconnect_waiting_for_image = False
            self._unplug()
        self._require_connected()
        self._advance()
        if self.interrupt_halted:
            raise usb.core.USBError("Pipe error", errno=errno.EPIPE)
        if self.faults.io_error_events:
            self.faults.io_error_events -= 1
            self.interrupt_halted = True
            raise usb.core.USBError("Input/Output Error", errno=errno.EIO)
        if not self.events:
            raise usb.core.USBTimeoutError("Operation timed out", errno=errno.ETIMEDOUT)
        packet = self.events.popleft()
        memoryview(buffer).cast("B")[:len(packet)] = packet
        return len(packet)

    def _queue_event(self, packet: bytes) -> None:
        """Queue an event container for the interrupt pipe: one transfer, or two with Faults.split_events."""
        if self.faults.split_events and len(packet) > HEADER_SIZE:
            self.events.extend((packet[:HEADER_SIZE], packet[HEADER_SIZE:]))
        else:
            self.events.append(packet)

    def class_request(self, request: int, payload: bytes) -> bytes:
        self._require_connected()
        if request == ClassRequest.CANCEL:
            self.in_pipe.clear()
            self._awaiting_data, self._out_transfer, self._downloading = None, bytearray(), False
            self._out_header, self._answer_due_s = b"", None
            return b""
        if request == ClassRequest.DEVICE_RESET:
            self._reset_state()
            return b""
        if request == ClassRequest.GET_DEVICE_STATUS:
            return struct.pack("<HH", 4, Response.OK)
        raise usb.core.USBError("Pipe error", errno=errno.EPIPE)

    def _unplug(self) -> None:
        self.connected = False
        self._unplug_eio_calls = self.faults.unplug_eio_calls

    def _require_connected(self) -> None:
        if self.connected:
            return
        if self._unplug_eio_calls:
            self._unplug_eio_calls -= 1
            raise usb.core.USBError("Input/Output Error", errno=errno.EIO)
        raise usb.core.USBError("No such device (it may have been disconnected)", errno=errno.ENODEV)

    # -- PTP side --------------------------------------------------------------------------------------------
    def _answer(self, request: Container, payload: bytes | None) -> None:
        code, transaction_id = request.code, request.transaction_id
        faults = self.faults
        if faults.silent_operation == code:
            faults.silent_operation = None
            return
        if faults.slow_operation == code:
            faults.slow_operation, self._answer_due_s = None, self.clock.monotonic() + faults.slow_answer_s
        if faults.io_error_operation == code:
            faults.io_error_operation, self._io_error_due = None, True
        if faults.io_error_mid_data_operation == code:
            faults.io_error_mid_data_operation, self._io_error_mid_data_due = None, True
        if faults.busy and self._handshake_done and code != Operation.OPEN_SESSION:
            faults.busy -= 1
            self._send(response(Response.DEVICE_BUSY, transaction_id))
            return
        if faults.wrong_transaction_operation == code:
            faults.wrong_transaction_operation = None
            transaction_id += 1
        if faults.stale_response_operation == code:
            faults.stale_response_operation = None
            self._send(response(Response.OK, transaction_id - 1))
        if code != Operation.OPEN_SESSION and code != Operation.GET_DEVICE_INFO and not self.session_open:
            self._send(response(Response.SESSION_NOT_OPEN, transaction_id))
            return
        handler = getattr(self, f"_op_{code:04x}", None)
        if handler is None or (faults.not_pc_remote and code >> 12 == 9):
            self._send(response(Response.OPERATION_NOT_SUPPORTED, transaction_id))
            return
        outcome = handler(request, payload)
        reply_payload, reply_code = outcome if isinstance(outcome, tuple) else (None, outcome)
        answer = response(reply_code, transaction_id).pack()
        if reply_payload is not None:
            packed = data(code, transaction_id, reply_payload).pack()
            if faults.unknown_length_objects and code == Operation.GET_OBJECT:
                packed = struct.pack("<I", 0xFFFFFFFF) + packed[4:]
            if faults.split_header:
                self.in_pipe.queue(packed[:12])
                packed = packed[12:]
            if faults.coalesce_response:
                self.in_pipe.queue(packed + answer)
                return
            self.in_pipe.queue(packed)
        self.in_pipe.queue(answer)

    def _send(self, container: Container) -> None:
        self.in_pipe.queue(container.pack())

    def _op_1002(self, request, payload):  # OpenSession
        if self.session_open:
            return Response.SESSION_ALREADY_OPEN
        if request.params and request.params[0] <= self.faults.session_ids_in_use:
            return Response.INVALID_TRANSACTION_ID
        self.session_open = True
        self.opened_at = self.clock.monotonic()
        return Response.OK

    def _op_1003(self, request, payload):  # CloseSession
        self.session_open = False
        return Response.OK

    def _op_1001(self, request, payload):  # GetDeviceInfo
        texts = ("Sony Corporation", self.faults.model, "3.20", f"{self.camera.seed:08d}")
        operations = tuple(sorted(code for code in Operation if not (self.faults.not_pc_remote and code >> 12 == 9)))
        info = DeviceInfo(100, self.faults.vendor_extension_id, 100, "Sony PTP Extensions", 0,
                          operations, tuple(sorted(Event)), self._property_codes(), (SONY_RAW_FORMAT,),
                          (SONY_RAW_FORMAT,), *texts)
        packed = info.pack()
        left_out = sum(len(Writer().string(text).bytes()) for text in texts[self.faults.device_info_strings:])
        return packed[:len(packed) - left_out], Response.OK

    def _op_9201(self, request, payload):  # SDIOConnect phases 1, 2, 3
        if request.params and request.params[0] == 3:
            self._handshake_done = True
        return Response.OK

    def _op_9202(self, request, payload):  # GetSDIOGetExtDeviceInfo -> protocol version, then codes
        if self.faults.empty_sdio_answers:  # a body still starting PC-remote mode answers OK with no data
            self.faults.empty_sdio_answers -= 1
            return b"", Response.OK
        # libgphoto2 ptp_sony_get_vendorpropcodes: u16 version, u32-counted u16 codes, optionally a second list
        operations_and_events = [int(c) for c in (*Operation, *Event)]
        properties = [int(c) for c in self._property_codes()]
        return (struct.pack(f"<HI{len(operations_and_events)}H", self.faults.sdio_protocol_version,
                            len(operations_and_events),
                            *operations_and_events)
                + struct.pack(f"<I{len(properties)}H", len(properties), *properties)), Response.OK

    def _property_codes(self) -> tuple[int, ...]:
        """The property codes DeviceInfo and 0x9202 list: ShutterSpeed2 and ISO2 on a newer body only."""
        return tuple(sorted(code for code in Property if self.faults.absolute_exposure
                            or code not in SONY_ABSOLUTE_EXPOSURE_PROPERTIES))

    def _op_9205(self, request, payload):  # SetControlDeviceA: the priority mode (0xD25A, INT8); a newer body's
        code = request.params[0] if request.params else 0  # ShutterSpeed2 and ISO2 (UINT32)
        if code == Property.SONY_PRIORITY_MODE and payload is not None and len(payload) == 1:
            self.priority_mode = struct.unpack("<b", payload)[0]
            return Response.OK
        if code in SONY_ABSOLUTE_EXPOSURE_PROPERTIES and self.faults.absolute_exposure:
            if self.faults.absolute_set_refused:
                return Response.DEVICE_PROP_NOT_SUPPORTED
            if payload is None or len(payload) != 4:
                return Response.PARAMETER_NOT_SUPPORTED
            value = struct.unpack("<I", payload)[0]
            listed = self._shutter_values() if code == Property.SONY_SHUTTER_SPEED_2 else self._offered_isos()
            if value not in listed:
                return Response.INVALID_DEVICE_PROP_VALUE
            self.absolute_sets.append((code, value))
            if not self.faults.absolute_set_ignored:
                self._steps.append((self.clock.monotonic() + self.latencies.step_s, code, value))
            return Response.OK
        return Response.DEVICE_PROP_NOT_SUPPORTED

    @staticmethod
    def _shutter_values() -> tuple[int, ...]:
        """0xD229's enumeration on a newer body: every notch, in 0xD20D's encoding (300/10 for 30 s, as config.c
        _get_Sony_ShutterSpeed notes Sony reports them)."""
        return tuple(notch.ptp_value for notch in SHUTTER_NOTCHES)

    def _op_9209(self, request, payload):  # GetAllDevicePropData
        return pack_sony_properties(self._descriptors()), Response.OK

    def _op_9207(self, request, payload):  # SetControlDeviceB: buttons and notch steps
        code = request.params[0] if request.params else 0
        if code in (Property.SONY_SHUTTER_SPEED, Property.SONY_ISO):
            if len(payload) not in (1, 2):
                return Response.PARAMETER_NOT_SUPPORTED
            delta = struct.unpack("<b" if len(payload) == 1 else "<h", payload)[0]
            if delta == 0:  # a jump of any other width moves that many notches (config.c sends posnew - posorig)
                return Response.PARAMETER_NOT_SUPPORTED
            self._step_count += 1
            if self.faults.overshoot_every and self._step_count % self.faults.overshoot_every == 0:
                delta += 1 if delta > 0 else -1  # one notch too far
            if code == Property.SONY_SHUTTER_SPEED and self.faults.reversed_shutter_steps:
                delta = -delta  # libgphoto2: +1 = one notch shorter (up the notch index); this body counts back
            self._steps.append((self.clock.monotonic() + self.latencies.step_s, code, delta))
            return Response.OK
        if code in self._buttons:
            if len(payload) != 2:
                return Response.PARAMETER_NOT_SUPPORTED
            state = struct.unpack("<H", payload)[0]
            if code == Property.SONY_HALF_PRESS:
                self._half_pressed_at = self.clock.monotonic() if state == 2 else None
            if code == Property.SONY_FULL_PRESS and state == 2 and self._starting_up():
                self.ignored_presses += 1
                return Response.OK  # not started up: the press does nothing (and its release neither)
            if code == Property.SONY_FULL_PRESS and state == 2 and self._buttons[code] != 2:
                if self.faults.malformed_event:
                    self.faults.malformed_event = False
                    self.events.append(struct.pack("<IHHI4I", 28, 4, Event.SONY_OBJECT_ADDED, 0, 1, 2, 3, 4))
                self.shots.append({"focused": self._focus_found() == self.faults.focus_found_value
                                   or self.faults.focus_mode == SONY_FOCUS_MANUAL,
                                   "exposure_s": self.camera.true_exposure_s()})
            if code == Property.SONY_FULL_PRESS and state == 1 and self._buttons[code] == 2:
                self._expose()
            self._buttons[code] = state
            return Response.OK
        return Response.DEVICE_PROP_NOT_SUPPORTED

    def _starting_up(self) -> bool:
        return self.faults.model in STARTUP_WAIT_MODELS and self.opened_at is not None and \
            self.clock.monotonic() - self.opened_at < STARTUP_WAIT_S

    def _image_ready(self) -> bool:
        self._advance()
        return self._image is not None and self._image_due_s is None

    def _op_1008(self, request, payload):  # GetObjectInfo
        if not request.params or request.params[0] != SONY_IN_MEMORY_OBJECT or not self._image_ready():
            self.premature_requests += 1
            return Response.INVALID_OBJECT_HANDLE
        info = ObjectInfo(0x00010001, self._image_format, 0, len(self._image), 0, 0, 0, 0,
                          self.camera.scene.width_px, self.camera.scene.height_px, 16, 0, 0, 0, 0,
                          self._image_name, "", "", "")
        return info.pack(), Response.OK

    def _op_1009(self, request, payload):  # GetObject: the image leaves memory once all of it was read
        if not request.params or request.params[0] != SONY_IN_MEMORY_OBJECT or not self._image_ready():
            self.premature_requests += 1
            return Response.INVALID_OBJECT_HANDLE
        self._downloading = True
        return self._image, Response.OK

    # -- camera behaviour ----------------------------------------------------------------------------------
    def _expose(self) -> None:
        camera = self.camera
        bayer = camera.render_dn(dark=self.lens_covered)
        settings = camera.settings()
        timestamp = dt.datetime.now().replace(microsecond=0)
        self._image_number += 1
        image = camera.frame_bytes(bayer, settings, timestamp)
        if self._image_number == self.faults.damaged_image:  # a transfer the body garbled: the header survives
            image = image[:200] + bytes(len(image) - 200)
        if self.faults.whole_packet_images:  # trailing zeros after a TIFF's last IFD and strip are ignored
            image += bytes(-(len(image) + 12) % BULK_PACKET_BYTES)
        raw = (image, SONY_RAW_FORMAT, f"DSC{self._image_number:05d}.DNG")
        if self.faults.image_quality in RAW_AND_JPEG_QUALITIES:  # assumption: the JPEG of the pair comes first
            self._image, self._image_format = _FAKE_JPEG, JPEG_FORMAT
            self._image_name, self._queued_images = f"DSC{self._image_number:05d}.JPG", [raw]
        else:
            self._image, self._image_format, self._image_name = raw
        exposure_end_s = self.clock.monotonic() + camera.true_exposure_s()
        self._image_due_s = exposure_end_s + self.latencies.image_ready_s
        if self.faults.early_object_added:
            self._early_event_s = exposure_end_s

    def _advance(self) -> None:
        """Apply whatever became due on the virtual clock: landed steps, a finished exposure."""
        now = self.clock.monotonic()
        if self._early_event_s is not None and now >= self._early_event_s:
            self._early_event_s = None
            self._queue_event(event(Event.SONY_OBJECT_ADDED, 0, SONY_IN_MEMORY_OBJECT).pack())
        for step in [s for s in self._steps if s[0] <= now]:
            self._steps.remove(step)
            _, code, delta = step
            if code == Property.SONY_SHUTTER_SPEED_2:  # an absolute set: delta is the value
                self.camera.set_notch(SHUTTER_NOTCHES[self._shutter_values().index(delta)])
            elif code == Property.SONY_ISO_2:
                self.camera.set_iso(delta)
            elif code == Property.SONY_SHUTTER_SPEED:
                index = min(max(self.camera.notch.index + delta, 0), len(SHUTTER_NOTCHES) - 1)
                self.camera.set_notch(SHUTTER_NOTCHES[index])
            else:
                offered = self._offered_isos()
                index = min(max(offered.index(int(self.camera.settings().iso)) + delta, 0), len(offered) - 1)
                self.camera.set_iso(offered[index])
            self._queue_event(event(Event.SONY_PROPERTY_CHANGED, 0, code).pack())
        if self._image_due_s is not None and now >= self._image_due_s:
            self._image_due_s = None
            if not self.faults.early_object_added:
                self._queue_event(event(Event.SONY_OBJECT_ADDED, 0, SONY_IN_MEMORY_OBJECT).pack())

    def _offered_isos(self) -> tuple[int, ...]:
        """The ISOs this body steps through (Faults.iso_max)."""
        top = self.faults.iso_max
        return tuple(sorted((*(ISO_VALUES if top is None else ISO_VALUES[:ISO_VALUES.index(top) + 1]),
                             *self.faults.extended_isos)))

    def _focus_found(self) -> int:
        """0xD213: 2 once an AF body has focused after the half press, else 1."""
        faults = self.faults
        if faults.focus_mode == SONY_FOCUS_MANUAL or self._half_pressed_at is None or faults.never_focus:
            return 1
        focused = self.clock.monotonic() >= self._half_pressed_at + self.latencies.focus_s
        return faults.focus_found_value if focused else 1

    def _descriptors(self) -> list[PropertyDescriptor]:
        self._advance()
        settings = self.camera.settings()
        faults = self.faults
        waiting = (self._image is not None) + len(self._queued_images)
        if faults.pending_images_unreported:
            pending = 0
        elif self._image is not None and self._image_due_s is None:
            pending = SONY_PENDING_IMAGE_FLAG | (0 if faults.pending_flag_alone_when_ready else waiting)
        elif waiting:
            pending = waiting  # still being written: the count without the flag (libgphoto2: "also turns to 1")
        else:
            pending = SONY_PENDING_IMAGE_FLAG if faults.pending_flag_without_images and self.downloads else 0
        shutter = self.camera.notch.ptp_value
        iso = ISO_AUTO if faults.iso_auto else int(settings.iso)
        if faults.iso_multi_frame_nr:
            iso |= 1 << 24
        listed = ISO_VALUES if faults.iso_listed_beyond_max else self._offered_isos()
        secondary = (*listed, ISO_AUTO) if faults.secondary_enumerations else None
        descriptors = [
            PropertyDescriptor(Property.SONY_SHUTTER_SPEED, DataType.UINT32, 1, 1, 0, shutter, FORM_NONE, ()),
            PropertyDescriptor(Property.SONY_ISO, DataType.UINT32, 1, 1, 100, iso, FORM_ENUMERATION,
                               (*listed, ISO_AUTO), secondary),
            *([PropertyDescriptor(Property.F_NUMBER, DataType.UINT16, 0, 1, 140, round(settings.f_number * 100))]
              if faults.lens_reports_aperture else []),
            PropertyDescriptor(Property.IMAGE_QUALITY, DataType.UINT8, 1, 1, 0x10, faults.image_quality),
            PropertyDescriptor(Property.FOCUS_MODE, DataType.UINT16, 1, 1, 2, faults.focus_mode, FORM_ENUMERATION,
                               (1, 2, 0x8004, 0x8005),
                               (1, 2, 0x8004, 0x8005) if faults.secondary_enumerations else None),
            PropertyDescriptor(Property.EXPOSURE_PROGRAM_MODE, DataType.UINT16, 0, 1, 1, faults.exposure_mode),
            PropertyDescriptor(Property.DRIVE_MODE, DataType.UINT16 if faults.drive_mode <= 0xFFFF else DataType.UINT32,
                               1, 1, 1, faults.drive_mode),  # newer bodies: 32 bits
            PropertyDescriptor(Property.SONY_FOCUS_FOUND, DataType.UINT8, 0, 1, 1, self._focus_found()),
            PropertyDescriptor(Property.SONY_PENDING_IMAGES, DataType.UINT16, 0, 1, 0, pending),
        ]
        if faults.absolute_exposure:
            descriptors += [
                PropertyDescriptor(Property.SONY_SHUTTER_SPEED_2, DataType.UINT32, 1, 1, 0, shutter, FORM_ENUMERATION,
                                   self._shutter_values()),
                PropertyDescriptor(Property.SONY_ISO_2, DataType.UINT32, 1, 1, 100, iso, FORM_ENUMERATION,
                                   (*listed, ISO_AUTO), secondary),
            ]
        if faults.odd_property_types:  # codes of the A7's lens/body info; the types are what matters here
            descriptors += [
                PropertyDescriptor(0xD2A0, DataType.ARRAY | DataType.UINT16, 0, 1, (), (1, 2, 3)),
                PropertyDescriptor(0xD2A1, DataType.INT128, 0, 1, -1, -(1 << 100), FORM_RANGE, (-(1 << 127), 0, 1)),
                PropertyDescriptor(0xD2A2, DataType.UINT128, 0, 1, 0, (1 << 128) - 1),
                PropertyDescriptor(0xD2A3, DataType.STRING, 0, 1, "", "FE 50mm F1.8"),
                PropertyDescriptor(0xD2A4, DataType.ARRAY | DataType.INT8, 0, 1, (), (-1, 0, 1), FORM_ENUMERATION,
                                   ((), (-1, 0, 1))),
            ]
        return descriptors


class EmulatedUsbBackend(usb.backend.IBackend):
    """A pyusb backend with one device on it: the emulated A7 (054c:094c, PTP interface 6/1/1)."""

    def __init__(self, camera: EmulatedSonyA7):
        super().__init__()
        self.camera = camera
        self._endpoints = (
            SimpleNamespace(bLength=7, bDescriptorType=5, bEndpointAddress=BULK_IN_ENDPOINT, bmAttributes=2,
                            wMaxPacketSize=BULK_PACKET_BYTES, bInterval=0, bRefresh=0, bSynchAddress=0,
                            extra_descriptors=[]),
            SimpleNamespace(bLength=7, bDescriptorType=5, bEndpointAddress=BULK_OUT_ENDPOINT, bmAttributes=2,
                            wMaxPacketSize=BULK_PACKET_BYTES, bInterval=0, bRefresh=0, bSynchAddress=0,
                            extra_descriptors=[]),
            SimpleNamespace(bLength=7, bDescriptorType=5, bEndpointAddress=INTERRUPT_ENDPOINT, bmAttributes=3,
                            wMaxPacketSize=INTERRUPT_PACKET_BYTES, bInterval=4, bRefresh=0, bSynchAddress=0,
                            extra_descriptors=[]),
        )

    def enumerate_devices(self):
        if self.camera.connected:
            yield "emulated-sony-a7"

    def get_device_descriptor(self, dev):
        return SimpleNamespace(bLength=18, bDescriptorType=1, bcdUSB=0x0200, bDeviceClass=0, bDeviceSubClass=0,
                               bDeviceProtocol=0, bMaxPacketSize0=64, idVendor=SONY_USB_VENDOR_ID,
                               idProduct=SONY_A7_PC_REMOTE_PRODUCT_ID, bcdDevice=0x0100, iManufacturer=1,
                               iProduct=2, iSerialNumber=3, bNumConfigurations=1, address=7, bus=1,
                               port_number=1, port_numbers=(1,), speed=3)

    def get_configuration_descriptor(self, dev, config):
        return SimpleNamespace(bLength=9, bDescriptorType=2, wTotalLength=39, bNumInterfaces=1,
                               bConfigurationValue=1, iConfiguration=0, bmAttributes=0xC0, bMaxPower=250,
                               extra_descriptors=[])

    def get_interface_descriptor(self, dev, intf, alt, config):
        return SimpleNamespace(bLength=9, bDescriptorType=4, bInterfaceNumber=0, bAlternateSetting=0,
                               bNumEndpoints=3, bInterfaceClass=6, bInterfaceSubClass=1, bInterfaceProtocol=1,
                               iInterface=0, extra_descriptors=[])

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        return self._endpoints[ep]

    def open_device(self, dev):
        self.camera._require_connected()
        return dev

    def close_device(self, dev_handle):
        pass

    def set_configuration(self, dev_handle, config_value):
        self.camera._require_connected()

    def get_configuration(self, dev_handle):
        return 1

    def set_interface_altsetting(self, dev_handle, intf, altsetting):
        pass

    def claim_interface(self, dev_handle, intf):
        self.camera._require_connected()

    def release_interface(self, dev_handle, intf):
        pass

    def bulk_write(self, dev_handle, ep, intf, data, timeout):
        self.camera.bulk_out(bytes(data))
        return len(data)

    def bulk_read(self, dev_handle, ep, intf, buff, timeout):
        self.camera.read_timeout_ms = timeout
        return self._read(self.camera.bulk_in, buff, timeout)

    def intr_read(self, dev_handle, ep, intf, buff, timeout):
        return self._read(self.camera.interrupt_in, buff, timeout)

    def _read(self, pipe, buff, timeout_ms: int) -> int:
        """A read that finds nothing waits out its timeout on the virtual clock, as on a real bus."""
        try:
            return pipe(buff)
        except usb.core.USBTimeoutError:
            self.camera.clock.sleep(timeout_ms / 1000)
            raise

    def ctrl_transfer(self, dev_handle, bmRequestType, bRequest, wValue, wIndex, data, timeout):
        reply = self.camera.class_request(bRequest, bytes(data) if data is not None else b"")
        if bmRequestType & 0x80:
            memoryview(data).cast("B")[:len(reply)] = reply
            return len(reply)
        return len(data) if data is not None else 0

    def clear_halt(self, dev_handle, ep):
        self.camera.clear_halt(ep)

    def reset_device(self, dev_handle):
        self.camera._reset_state()

    def is_kernel_driver_active(self, dev_handle, intf):
        return False
