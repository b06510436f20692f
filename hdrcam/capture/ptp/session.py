"""PTP sessions and transactions: command, optional data phase (either direction), response.

OpenSession goes out with transaction id 0; later transactions count up from 1. A container for an earlier
transaction (a late answer to one that timed out and was cancelled) is dropped and the next one read, as
libgphoto2's ptp_transaction_new does ("suspecting old reply"); one for any other transaction is a protocol
error. DeviceBusy is retried with back-off. Each transfer may take TRANSACTION_TIMEOUT_S (20 s, OpenSession 8 s:
libgphoto2's USB_NORMAL_TIMEOUT and USB_START_TIMEOUT). A timeout cancels
the transaction (class request 0x64) and waits for the device to report OK; a stalled pipe (EPIPE) or a USB
I/O error (EIO) before any byte of a container arrived has its halts cleared and the device status checked
(libgphoto2's recovery). Either is retried, up to ``TRANSIENT_RETRIES`` times, for operations that only read; an
operation that changes the camera's state is not repeated blindly (a second notch step or button press would do
something else) and raises. A transaction stopped by anything else mid-flight (Ctrl-C or SIGTERM during a
download, a malformed container, an EIO after part of a container arrived: libgphoto2's ptp_usb_getdata then
fails with PTP_ERROR_IO) is cancelled too and raised, so the camera is not left streaming a data phase into the
next session. OpenSession that meets bytes of
no container, none in time (what a run killed mid-download leaves queued) or a stalled pipe (an I/O error to
libgphoto2's camera_init, which resets and tries OpenSession again) resets the device (class request 0x66),
clears the pipes' halts and opens once more. OpenSession answered InvalidTransactionID (a body still
holding that session id) is asked again with the next session ids, up to SESSION_IDS_TRIED of them, then once
more with the first after a device reset - libgphoto2's camera_init.
"""

from __future__ import annotations

import contextlib
import time
from hdrcam.capture.camera import CameraError
from hdrcam.capture.ptp import codes
from hdrcam.capture.ptp.codes import ContainerType, Operation, Response
from hdrcam.capture.ptp.container import Container, ContainerError, command, data
from hdrcam.capture.ptp.datasets import DeviceInfo, ObjectInfo
from hdrcam.capture.ptp.transport import Disconnected, Stalled, TransportTimeout, UsbTransport

READ_ONLY_OPERATIONS = {Operation.GET_DEVICE_INFO, Operation.GET_OBJECT_INFO, Operation.GET_OBJECT,
                        Operation.GET_DEVICE_PROP_DESC, Operation.GET_DEVICE_PROP_VALUE,
                        Operation.SONY_GET_ALL_DEVICE_PROP_DATA, Operation.SONY_GET_SDIO_EXT_DEVICE_INFO}
TRANSIENT_RETRIES = 2  # timeouts and stalls, per transaction
SESSION_IDS_TRIED = 10  # library.c camera_init: OpenSession answered InvalidTransactionID tries ids 1, 2, ... 10
STALE_CONTAINERS_MAX = 8  # late containers of earlier transactions dropped while waiting for this one's
STATUS_WAIT_S = 5.0  # for the device to report OK after a cancel or a cleared stall
TRANSACTION_TIMEOUT_S = 20.0  # per transfer once the session is open: libgphoto2's USB_NORMAL_TIMEOUT (library.c:
# "We have cameras where a response takes 15 seconds(!), so make post init timeouts longer")
OPEN_SESSION_TIMEOUT_S = 8.0  # OpenSession: libgphoto2's USB_START_TIMEOUT (a body that never answers is reset)


class ResponseError(CameraError):
    """The camera answered a transaction with a response code other than OK."""

    def __init__(self, operation: int, response_code: int):
        self.operation, self.response_code = operation, response_code
        super().__init__(f"the camera answered {codes.name(operation)} with {codes.name(response_code)}")


class ProtocolError(CameraError):
    """The camera sent something PTP does not allow at this point."""


def _is_earlier(reply_id: int, current_id: int) -> bool:
    """True when ``reply_id`` precedes ``current_id`` in the (wrapping, 32-bit) transaction sequence."""
    return 0 < (current_id - reply_id) % (1 << 32) < (1 << 31)


class Clock:
    """Wall-clock time and sleep; the emulated camera substitutes a virtual clock."""

    monotonic = staticmethod(time.monotonic)
    sleep = staticmethod(time.sleep)


class PtpSession:
    def __init__(self, transport: UsbTransport, *, clock: Clock | None = None, timeout_s: float = TRANSACTION_TIMEOUT_S,
                 busy_retries: int = 8, busy_backoff_s: float = 0.25):
        self.transport = transport
        self.clock = clock or Clock()
        self.timeout_s, self.busy_retries, self.busy_backoff_s = timeout_s, busy_retries, busy_backoff_s
        self._next_transaction_id = 0
        self.session_id: int | None = None  # the one the body accepted (None: one a previous run left open)
        self.is_open = False
        self.log: list[str] = []  # one line per retry, cancel or reset, for the capture manifest

    # -- transactions --------------------------------------------------------------------------------------
    def transact(self, operation: int, *params: int, data_out: bytes | None = None,
                 timeout_s: float | None = None) -> tuple[Container, bytes]:
        """Run one operation; returns (response, data received). Retries DeviceBusy; raises ResponseError."""
        busy = transient = 0
        while True:
            try:
                reply, payload = self._transaction(operation, params, data_out, timeout_s or self.timeout_s)
            except (TransportTimeout, Stalled) as error:
                if isinstance(error, Stalled):
                    self._recover_from_stall()
                    recovery = "cleared the halt"
                else:
                    self._cancel_in_flight()
                    recovery = "cancelled"
                if operation not in READ_ONLY_OPERATIONS or transient >= TRANSIENT_RETRIES:
                    raise
                transient += 1
                self.log.append(f"{codes.name(operation)}: {error}; {recovery} and retried ({transient})")
                continue
            if reply.code == Response.DEVICE_BUSY and busy < self.busy_retries:
                busy += 1
                self.log.append(f"{codes.name(operation)}: device busy, retry {busy}")
                self.clock.sleep(self.busy_backoff_s * 2 ** min(busy - 1, 4))
                continue
            if reply.code != Response.OK:
                raise ResponseError(operation, reply.code)
            return reply, payload

    def _transaction(self, operation: int, params, data_out: bytes | None,
                     timeout_s: float) -> tuple[Container, bytes]:
        transaction_id = self._take_transaction_id(operation)
        try:
            return self._phases(operation, transaction_id, params, data_out, int(timeout_s * 1000))
        except (TransportTimeout, Stalled, Disconnected):
            raise  # transact() recovers from the first two; the third has no camera to tell
        except BaseException:  # interrupted or garbled mid-flight: the camera must not go on sending its data
            with contextlib.suppress(CameraError):
                self._cancel_in_flight()
            raise

    def _phases(self, operation: int, transaction_id: int, params, data_out: bytes | None,
                timeout_ms: int) -> tuple[Container, bytes]:
        self.transport.send(command(operation, transaction_id, *params), timeout_ms)
        if data_out is not None:
            self.transport.send(data(operation, transaction_id, data_out), timeout_ms)
        payload = b""
        reply = self._receive(operation, transaction_id, timeout_ms)
        if reply.kind == ContainerType.DATA:
            self._check_matches(reply, operation, transaction_id)
            payload = reply.payload
            reply = self._receive(operation, transaction_id, timeout_ms)
        if reply.kind != ContainerType.RESPONSE:
            raise ProtocolError(f"expected a response to {codes.name(operation)}, got a {reply.kind.name.lower()} "
                                "container")
        self._check_matches(reply, operation, transaction_id)
        return reply, payload

    def _receive(self, operation: int, transaction_id: int, timeout_ms: int) -> Container:
        """The next container for this transaction, dropping late ones of earlier transactions (and events
        sent on the bulk pipe), a bounded number of times."""
        for _ in range(STALE_CONTAINERS_MAX):
            reply = self.transport.receive(timeout_ms)
            stale = _is_earlier(reply.transaction_id, transaction_id) or (  # OpenSession: a previous session's
                operation == Operation.OPEN_SESSION and reply.transaction_id != transaction_id)
            if reply.kind == ContainerType.EVENT or stale:
                self.log.append(f"{codes.name(operation)}: dropped a late {reply.kind.name.lower()} container "
                                f"({codes.name(reply.code)}, transaction {reply.transaction_id})")
                continue
            return reply
        raise ProtocolError(f"the camera sent {STALE_CONTAINERS_MAX} containers of other transactions while "
                            f"{codes.name(operation)} (transaction {transaction_id}) was in flight")

    def _take_transaction_id(self, operation: int) -> int:
        if operation == Operation.OPEN_SESSION:
            self._next_transaction_id = 1
            return 0
        transaction_id = self._next_transaction_id
        self._next_transaction_id = (transaction_id + 1) % 0xFFFFFFFF or 1
        return transaction_id

    @staticmethod
    def _check_matches(reply: Container, operation: int, transaction_id: int) -> None:
        if reply.transaction_id != transaction_id:
            raise ProtocolError(f"the camera answered transaction {reply.transaction_id} while "
                                f"{codes.name(operation)} (transaction {transaction_id}) was in flight")
        if reply.kind == ContainerType.DATA and reply.code != operation:
            raise ProtocolError(f"data for {codes.name(reply.code)} arrived during {codes.name(operation)}")

    def _cancel_in_flight(self) -> None:
        """Cancel the last transaction and wait for the device to be idle again."""
        transaction_id = self._next_transaction_id - 1
        try:
            self.transport.cancel(transaction_id)
            self._wait_for_idle("a cancel")
        finally:
            self.transport.clear_halts()

    def _recover_from_stall(self) -> None:
        """Clear both bulk pipes' halts, then wait for the device to report OK (what libgphoto2 does on EPIPE)."""
        self.transport.clear_halts()
        self._wait_for_idle("a stalled pipe")

    def _wait_for_idle(self, after: str) -> None:
        deadline = self.clock.monotonic() + STATUS_WAIT_S
        while self.transport.status() != Response.OK:
            if self.clock.monotonic() > deadline:
                raise CameraError(f"the camera stayed busy after {after}; switch it off and on")
            self.clock.sleep(0.1)

    # -- operations ----------------------------------------------------------------------------------------
    def open(self, session_id: int = 1) -> None:
        try:
            try:
                self._open_some_session(session_id)
            except (ContainerError, ProtocolError, TransportTimeout, Stalled) as error:  # another run's leftovers
                self.log.append(f"OpenSession met {error}; reset the device")
                self._reset_device()
                self._open_some_session(session_id)
                self.log.append("OpenSession after the reset: opened")
            except ResponseError as error:
                if error.response_code != Response.INVALID_TRANSACTION_ID:
                    raise
                self.log.append(f"OpenSession refused session ids {session_id} to "
                                f"{session_id + SESSION_IDS_TRIED - 1}; reset the device")
                self._reset_device()
                self.transact(Operation.OPEN_SESSION, session_id, timeout_s=OPEN_SESSION_TIMEOUT_S)
                self.session_id = session_id
        except ResponseError as error:
            if error.response_code != Response.SESSION_ALREADY_OPEN:  # benign: a previous run left it open
                raise
        self.is_open = True

    def _open_some_session(self, first_id: int) -> None:
        """OpenSession with ``first_id``, then the next ids while the body answers InvalidTransactionID."""
        for session_id in range(first_id, first_id + SESSION_IDS_TRIED):
            try:
                self.transact(Operation.OPEN_SESSION, session_id, timeout_s=OPEN_SESSION_TIMEOUT_S)
            except ResponseError as error:
                if error.response_code != Response.INVALID_TRANSACTION_ID or \
                        session_id == first_id + SESSION_IDS_TRIED - 1:
                    raise
                self.log.append(f"OpenSession({session_id}) answered {codes.name(error.response_code)}; trying "
                                f"session id {session_id + 1}")
                continue
            self.session_id = session_id
            return

    def _reset_device(self) -> None:
        self.transport.reset()
        self.transport.clear_halts()
        self._wait_for_idle("a device reset")

    def close(self) -> None:
        if self.is_open:
            self.is_open = False
            try:
                self.transact(Operation.CLOSE_SESSION)
            except CameraError:
                pass  # closing must not hide the error that made us close

    def device_info(self) -> DeviceInfo:
        return DeviceInfo.unpack(self.transact(Operation.GET_DEVICE_INFO)[1])

    def object_info(self, handle: int) -> ObjectInfo:
        return ObjectInfo.unpack(self.transact(Operation.GET_OBJECT_INFO, handle)[1])

    def get_object(self, handle: int, timeout_s: float = 60.0) -> bytes:
        return self.transact(Operation.GET_OBJECT, handle, timeout_s=timeout_s)[1]
