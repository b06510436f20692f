"""PTP over USB bulk pipes (PIMA 15740 USB still-image class), on pyusb.

A transaction's phases are containers on the bulk pipes; a transfer whose length is an exact multiple of the
endpoint's wMaxPacketSize is ended by a zero-length packet (ZLP), in both directions. Reading follows
libgphoto2's ptp_usb_getdata (camlibs/ptp2/usb.c): the first read is one packet's worth, the rest of a
container is read until its length field is satisfied however short each read is, bytes read past its end (a
device that sent no ZLP, or data and response in one transfer) are kept for the next container, and a
zero-length read (a ZLP left over) is skipped; a data container whose length field is 0xFFFFFFFF (size not
known in advance) is read until a short packet or a ZLP, as ptp_usb_getdata does. A device that sends a data
container's 12-byte header in a transfer of its own gets the host's data phases split the same way from then on
(ptp_usb_getdata sets params->split_header_data, ptp_usb_senddata honours it). A command whose write is refused
(a stall, or an I/O error with the device still there) is written once more after clearing the OUT endpoint's
halt, as ptp_usb_sendreq does: the device never took it. Events arrive on the
interrupt pipe; they are hints only, so a packet that is not a valid event container is dropped, never raised.
Class requests on the control pipe cancel a transaction, reset the device and read its status. USB failures
become ``TransportTimeout``, ``Stalled`` (EPIPE, and EIO before any byte of a container arrived: a transfer
error with the device still there, which libgphoto2's usb.c recovers from as from a stall, clearing the IN halt
and reading again) or ``Disconnected`` (ENODEV, ENOENT). An EIO once bytes of a container arrived is a plain
``CameraError``: the transfer is broken (libgphoto2's ptp_usb_getdata retries a read "only once and only if we
did not read anything yet", else fails with PTP_ERROR_IO), and re-sending the transaction would read the rest
of the old data as the next container; the session cancels the transaction instead. An EIO is also what an
unplug gives before the kernel sees the device go (Linux URB -EPROTO, LIBUSB_ERROR_IO), so after one the device
is asked for its status: failing that too (ENODEV, ENOENT, EIO), it is ``Disconnected``. On the interrupt pipe
an EIO from a device still there clears that endpoint's halt and reads as no event.
"""

from __future__ import annotations

import contextlib
import errno
import struct

import usb.core
import usb.util

from hdrcam.capture.camera import CameraError
from hdrcam.capture.ptp.codes import CANCEL_EVENT_CODE, PTP_INTERFACE, ClassRequest, ContainerType
from hdrcam.capture.ptp.container import HEADER_SIZE, Container, ContainerError, parse_header

READ_CHUNK_BYTES = 1 << 20  # a whole number of packets for any wMaxPacketSize
FIRST_READ_MIN_BYTES = 512  # libgphoto2 reads sizeof(PTPUSBBulkContainer) = 512 bytes first
EMPTY_READS_MAX = 4  # zero-length reads (left-over ZLPs) skipped in a row before giving up
UNKNOWN_LENGTH = 0xFFFFFFFF  # a data container's length field when the device does not know its size
EVENT_MAX_BYTES = 24  # an event container: header and 3 parameters (libgphoto2's PTPUSBEventContainer)
EVENT_REST_TIMEOUT_MS = 150  # for the rest of an event sent in several transfers (libgphoto2's PTP2_FAST_TIMEOUT)
PROBE_TIMEOUT_MS = 2000  # the status request asking, after an I/O error, whether the device is still there
_CLASS_OUT = usb.util.build_request_type(usb.util.CTRL_OUT, usb.util.CTRL_TYPE_CLASS, usb.util.CTRL_RECIPIENT_INTERFACE)
_CLASS_IN = usb.util.build_request_type(usb.util.CTRL_IN, usb.util.CTRL_TYPE_CLASS, usb.util.CTRL_RECIPIENT_INTERFACE)


class TransportTimeout(CameraError):
    """The camera did not answer within the timeout."""


class Stalled(CameraError):
    """An endpoint answered with a STALL (EPIPE), or a transfer failed with an I/O error (EIO) before any byte of
    a container arrived, the device still answering its status request: its halt must be cleared before the pipe
    works again (libgphoto2 usb.c ptp_usb_getdata / ptp_usb_getpacket: clear the IN endpoint's halt and retry)."""


class Disconnected(CameraError):
    """The camera went away (cable, power, or it left PC-remote mode)."""


def is_ptp_interface(interface) -> bool:
    return (interface.bInterfaceClass, interface.bInterfaceSubClass, interface.bInterfaceProtocol) == PTP_INTERFACE


class UsbTransport:
    """Bulk-in, bulk-out and interrupt-in endpoints of a device's PTP interface."""

    def __init__(self, device: usb.core.Device):
        self.device = device
        try:
            if device.get_active_configuration() is None:
                device.set_configuration()
        except usb.core.USBError:
            device.set_configuration()
        configuration = device.get_active_configuration()
        interface = usb.util.find_descriptor(configuration, custom_match=is_ptp_interface)
        if interface is None:
            raise CameraError("the USB device has no PTP (still image) interface")
        self.interface_number = interface.bInterfaceNumber
        self._detach_kernel_driver()
        usb.util.claim_interface(device, self.interface_number)

        def endpoint(direction, kind):
            return usb.util.find_descriptor(interface, custom_match=lambda e: (
                usb.util.endpoint_direction(e.bEndpointAddress) == direction
                and usb.util.endpoint_type(e.bmAttributes) == kind))

        self.bulk_in = endpoint(usb.util.ENDPOINT_IN, usb.util.ENDPOINT_TYPE_BULK)
        self.bulk_out = endpoint(usb.util.ENDPOINT_OUT, usb.util.ENDPOINT_TYPE_BULK)
        self.interrupt_in = endpoint(usb.util.ENDPOINT_IN, usb.util.ENDPOINT_TYPE_INTR)
        if self.bulk_in is None or self.bulk_out is None:
            raise CameraError("the PTP interface lacks its bulk endpoints")
        self._pending = b""  # bytes read past the end of the last container, the start of the next one
        self.split_header_data = False  # the device sent a data container's header alone: split ours too

    def _detach_kernel_driver(self) -> None:
        try:
            if self.device.is_kernel_driver_active(self.interface_number):
                self.device.detach_kernel_driver(self.interface_number)
        except (NotImplementedError, usb.core.USBError):
            pass  # not on Linux, or the backend does not manage kernel drivers

    def close(self) -> None:
        try:
            usb.util.release_interface(self.device, self.interface_number)
            usb.util.dispose_resources(self.device)
        except usb.core.USBError:
            pass

    # -- bulk ------------------------------------------------------------------------------------------------
    def send(self, container: Container, timeout_ms: int) -> None:
        """Write one container, then a ZLP if its length is a multiple of the packet size. Once the device has sent
        a data container's 12-byte header alone (``split_header_data``), a data container goes out as its header
        alone, then its payload (ZLP after the payload when that is whole packets), as libgphoto2's
        ptp_usb_senddata writes to such a device."""
        packet = container.pack()
        if container.kind == ContainerType.COMMAND:
            self._send_command(packet, timeout_ms)
            return
        transfers = [packet]
        if self.split_header_data and container.kind == ContainerType.DATA and len(packet) > HEADER_SIZE:
            transfers = [packet[:HEADER_SIZE], packet[HEADER_SIZE:]]
        with _usb_errors(self, "sending", timeout_ms):
            for transfer in transfers:
                self.bulk_out.write(transfer, timeout_ms)
        self._end_transfer(transfers[-1], timeout_ms)

    def _send_command(self, packet: bytes, timeout_ms: int) -> None:
        """Write a command container (one short packet); a write refused by a stalled pipe or an I/O error, the
        device still there, has the OUT endpoint's halt cleared and is written once more (libgphoto2 usb.c
        ptp_usb_sendreq: the device never took the request, so sending it again repeats nothing)."""
        try:
            self.bulk_out.write(packet, timeout_ms)
        except usb.core.USBError as error:
            translated = self._translate(error, "sending", timeout_ms)
            if not isinstance(translated, Stalled):
                raise translated from None
            with contextlib.suppress(usb.core.USBError):
                self.device.clear_halt(self.bulk_out)
            with _usb_errors(self, "sending", timeout_ms):
                self.bulk_out.write(packet, timeout_ms)
        self._end_transfer(packet, timeout_ms)  # a ZLP only with packets of 32 bytes or less (full speed)

    def _end_transfer(self, last: bytes, timeout_ms: int) -> None:
        """A zero-length packet after ``last``, the transfer just written, when it filled whole packets: the device
        would otherwise wait for more of it."""
        if len(last) % self.bulk_out.wMaxPacketSize == 0:
            with _usb_errors(self, "sending", timeout_ms):
                self.bulk_out.write(b"", timeout_ms)

    def receive(self, timeout_ms: int) -> Container:
        """Read one container (data or response), as libgphoto2's ptp_usb_getdata does.

        The first read asks for one packet's worth (at least 512 bytes); the rest is read in whole packets
        until the container's length is reached, however few bytes each read returns (one packet per read,
        a 12-byte header sent alone). Bytes past the container's end are kept as the start of the next one;
        zero-length reads (a ZLP ending an earlier transfer of whole packets) are skipped. A short packet (a
        read that is not a whole number of packets) ends a transfer: a container still incomplete there is
        damaged (CameraError), except after a read of exactly its 12-byte header (the header sent alone). A data
        container of UNKNOWN_LENGTH is read one packet at a time until a read comes back under one packet (a short
        packet or a ZLP), as ptp_usb_getdata's read-until-short-packet mode does: a larger read could not tell a
        ZLP that ended it early from a backend that returns less than asked. Its first read ends it only if it
        was not a whole number of packets and not the header alone.
        """
        packet_size = self.bulk_in.wMaxPacketSize or 512
        first_read = packet_size * max(1, -(-FIRST_READ_MIN_BYTES // packet_size))
        buffer, self._pending = bytearray(self._pending), b""
        with _usb_errors(self, "waiting for the camera", timeout_ms, received=buffer):
            chunk = b""
            while len(buffer) < HEADER_SIZE:
                chunk = self._read(first_read, timeout_ms)
                buffer += chunk
            length, kind = parse_header(buffer)[:2]
            if kind == ContainerType.DATA and length > HEADER_SIZE and len(chunk) == len(buffer) == HEADER_SIZE:
                self.split_header_data = True  # ptp_usb_getdata's autodetection of split header/data devices
            if length == UNKNOWN_LENGTH and kind == ContainerType.DATA:
                ended = len(chunk) % packet_size != 0 and len(buffer) != HEADER_SIZE
                while not ended:
                    chunk = bytes(self.bulk_in.read(packet_size, timeout_ms))
                    buffer += chunk
                    ended = len(chunk) < packet_size
                buffer[:4] = struct.pack("<I", len(buffer))
                return Container.unpack(bytes(buffer))
            while len(buffer) < length:
                if chunk and len(chunk) % packet_size and len(buffer) != HEADER_SIZE:
                    raise CameraError(f"the camera sent {len(buffer)} bytes of a {length}-byte container")
                remaining = length - len(buffer)
                chunk = self._read(min(READ_CHUNK_BYTES, -(-remaining // packet_size) * packet_size), timeout_ms)
                buffer += chunk
        if len(buffer) > length:
            self._pending = bytes(buffer[length:])
            del buffer[length:]
        return Container.unpack(bytes(buffer))

    def _read(self, size: int, timeout_ms: int) -> bytes:
        """One bulk-in read of at most ``size`` bytes that returns data; zero-length reads are skipped."""
        for _ in range(EMPTY_READS_MAX):
            chunk = bytes(self.bulk_in.read(size, timeout_ms))
            if chunk:
                return chunk
        raise CameraError(f"the camera sent {EMPTY_READS_MAX} zero-length packets in a row instead of a container")

    # -- interrupt ---------------------------------------------------------------------------------------------
    def read_event(self, timeout_ms: int) -> Container | None:
        """One event container, or None if none arrives within the timeout or the packet is not a valid event
        (events only wake waits up; libgphoto2's ptp_usb_event reads at most 24 bytes and never fails a
        capture on a bad one). An event container longer than its first transfer is completed from the next
        ones, EVENT_REST_TIMEOUT_MS each, as ptp_usb_event's "incremental read" does. An I/O error with the
        device still there is None too, after clearing the interrupt endpoint's halt, as libgphoto2's usb.c
        clears the IN endpoint's halt after GP_ERROR_IO_READ; one with the device gone is ``Disconnected``."""
        if self.interrupt_in is None:
            return None
        packet = self._read_interrupt(timeout_ms)
        if len(packet) >= 8:  # usb.c: an event longer than what was read is read on, to 24 bytes at most
            length, kind = struct.unpack_from("<IH", packet)
            while kind == ContainerType.EVENT and len(packet) < min(length, EVENT_MAX_BYTES):
                rest = self._read_interrupt(EVENT_REST_TIMEOUT_MS)
                if not rest:
                    break
                packet += rest
        try:
            return Container.unpack(packet[:parse_header(packet)[0]])
        except ContainerError:
            return None

    def _read_interrupt(self, timeout_ms: int) -> bytes:
        """One interrupt-in transfer; empty on a timeout, or on an I/O error with the device still there (after
        clearing the endpoint's halt); ``Disconnected`` with the device gone."""
        try:
            return bytes(self.interrupt_in.read(max(self.interrupt_in.wMaxPacketSize, EVENT_MAX_BYTES), timeout_ms))
        except usb.core.USBError as error:
            translated = self._translate(error, "reading events", timeout_ms)
            if isinstance(translated, TransportTimeout):
                return b""
            if error.errno == errno.EIO and isinstance(translated, Stalled):
                with contextlib.suppress(usb.core.USBError):
                    self.device.clear_halt(self.interrupt_in)
                return b""
            raise translated from None

    # -- control (class requests) ---------------------------------------------------------------------------
    def cancel(self, transaction_id: int, timeout_ms: int = 2000) -> None:
        self._pending = b""  # whatever was read ahead belongs to the cancelled transaction
        with _usb_errors(self, "cancelling", timeout_ms):
            self.device.ctrl_transfer(_CLASS_OUT, ClassRequest.CANCEL, 0, self.interface_number,
                                      struct.pack("<HI", CANCEL_EVENT_CODE, transaction_id), timeout_ms)

    def reset(self, timeout_ms: int = 2000) -> None:
        with _usb_errors(self, "resetting", timeout_ms):
            self.device.ctrl_transfer(_CLASS_OUT, ClassRequest.DEVICE_RESET, 0, self.interface_number, None,
                                      timeout_ms)

    def status(self, timeout_ms: int = 2000) -> int:
        """The device's status response code (0x2001 OK, 0x2019 busy)."""
        with _usb_errors(self, "reading the status", timeout_ms):
            reply = bytes(self.device.ctrl_transfer(_CLASS_IN, ClassRequest.GET_DEVICE_STATUS, 0,
                                                    self.interface_number, 20, timeout_ms))
        if len(reply) < 4:
            raise CameraError("the camera's status reply is too short")
        return struct.unpack_from("<HH", reply)[1]

    def _translate(self, error: usb.core.USBError, action: str, timeout_ms: int, received: int = 0) -> CameraError:
        """``error`` as a camera error; an EIO is a disconnect when the device's status request (class request
        0x67, libgphoto2's ptp_usb_control_get_device_status) fails too with ENODEV, ENOENT or EIO, and no stall
        once ``received`` bytes of a container arrived (module docstring)."""
        if error.errno == errno.EIO:
            try:
                self.device.ctrl_transfer(_CLASS_IN, ClassRequest.GET_DEVICE_STATUS, 0, self.interface_number, 20,
                                          PROBE_TIMEOUT_MS)
            except usb.core.USBError as probe_error:
                if probe_error.errno in (errno.ENODEV, errno.ENOENT, errno.EIO) or "No such device" in str(probe_error):
                    return Disconnected(f"the camera disconnected while {action} (an I/O error, then its status "
                                        f"request failed: {probe_error})")
            if received:
                return CameraError(f"USB I/O error while {action}, after {received} bytes of a container: the "
                                   "transfer is broken, so the transaction is cancelled, not repeated")
        return _translate(error, action, timeout_ms)

    def clear_halts(self) -> None:
        self._pending = b""
        for endpoint in (self.bulk_in, self.bulk_out):
            try:
                self.device.clear_halt(endpoint)
            except usb.core.USBError:
                pass


class _usb_errors:
    """Context manager turning pyusb errors into camera errors that say what was happening; ``received`` is the
    buffer a container is being read into (filled in place), whose length decides what an EIO means."""

    def __init__(self, transport: UsbTransport, action: str, timeout_ms: int, received: bytes | bytearray = b""):
        self.transport, self.action, self.timeout_ms, self.received = transport, action, timeout_ms, received

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        if isinstance(error, usb.core.USBError):
            raise self.transport._translate(error, self.action, self.timeout_ms, len(self.received)) from None
        return False


def _translate(error: usb.core.USBError, action: str, timeout_ms: int | None = None) -> CameraError:
    if isinstance(error, usb.core.USBTimeoutError) or error.errno == errno.ETIMEDOUT:
        within = f" within {timeout_ms / 1000:g} s" if timeout_ms is not None else ""
        return TransportTimeout(f"the camera did not answer{within} while {action}")
    if error.errno == errno.EPIPE:
        return Stalled(f"the camera stalled a pipe while {action}")
    if error.errno == errno.EIO:
        return Stalled(f"USB I/O error while {action} ({error})")
    if error.errno in (errno.ENODEV, errno.ENOENT) or "No such device" in str(error):
        return Disconnected(f"the camera disconnected while {action} ({error})")
    return CameraError(f"USB error while {action}: {error}")
