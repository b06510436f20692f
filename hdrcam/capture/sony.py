"""``--camera usb``: a Sony A7 in PC-remote mode over PTP/USB, with Sony's SDIO extension (REFERENCE.md sec. 4).

Life cycle: find the camera (054c:*, PTP interface), OpenSession, GetDeviceInfo (vendor extension 0x11, and
0x9202 among its operations, without which libgphoto2 skips the handshake: no PC Remote mode), the SDIO
handshake 0x9201(1), 0x9201(2), 0x9202(0xC8) -> protocol version, 0x9201(3), then 0x9209 for every property
descriptor. The A7 speaks protocol "mode 2": shutter and ISO cannot be set absolutely, only
stepped one notch at a time with 0x9207; each step is polled through 0x9209 until the value lands, and an
overshoot is stepped back. An empty 0x9202 answer is asked again (Sony's PTP documentation says to retry;
the body is still starting its PC-remote mode); if it stays empty the handshake goes on with the version
unknown, as libgphoto2's ptp_sony_get_vendorpropcodes does ("No special operations sent?") - a body not in
PC-remote mode fails at 0x9209 anyway. The handshake refuses, before any shot, a body not on M (0x500E), recording
JPEG only (0x5004 without its RAW bit) or on Bulb, and records focus mode, drive mode and firmware.

Newer bodies set shutter and ISO absolutely. What libgphoto2 does (read in camlibs/ptp2 of gphoto/libgphoto2 at
ef42524a and 00539518; the codes from ptp.h): (a) it decides per property with config.c have_prop(): the code is in
DeviceInfo's DevicePropertiesSupported, which library.c fixup_cached_deviceinfo extends with the property codes
((code & 0x7000) == 0x5000) of the 0x9202(0xC8) answer (ptp.c ptp_sony_get_vendorpropcodes: u16 version, then
one or two u32-counted u16 lists). ShutterSpeed2 is 0xD229 and ISO2 0xD226; the protocol version is not looked
at (no check of 0x12C / 300 decides this). (b) config.c _put_Sony_ShutterSpeed ("new style") sends 0x9205
SetControlDeviceA on 0xD229 with the UINT32 (numerator << 16) | denominator; its ISO menu entry for 0xD226 comes
before 0xD21E's ("the older Sony do not have d226, so it should pick the next entry") and _put_Sony_ISO2 sends
0x9205 on 0xD226 with the UINT32 ISO. (c) it does not fall back: the 0x9205 result is returned as the setting's
result (translate_ptp_result), an error ends the set, and stepping (0x9207 on 0xD20D / 0xD21E) is used only when
the code is not listed. (d) it neither waits nor reads back after the 0x9205; _get_Sony_ShutterSpeed reads 0xD229's
descriptor (via 0x9209) when listed, and the ISO entry reads 0xD226's. So here: a body listing 0xD229 (0xD226) has
its shutter (ISO) read from and set through that code with one 0x9205, a value its enumeration lists; a refusal
is a CameraError with no stepping. hdrcam then polls 0x9209 until the value reads back (within STEP_TIMEOUT_S,
else CameraError), which libgphoto2 does not: a frame must be taken at the setting recorded for it. A body that
lists neither code (the A7) is stepped as before.

After the handshake the priority mode (0xD25A) is set to "application" with 0x9205, as libgphoto2 does;
a body that does not know it answers with an error, which is logged and ignored.

Capture, as libgphoto2's camera_sony_capture: drain the events queued since the last shot and any image still
in memory; half press; in an AF mode wait until FocusFound (0xD213) turns 2 (or 3, as libgphoto2 accepts for
the RX0; never in MF), with a timeout; full press, release both; then wait until 0xD215 says the image is
ready. libgphoto2 reads that property two ways: its capture path (camera_sony_capture) takes >= 0x8000 as
ready, its event loop (camera_wait_for_event) 0x8000 | count with a count of at least 1, i.e. 0x8000 alone as
none. So an image is ready above 0x8000, and at 0x8000 exactly only if 0xD215 did not already read 0x8000
before the release; for the next object of the same shot (RAW + JPEG) only if 0x8000 alone announced the one
before (a body that announced it with a count means "empty" by 0x8000); a count without the flag (the body
still writing: "also turns to 1") never is. Events (0xC201 ObjectAdded) only wake the wait, they are not taken
as proof: a stale or early one would make the camera answer GetObjectInfo with InvalidObjectHandle, and
premature access can crash the firmware; 0xFFFFC001 is asked for on one only when 0xD215 stays 0 for a second
after it, or when the wait runs out after one arrived (a body announcing images by the event alone: "needed on
older cameras like the a58"). Then GetObjectInfo and GetObject on 0xFFFFC001; with RAW + JPEG the object that
is not RAW is dropped and the next one awaited the same way. All vendor quirks live here; the generic PTP layer
knows nothing of Sony.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import importlib
import math
import os
import struct
from collections.abc import Iterator
from pathlib import Path

import usb.backend
import usb.core

from hdrcam.capture.camera import CameraError, CameraNotFound, CapturedFrame, ExposureSettings
from hdrcam.capture.notches import ISO_AUTO, ISO_VALUES, SHUTTER_NOTCHES, iso_setting, nearest_shutter, shutter_from_ptp
from hdrcam.capture.ptp.codes import (DRIVE_MODE_NAMES, FOCUS_MODE_NAMES, MTP_VENDOR_EXTENSION_ID,
                                      SINGLE_SHOT_DRIVE, SONY_EXPOSURE_MODE_M, SONY_FOCUS_FOUND_VALUES,
                                      SONY_FOCUS_MANUAL, SONY_IN_MEMORY_OBJECT, SONY_ISO_NR_SHIFT, SONY_MANUFACTURER,
                                      SONY_PENDING_IMAGE_FLAG, SONY_PRIORITY_APPLICATION, SONY_PROTOCOL_MODE_2,
                                      SONY_RAW_FORMAT, SONY_RAW_QUALITY_FLAG, SONY_USB_VENDOR_ID,
                                      SONY_VENDOR_EXTENSION_ID, STARTUP_WAIT_MODELS, STARTUP_WAIT_S, Event,
                                      Operation, Property, Response)
from hdrcam.capture.ptp.datasets import (FORM_ENUMERATION, PropertyDescriptor, unpack_sony_properties,
                                         unpack_sony_vendor_codes)
from hdrcam.capture.ptp.session import Clock, PtpSession, ResponseError
from hdrcam.capture.ptp.transport import Stalled, TransportTimeout, UsbTransport, is_ptp_interface
from hdrcam.io.atomic import write_bytes_atomic
from hdrcam.io.raw import read_raw

STEP_POLL_INTERVAL_S = 0.1
STEP_TIMEOUT_S = 3.0  # a notch lands in ~0.7 s on an A7
CAPTURE_TIMEOUT_S = 35.0  # plus the exposure time
FOCUS_TIMEOUT_S = 5.0  # from the half press, in AF modes
UNREPORTED_GRACE_S = 1.0  # 0xD215 left at 0 this long after an ObjectAdded: the body announces by the event alone
FOCUS_POLL_INTERVAL_S = 0.05
SDIO_INFO_ATTEMPTS = 10  # an empty 0x9202 answer is asked again this many times, SDIO_RETRY_S apart
SDIO_RETRY_S = 0.2
OBJECTS_PER_SHOT = 3  # RAW + JPEG gives two
STALE_EVENTS_MAX = 64  # events drained at the start of a shot, at most
DRAIN_MAX_OBJECTS = 32  # images left in memory fetched and dropped before a shot, at most
USB_BACKEND_VARIABLE = "HDRCAM_USB_BACKEND"
_PRESS, _RELEASE = 2, 1
_MFNR_MESSAGE = ("ISO is set with Multi Frame Noise Reduction (the body merges several exposures): choose a plain "
                 "ISO value in the camera's menu")


def usb_backend_from_environment():
    """The pyusb backend named by HDRCAM_USB_BACKEND=module:callable (None when unset: libusb).

    The callable takes no arguments and returns a usb.backend.IBackend - any simulated camera put on the bus
    this way runs through the same code as a real one (``--camera usb``)."""
    spec = os.environ.get(USB_BACKEND_VARIABLE, "").strip()
    if not spec:
        return None
    module_name, _, attribute = spec.partition(":")
    if not module_name or not attribute:
        raise CameraNotFound(f"{USB_BACKEND_VARIABLE}={spec!r}: give module:callable, e.g. mypackage.fake:backend")
    try:
        factory = getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as error:
        raise CameraNotFound(f"{USB_BACKEND_VARIABLE}={spec!r}: cannot load it ({error})") from None
    if not callable(factory):
        raise CameraNotFound(f"{USB_BACKEND_VARIABLE}={spec!r} is a {type(factory).__name__}, not a callable that "
                             "returns a usb.backend.IBackend")
    try:
        backend = factory()
    except Exception as error:  # the outside simulator's own failure, reported in one line
        raise CameraNotFound(f"{USB_BACKEND_VARIABLE}={spec!r} failed: {type(error).__name__}: {error}") from None
    if not isinstance(backend, usb.backend.IBackend):
        raise CameraNotFound(f"{USB_BACKEND_VARIABLE}={spec!r} returned {type(backend).__name__}, not a "
                             "usb.backend.IBackend")
    return backend


def find_sony_camera(backend=None) -> usb.core.Device:
    """The first Sony USB device with a PTP interface; CameraNotFound with advice otherwise."""
    def has_ptp_interface(device) -> bool:
        try:
            return any(is_ptp_interface(interface) for configuration in device for interface in configuration)
        except usb.core.USBError:
            return False

    try:
        device = usb.core.find(idVendor=SONY_USB_VENDOR_ID, custom_match=has_ptp_interface, backend=backend)
    except usb.core.NoBackendError:
        raise CameraNotFound("no USB backend: install libusb (e.g. 'pip install libusb-package') to reach a "
                             "real camera") from None
    if device is None:
        raise CameraNotFound("no Sony camera found on USB: connect the A7, set USB Connection to 'PC Remote', "
                             "and check the cable (or use --camera sim)")
    return device


class TerminalLensCover:
    """Asks the user at the terminal to cover or uncover the lens when that must change."""

    def __init__(self):
        self.covered = False

    def __call__(self, covered: bool) -> None:
        if covered != self.covered:
            try:
                input("Cover the lens for dark frames, then press Enter " if covered else
                      "Uncover the lens, then press Enter ")
            except EOFError:
                raise CameraError("dark frames need the lens covered by hand, and hdrcam asks for it on standard "
                                  "input, which has ended (no terminal?): run the capture from a terminal, or give "
                                  "an Enter for each prompt on standard input") from None
            self.covered = covered


def _notch(value: int):
    try:
        return shutter_from_ptp(value)
    except ValueError as error:
        raise CameraError(f"{error}: set a shutter time on the camera (mode dial on M)") from None


def _step_data(direction: int) -> bytes:
    """0x9207 payload for one notch: u8 +1 (0x01) or -1 (0xFF)."""
    return struct.pack("<b", direction)


class SonyA7Camera:
    """A Sony A7 over USB (Camera protocol)."""

    suffix_default = ".arw"

    def __init__(self, device: usb.core.Device | None = None, *, backend=None, clock: Clock | None = None,
                 cover_lens=None):
        self._device = device if device is not None else find_sony_camera(backend or usb_backend_from_environment())
        self.clock = clock or Clock()
        self.cover_lens = cover_lens or TerminalLensCover()
        self.model = "Sony camera"
        self.model_code = ""  # DeviceInfo's model alone, e.g. ILCE-7RM4
        self._started_at: float | None = None  # when the session opened (libgphoto2 counts from camera_init)
        self.session: PtpSession | None = None
        self.properties: dict[int, PropertyDescriptor] = {}
        self._list_cut: str | None = None  # why the last 0x9209 answer's list ended early, if it did
        self.protocol_version = 0
        self.vendor_properties: frozenset[int] = frozenset()  # the property codes 0x9202 listed
        self.firmware = ""
        self._step_sign = {Property.SONY_SHUTTER_SPEED: 1, Property.SONY_ISO: 1}

    # -- life cycle ------------------------------------------------------------------------------------------
    def __enter__(self) -> "SonyA7Camera":
        self.session = PtpSession(UsbTransport(self._device), clock=self.clock)
        try:
            self._handshake()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc) -> None:
        if self.session is not None:
            self.session.close()
            self.session.transport.close()
            self.session = None

    def _handshake(self) -> None:
        session = self.session
        session.open(1)
        self._started_at = self.clock.monotonic()
        info = session.device_info()
        sony_over_mtp_id = info.vendor_extension_id == MTP_VENDOR_EXTENSION_ID and \
            info.manufacturer == SONY_MANUFACTURER  # libgphoto2 takes these for Sony's extensions (PTP/IP mode)
        if info.vendor_extension_id != SONY_VENDOR_EXTENSION_ID and not sony_over_mtp_id:
            raise CameraError(f"{info.manufacturer} {info.model} does not offer Sony's PTP extensions (vendor "
                              f"extension 0x{info.vendor_extension_id:X}): set USB Connection to 'PC Remote' in "
                              "the camera's menu")
        self.model = f"{info.manufacturer} {info.model}".strip() or self.model  # both optional (ptp_unpack_DI)
        self.model_code = info.model.strip()
        self.firmware = info.device_version
        if Operation.SONY_GET_SDIO_EXT_DEVICE_INFO not in info.operations:  # library.c fixup_cached_deviceinfo
            raise CameraError(f"{self.model} offers no remote control (its operations lack Sony's 0x9202): set USB "
                              "Connection to 'PC Remote' in the camera's menu, then reconnect the cable")
        session.transact(Operation.SONY_SDIO_CONNECT, 1, 0, 0)
        session.transact(Operation.SONY_SDIO_CONNECT, 2, 0, 0)
        self.protocol_version = self._sdio_protocol_version()
        session.transact(Operation.SONY_SDIO_CONNECT, 3, 0, 0)
        self._set_priority_to_application()
        self.refresh()
        self._check_ready_for_raw_brackets()

    def _set_priority_to_application(self) -> None:
        """0x9205 on 0xD25A = 1 (INT8): the PC, not the body's dials, has priority (libgphoto2 does this after
        0x9201(3) and ignores a refusal; so does this)."""
        try:
            self.session.transact(Operation.SONY_SET_CONTROL_DEVICE_A, Property.SONY_PRIORITY_MODE,
                                  data_out=struct.pack("<b", SONY_PRIORITY_APPLICATION))
        except (ResponseError, TransportTimeout, Stalled) as error:  # libgphoto2: LOG_ON_PTP_E, any PTP error
            self.session.log.append(f"priority mode not set to application ({error}); continuing")

    def _sdio_protocol_version(self) -> int:
        """0x9202's protocol version, asking again while the answer is empty."""
        for attempt in range(SDIO_INFO_ATTEMPTS):
            _, answer = self.session.transact(Operation.SONY_GET_SDIO_EXT_DEVICE_INFO, SONY_PROTOCOL_MODE_2)
            if len(answer) >= 2:
                version, codes = unpack_sony_vendor_codes(answer)
                self.vendor_properties = frozenset(code for code in codes if code & 0x7000 == 0x5000)
                return version
            self.session.log.append(f"GetSDIOGetExtDeviceInfo answered empty; asked again ({attempt + 1})")
            self.clock.sleep(SDIO_RETRY_S)
        self.session.log.append(f"GetSDIOGetExtDeviceInfo stayed empty after {SDIO_INFO_ATTEMPTS} requests; going on "
                                "with the protocol version unknown (as libgphoto2 does)")
        return 0

    def _check_ready_for_raw_brackets(self) -> None:
        """Refuse, before any shot, what would spoil a bracket: not on M, Bulb, JPEG only, a drive mode that takes
        other than one frame per press at the shutter time set (the body's own bracket, continuous, self-timer).
        A quality (0x5004) reading 0 is the descriptor's factory default, as libgphoto2's camera_sony_capture
        reads it (a current value 0 is replaced by FactoryDefaultValue)."""
        mode = self.properties.get(Property.EXPOSURE_PROGRAM_MODE)
        if mode is not None and mode.current != SONY_EXPOSURE_MODE_M:
            raise CameraError(f"the camera is not in manual exposure (mode 0x{mode.current:X}): turn the mode dial "
                              "to M")
        drive = self.properties.get(Property.DRIVE_MODE)
        if drive is not None and drive.current & 0xFFFF != SINGLE_SHOT_DRIVE:
            raise CameraError(f"the drive mode is {self.details()['drive_mode']}, not single shooting: set Drive "
                              "Mode to Single Shooting (each frame must be one press at the shutter time hdrcam "
                              "sets)")
        if self._current(self._shutter_code) == 0:
            raise CameraError("the shutter is on Bulb: set the mode dial to M and a shutter time "
                              "(Bulb's hot-pixel filter flattens a PSF core)")
        iso = self.properties.get(self._iso_code)
        if iso is not None and iso.current >> SONY_ISO_NR_SHIFT:
            raise CameraError(_MFNR_MESSAGE)
        quality = self.properties.get(Property.IMAGE_QUALITY)
        recorded = None if quality is None else quality.current or quality.factory_default
        if recorded is not None and not recorded & SONY_RAW_QUALITY_FLAG:
            raise CameraError(f"the camera records JPEG only (quality 0x{recorded:02X}): set File Format to "
                              "RAW (or RAW & JPEG) in the camera's menu")

    @property
    def focus_is_manual(self) -> bool:
        mode = self.properties.get(Property.FOCUS_MODE)
        return mode is None or mode.current == SONY_FOCUS_MANUAL

    def details(self) -> dict:
        """Focus mode, drive mode and firmware, for the bracket manifest."""
        def named(code, names):
            descriptor = self.properties.get(code)
            if descriptor is None:
                return None
            return names.get(descriptor.current & 0xFFFF, f"0x{descriptor.current:X}")

        return {"focus_mode": named(Property.FOCUS_MODE, FOCUS_MODE_NAMES),
                "drive_mode": named(Property.DRIVE_MODE, DRIVE_MODE_NAMES), "firmware": self.firmware}

    def refresh(self) -> dict[int, PropertyDescriptor]:
        """Read every property descriptor (0x9209)."""
        notes: list[str] = []
        self.properties = unpack_sony_properties(self.session.transact(Operation.SONY_GET_ALL_DEVICE_PROP_DATA)[1],
                                                 notes)
        cut = notes[-1] if notes else None
        if cut is not None and cut != self._list_cut:  # logged once, not at every 0.1 s poll
            self.session.log.append(cut)
        self._list_cut = cut
        return self.properties

    def _current(self, code: int) -> int:
        if code not in self.properties:
            raise self._missing(code)
        return self.properties[code].current

    def _missing(self, code: int) -> CameraError:
        """The error for a property the last 0x9209 answer lacks, with why that list ended early if it did."""
        return CameraError(f"the camera does not report property 0x{code:04X}"
                           + (f" ({self._list_cut})" if self._list_cut else ""))

    # -- exposure --------------------------------------------------------------------------------------------
    @property
    def _shutter_code(self) -> int:
        """0xD229 on a body whose 0x9202 answer lists it (config.c have_prop), else 0xD20D."""
        return Property.SONY_SHUTTER_SPEED_2 if Property.SONY_SHUTTER_SPEED_2 in self.vendor_properties else \
            Property.SONY_SHUTTER_SPEED

    @property
    def _iso_code(self) -> int:
        """0xD226 on a body whose 0x9202 answer lists it, else 0xD21E."""
        return Property.SONY_ISO_2 if Property.SONY_ISO_2 in self.vendor_properties else Property.SONY_ISO

    def settings(self) -> ExposureSettings:
        notch = _notch(self._current(self._shutter_code))
        iso = self._current(self._iso_code) & 0xFFFFFF
        f_number = self._current(Property.F_NUMBER) / 100.0 if Property.F_NUMBER in self.properties else None
        return ExposureSettings(float(notch.nominal), notch.label, float(iso), f_number)

    def set_exposure(self, exposure_s: float | None = None, iso: float | None = None) -> ExposureSettings:
        if exposure_s is not None:
            notch = nearest_shutter(exposure_s)

            def shutter_name(index: int) -> str:
                return f"shutter {SHUTTER_NOTCHES[index].label}"

            if self._shutter_code == Property.SONY_SHUTTER_SPEED_2:
                self._set_absolutely(self._shutter_code, notch.index, lambda value: _notch(value).index,
                                     shutter_name, notch.ptp_value)
            else:
                self._step_to(Property.SONY_SHUTTER_SPEED, notch.index, lambda value: _notch(value).index,
                              len(SHUTTER_NOTCHES), shutter_name)
        if iso is not None:
            value = iso_setting(iso)
            if self._iso_code == Property.SONY_ISO_2:
                self._set_absolutely(self._iso_code, ISO_VALUES.index(value), self._iso_index, self._iso_name, value)
            else:
                self._step_to(Property.SONY_ISO, ISO_VALUES.index(value), self._iso_index, len(ISO_VALUES),
                              self._iso_name)
        return self.settings()

    def _set_absolutely(self, code: int, target: int, index_of, name_of, default_value: int) -> None:
        """Set ``code`` (0xD229 or 0xD226) to the notch ``target`` with one 0x9205 UINT32, as libgphoto2's
        _put_Sony_ShutterSpeed / _put_Sony_ISO2 (module docstring): the value the descriptor's enumeration lists
        for that notch (``default_value`` when it lists none), refused before any write if not offered; nothing
        is sent when the body is already there. A refusal is a CameraError (libgphoto2 returns it, it does not
        step); then 0x9209 is polled until the value reads back."""
        self._check_offered(code, target, index_of, name_of)
        if index_of(self._current(code)) == target:
            return
        value = default_value
        descriptor = self.properties.get(code)
        if descriptor is not None and descriptor.form_flag == FORM_ENUMERATION:
            for listed in (*descriptor.form, *(descriptor.secondary_form or ())):
                with contextlib.suppress(CameraError):
                    if index_of(listed) == target:
                        value = listed
                        break
        try:
            self.session.transact(Operation.SONY_SET_CONTROL_DEVICE_A, code, data_out=struct.pack("<I", value))
        except ResponseError as error:
            raise CameraError(f"the camera refused {name_of(target)} (0x9205 on 0x{code:04X}: {error}); libgphoto2 "
                              "does not step such a body either: check the mode dial is on M") from None
        deadline = self.clock.monotonic() + STEP_TIMEOUT_S
        while index_of(self._current_after_refresh(code)) != target:
            if self.clock.monotonic() >= deadline:
                raise CameraError(f"{name_of(target)} was taken (0x9205 on 0x{code:04X}) but the camera still reads "
                                  f"{name_of(index_of(self._current(code)))} after {STEP_TIMEOUT_S:g} s; is the mode "
                                  "dial on M?")
            self.clock.sleep(STEP_POLL_INTERVAL_S)

    def _iso_name(self, index: int) -> str:
        """'ISO N' for a notch of :meth:`_iso_index`: the value the body lists for it (its extended ones too),
        else ISO_VALUES'."""
        descriptor = self.properties.get(self._iso_code)
        for value in (*(descriptor.form if descriptor else ()), *ISO_VALUES):
            with contextlib.suppress(CameraError):
                if self._iso_index(value) == index:
                    return f"ISO {value & 0xFFFFFF}"
        return f"ISO notch {index}"

    @staticmethod
    def _iso_index(value: int) -> int:
        """The notch of a 0xD21E value: 1/3-stop steps from ISO 100 - the index in ISO_VALUES, and beyond them the
        extended ISOs a body also lists and steps through (an A7's 50, 64, 80: -3 to -1; 32000 and up: 25 on), so
        that a step overshooting onto one, or a body left on one, is stepped back like any other notch (they ended
        the capture as "ISO is on Auto or an extended value")."""
        if value >> SONY_ISO_NR_SHIFT:
            raise CameraError(_MFNR_MESSAGE)
        value &= 0xFFFFFF
        if value == ISO_AUTO or value == 0:
            raise CameraError("ISO is on Auto: set a fixed ISO between 100 and 25600")
        return round(3 * math.log2(value / ISO_VALUES[0]))

    def _step_to(self, code: int, target: int, index_of, notches: int, name_of) -> None:
        """Step ``code`` one notch at a time to the notch ``target``; handles direction and overshoot. A target the
        body does not offer is refused before any step (``_check_offered``); a step that changes nothing after
        earlier steps landed (the body is on M) is the end of the body's list: the target is not offered."""
        self._check_offered(code, target, index_of, name_of)
        budget = 2 * notches
        position = index_of(self._current(code))
        moved = False
        while position != target:
            if budget == 0:
                raise CameraError(f"could not step property 0x{code:04X} to notch {target} (stuck at {position})")
            budget -= 1
            direction = 1 if target > position else -1
            self.session.transact(Operation.SONY_SET_CONTROL_DEVICE_B, code,
                                  data_out=_step_data(direction * self._step_sign[code]))
            landed = self._wait_for_change(code, position, index_of, (
                f"{name_of(target)} is not offered by this body: it steps no further than {name_of(position)}"
                if moved else None))
            moved = True
            if (landed - position) * direction < 0:  # the camera counts the other way: learn it
                self._step_sign[code] = -self._step_sign[code]
            position = landed  # an overshoot is stepped back on the next pass

    def _check_offered(self, code: int, target: int, index_of, name_of) -> None:
        """Refuse a target notch that the descriptor's enumeration (either of Sony's lists) does not hold, naming
        the offered notches nearest to it, as libgphoto2 config.c _put_sony_value_* (useenumorder) refuses one
        before stepping: "Target value is not in enumeration." A descriptor without an enumeration (the A7's
        shutter) lists nothing to check against."""
        descriptor = self.properties.get(code)
        if descriptor is None or descriptor.form_flag != FORM_ENUMERATION:
            return
        offered = set()
        for value in {*descriptor.form, *(descriptor.secondary_form or ())}:
            with contextlib.suppress(CameraError):  # Auto, Bulb: no notch of hdrcam's
                offered.add(index_of(value))
        if not offered or target in offered:
            return
        nearest = [max((i for i in offered if i < target), default=None),
                   min((i for i in offered if i > target), default=None)]
        raise CameraError(f"{name_of(target)} is not offered by this body (the nearest it offers: "
                          f"{' and '.join(name_of(index) for index in nearest if index is not None)})")

    def _wait_for_change(self, code: int, position: int, index_of, unchanged: str | None) -> int:
        """The notch ``code`` lands on after a step; CameraError ``unchanged`` (or a mode dial hint when None)
        if it did not change within STEP_TIMEOUT_S."""
        deadline = self.clock.monotonic() + STEP_TIMEOUT_S
        while self.clock.monotonic() < deadline:
            self.clock.sleep(STEP_POLL_INTERVAL_S)
            landed = index_of(self._current_after_refresh(code))
            if landed != position:
                return landed
        raise CameraError(unchanged or f"property 0x{code:04X} did not change within {STEP_TIMEOUT_S:g} s of a "
                          "step; is the mode dial on M?")

    # -- capture ---------------------------------------------------------------------------------------------
    def capture(self, folder: Path, stem: str, *, dark: bool = False) -> CapturedFrame:
        self.cover_lens(dark)
        settings = self.settings()
        self._wait_for_startup()
        self._drain_stale_events()
        before_release = self._drain_pending_image()
        with self._pressed(Property.SONY_HALF_PRESS):
            if not self.focus_is_manual:
                self._wait_for_focus()
            with self._pressed(Property.SONY_FULL_PRESS):
                pass
        timestamp = dt.datetime.now().replace(microsecond=0)
        announced = self._wait_for_image(CAPTURE_TIMEOUT_S + settings.exposure_s,
                                         before_release != SONY_PENDING_IMAGE_FLAG)
        info, content = self._download_raw(CAPTURE_TIMEOUT_S, announced)
        suffix = Path(info.filename).suffix.lower() or self.suffix_default
        path = write_bytes_atomic(folder / f"{stem}{suffix}", content)
        return CapturedFrame(path, settings, timestamp, self.model, read_raw(path))

    def _wait_for_startup(self) -> None:
        """A body of STARTUP_WAIT_MODELS ignores a press in its first 2.5 s after the session opened: wait that out,
        reading events and 0x9209 as libgphoto2 does (other bodies, and later shots, do not wait)."""
        if self.model_code not in STARTUP_WAIT_MODELS or self._started_at is None:
            return
        while self.clock.monotonic() - self._started_at < STARTUP_WAIT_S:
            self._pause_for_events()
            self.refresh()

    def _download_raw(self, timeout_s: float, announced: int):
        """The shot's RAW object: with RAW + JPEG the camera holds two images in turn; the JPEG is dropped and the
        next one awaited. ``announced`` is the 0xD215 value that said the object in memory was ready: 0x8000
        alone then reads "ready" for the next one too, a count (0x8001 and up) says this body means "memory
        empty" by 0x8000 (libgphoto2 camera_wait_for_event waits for more than 0x8000), whatever 0xD215 read
        before the release (0 on a session's first shot)."""
        for _ in range(OBJECTS_PER_SHOT):
            info = self.session.object_info(SONY_IN_MEMORY_OBJECT)
            content = self.session.get_object(SONY_IN_MEMORY_OBJECT)
            if len(content) != info.compressed_size:
                raise CameraError(f"downloaded {len(content)} bytes of {info.filename}, expected "
                                  f"{info.compressed_size}")
            if info.object_format == SONY_RAW_FORMAT:
                return info, content
            self.session.log.append(f"dropped {info.filename} (format 0x{info.object_format:04X}, not RAW)")
            announced = self._wait_for_image(timeout_s, announced == SONY_PENDING_IMAGE_FLAG)
        raise CameraError(f"the camera sent no RAW image among {OBJECTS_PER_SHOT} objects: set File Format to RAW")

    def _press(self, button: int, state: int) -> None:
        self.session.transact(Operation.SONY_SET_CONTROL_DEVICE_B, button, data_out=struct.pack("<H", state))

    @contextlib.contextmanager
    def _pressed(self, button: int) -> Iterator[None]:
        """Hold ``button`` (half or full press) for the body, and release it on every way out: a failure or an
        interrupt while it is held must not leave the body's button down (it would refocus or keep shooting).
        A release that fails after another failure is not reported over it."""
        self._press(button, _PRESS)
        try:
            yield
        except BaseException:
            with contextlib.suppress(Exception):
                self._release(button)
            raise
        self._release(button)

    def _release(self, button: int) -> None:
        """Release ``button``; a release whose answer was lost or interrupted is sent once more (releasing a
        released button changes nothing, unlike a notch step) before its error is raised."""
        try:
            self._press(button, _RELEASE)
        except BaseException:
            with contextlib.suppress(Exception):
                self._press(button, _RELEASE)
            raise

    def _wait_for_focus(self) -> None:
        """Poll FocusFound until it turns 2; CameraError after FOCUS_TIMEOUT_S."""
        deadline = self.clock.monotonic() + FOCUS_TIMEOUT_S
        while self._current_after_refresh(Property.SONY_FOCUS_FOUND) not in SONY_FOCUS_FOUND_VALUES:
            if self.clock.monotonic() > deadline:
                raise CameraError(f"the camera found no focus within {FOCUS_TIMEOUT_S:g} s of the half press: focus "
                                  "by hand and set the focus mode to MF (a calibration bracket must not refocus)")
            self.clock.sleep(FOCUS_POLL_INTERVAL_S)

    def _current_after_refresh(self, code: int):
        descriptor = self.refresh().get(code)
        if descriptor is None:
            raise self._missing(code)
        return descriptor.current

    def _wait_for_image(self, timeout_s: float, flag_alone_is_ready: bool) -> int:
        """Until 0xD215 says an image is ready (module docstring; ``flag_alone_is_ready``: 0x8000 exactly counts);
        events only shorten the wait between polls. Returns the 0xD215 value that said so. A body that announces
        its image only by ObjectAdded (library.c camera_sony_capture ends its wait on that event: "needed on older
        cameras like the a58") has 0xFFFFC001 asked for once 0xD215 read 0 at every poll for UNREPORTED_GRACE_S
        after the event (a body that counts its image while writing is waited on), and once more when the wait
        runs out after an ObjectAdded."""
        deadline = self.clock.monotonic() + timeout_s
        object_added = False
        quiet_since = None  # when an ObjectAdded came with 0xD215 at 0, while it stays 0
        while not _image_ready(pending := self._current_after_refresh(Property.SONY_PENDING_IMAGES),
                               flag_alone_is_ready):
            now = self.clock.monotonic()
            if pending:
                quiet_since = None
            elif quiet_since is not None and now - quiet_since >= UNREPORTED_GRACE_S:
                quiet_since = None  # asked for once per ObjectAdded
                if self._object_in_memory():
                    return pending
            if now > deadline:
                if object_added and self._object_in_memory():
                    return pending
                stuck = (" (0xD215 read 0x8000 before and after: an image left in the camera's memory is not "
                         "drained on a body that means 'ready' by it; switch the camera off and on)"
                         if pending == SONY_PENDING_IMAGE_FLAG else "")
                raise TransportTimeout(f"the camera reported no image within {timeout_s:g} s of the shutter "
                                       f"release{stuck}")
            event = self._pause_for_events()
            if event is not None and event.code == Event.SONY_OBJECT_ADDED:
                object_added = True
                if not pending and quiet_since is None:
                    quiet_since = self.clock.monotonic()
        return pending

    def _object_in_memory(self) -> bool:
        """Whether GetObjectInfo(0xFFFFC001) finds an image (InvalidObjectHandle: none)."""
        try:
            self.session.object_info(SONY_IN_MEMORY_OBJECT)
        except ResponseError as error:
            if error.response_code != Response.INVALID_OBJECT_HANDLE:
                raise
            return False
        return True

    def _pause_for_events(self):
        """One poll interval between property reads: spent waiting on the interrupt pipe, which an event ends
        early; asleep for what is left of it when the pipe returned sooner without one (a body without the pipe,
        or an I/O error on it: back-to-back property reads otherwise). Returns the event, if one came."""
        started = self.clock.monotonic()
        event = self.session.transport.read_event(int(STEP_POLL_INTERVAL_S * 1000))
        if event is None:
            rest = STEP_POLL_INTERVAL_S - (self.clock.monotonic() - started)
            if rest > 0:
                self.clock.sleep(rest)
        return event

    def _drain_stale_events(self) -> None:
        """Read and drop the events queued since the last shot (an old ObjectAdded says nothing of this one)."""
        for _ in range(STALE_EVENTS_MAX):
            if self.session.transport.read_event(1) is None:
                return

    def _drain_pending_image(self) -> int:
        """An image left in the camera's memory would be returned instead of the next one: fetch and drop it
        while 0xD215 is above 0x8000 (both of libgphoto2's readings agree there). A body whose 0xD215 lags
        behind answers InvalidObjectHandle: that ends the drain, it is not an error. Returns 0xD215 after it."""
        for _ in range(DRAIN_MAX_OBJECTS):
            pending = self._current_after_refresh(Property.SONY_PENDING_IMAGES)
            if pending <= SONY_PENDING_IMAGE_FLAG:
                return pending
            try:
                self.session.object_info(SONY_IN_MEMORY_OBJECT)
            except ResponseError as error:
                if error.response_code != Response.INVALID_OBJECT_HANDLE:
                    raise
                self.session.log.append("0xD215 said an image waits but there was none; nothing to drain")
                return pending
            self.session.get_object(SONY_IN_MEMORY_OBJECT)
        raise CameraError("the camera keeps reporting images in memory after draining them; switch it off and on")


def _image_ready(pending_images: int, flag_alone_is_ready: bool) -> bool:
    """0xD215's value says an image waits as 0xFFFFC001: 0x8000 | count above 0x8000; 0x8000 exactly when
    ``flag_alone_is_ready``; a count without the flag (the body still writing) never."""
    return pending_images > SONY_PENDING_IMAGE_FLAG or (pending_images == SONY_PENDING_IMAGE_FLAG
                                                        and flag_alone_is_ready)
