"""PTP and Sony vendor codes used by hdrcam (REFERENCE.md sec. 4; ISO 15740; libgphoto2 ptp.h)."""

from enum import IntEnum


class ContainerType(IntEnum):
    COMMAND = 1
    DATA = 2
    RESPONSE = 3
    EVENT = 4


class Operation(IntEnum):
    GET_DEVICE_INFO = 0x1001
    OPEN_SESSION = 0x1002
    CLOSE_SESSION = 0x1003
    GET_STORAGE_IDS = 0x1004
    GET_OBJECT_HANDLES = 0x1007
    GET_OBJECT_INFO = 0x1008
    GET_OBJECT = 0x1009
    DELETE_OBJECT = 0x100B
    INITIATE_CAPTURE = 0x100E
    GET_DEVICE_PROP_DESC = 0x1014
    GET_DEVICE_PROP_VALUE = 0x1015
    SET_DEVICE_PROP_VALUE = 0x1016
    SONY_SDIO_CONNECT = 0x9201
    SONY_GET_SDIO_EXT_DEVICE_INFO = 0x9202
    SONY_SET_CONTROL_DEVICE_A = 0x9205
    SONY_SET_CONTROL_DEVICE_B = 0x9207
    SONY_GET_ALL_DEVICE_PROP_DATA = 0x9209


class Response(IntEnum):
    OK = 0x2001
    GENERAL_ERROR = 0x2002
    SESSION_NOT_OPEN = 0x2003
    INVALID_TRANSACTION_ID = 0x2004
    OPERATION_NOT_SUPPORTED = 0x2005
    PARAMETER_NOT_SUPPORTED = 0x2006
    INCOMPLETE_TRANSFER = 0x2007
    INVALID_OBJECT_HANDLE = 0x2009
    DEVICE_PROP_NOT_SUPPORTED = 0x200A
    STORE_NOT_AVAILABLE = 0x2013
    DEVICE_BUSY = 0x2019
    INVALID_DEVICE_PROP_VALUE = 0x201C
    TRANSACTION_CANCELLED = 0x201F
    SESSION_ALREADY_OPEN = 0x201E


class Event(IntEnum):
    OBJECT_ADDED = 0x4002
    CAPTURE_COMPLETE = 0x400D
    SONY_OBJECT_ADDED = 0xC201
    SONY_PROPERTY_CHANGED = 0xC203


class Property(IntEnum):
    IMAGE_QUALITY = 0x5004  # Sony: bit 0x10 set = RAW is recorded (0x10 RAW, 0x13/0x14 RAW+JPEG; 0x02-0x04 JPEG)
    F_NUMBER = 0x5007  # u16, f-number x 100
    FOCUS_MODE = 0x500A  # 1 = manual (MF); 2 = AF-S, 0x8004 = AF-C, 0x8005 = AF-A, 0x8006 = DMF (libgphoto2)
    EXPOSURE_PROGRAM_MODE = 0x500E  # 1 = M
    DRIVE_MODE = 0x5013  # 1 = single shot
    EXPOSURE_COMPENSATION = 0x5010  # i16, EV x 1000
    SONY_SHUTTER_SPEED = 0xD20D  # u32 (numerator << 16) | denominator; 0 = bulb
    SONY_FOCUS_FOUND = 0xD213  # 1 = searching / not focused, 2 = focus found (after a half press)
    SONY_PENDING_IMAGES = 0xD215  # 0x8000 | count: images wait in memory as 0xFFFFC001
    SONY_ISO = 0xD21E  # low 24 bits; 0xFFFFFF = auto; high byte: 1/2 = Multi Frame Noise Reduction (std/high)
    SONY_ISO_2 = 0xD226  # newer bodies: ISO as 0xD21E's encoding, set absolutely with 0x9205 (libgphoto2 ISO2)
    SONY_SHUTTER_SPEED_2 = 0xD229  # newer bodies: 0xD20D's encoding, set absolutely with 0x9205 (ShutterSpeed2)
    SONY_PRIORITY_MODE = 0xD25A  # INT8 0 = camera, 1 = application (PC); libgphoto2 sets 1 after the handshake
    SONY_HALF_PRESS = 0xD2C1  # 2 = press, 1 = release (autofocus button)
    SONY_FULL_PRESS = 0xD2C2  # 2 = press, 1 = release (shutter button)


class DataType(IntEnum):
    INT8 = 0x0001
    UINT8 = 0x0002
    INT16 = 0x0003
    UINT16 = 0x0004
    INT32 = 0x0005
    UINT32 = 0x0006
    INT64 = 0x0007
    UINT64 = 0x0008
    INT128 = 0x0009
    UINT128 = 0x000A
    ARRAY = 0x4000  # flag: ARRAY | element type (AINT8 0x4001 ... AUINT128 0x400A): u32 count, then elements
    STRING = 0xFFFF


class ClassRequest(IntEnum):
    """USB still-image class requests on the control endpoint (PIMA 15740 USB transport)."""

    CANCEL = 0x64
    GET_EXTENDED_EVENT_DATA = 0x65
    DEVICE_RESET = 0x66
    GET_DEVICE_STATUS = 0x67


SONY_VENDOR_EXTENSION_ID = 0x11
MTP_VENDOR_EXTENSION_ID = 0xFFFFFFFF  # libgphoto2's PTP_VENDOR_MTP; with SONY_MANUFACTURER it means Sony's extensions
SONY_MANUFACTURER = "Sony Corporation"
SONY_USB_VENDOR_ID = 0x054C
SONY_A7_PC_REMOTE_PRODUCT_ID = 0x094C
SONY_IN_MEMORY_OBJECT = 0xFFFFC001
SONY_RAW_FORMAT = 0xB101
SONY_PENDING_IMAGE_FLAG = 0x8000  # 0xD215 = 0x8000 | images waiting (0x8000 alone: see hdrcam.capture.sony)
SONY_ISO_NR_SHIFT = 24  # 0xD21E >> 24: 0 off, 1 Multi Frame Noise Reduction, 2 MFNR high (libgphoto2 config.c)
SONY_PRIORITY_APPLICATION = 1
SONY_RAW_QUALITY_FLAG = 0x10  # in 0x5004: RAW is recorded
SONY_FOCUS_MANUAL = 1
SONY_FOCUS_FOUND = 2
SONY_FOCUS_FOUND_VALUES = (2, 3)  # libgphoto2 camera_sony_capture: "0xd213 = 2 or 3 (for rx0)"
SONY_EXPOSURE_MODE_M = 1
SONY_PROTOCOL_MODE_2 = 0xC8  # the A7's "old" SDIO protocol: notch stepping only
# properties a body that sets shutter / ISO absolutely lists in its 0x9202 answer (libgphoto2 config.c have_prop);
# an A7 lists neither
SONY_ABSOLUTE_EXPOSURE_PROPERTIES = (Property.SONY_SHUTTER_SPEED_2, Property.SONY_ISO_2)
CANCEL_EVENT_CODE = 0x4001  # the event code carried by a cancel request
PTP_INTERFACE = (6, 1, 1)  # still-image class, subclass, protocol


# library.c camera_sony_capture: these bodies "need around 3 seconds startup time to be able to capture"; libgphoto2
# holds the first press until 2.5 s after camera_init, reading events and 0x9209 meanwhile
STARTUP_WAIT_MODELS = ("ZV-E10", "ZV-1", "DSC-RX100M7", "ILCE-7RM4", "ILCE-7RM4A", "DSC-RX0M2", "ILCE-7C")
STARTUP_WAIT_S = 2.5

FOCUS_MODE_NAMES = {  # libgphoto2's config.c focusmodes[]: the PTP values, then PTP_VENDOR_SONY's
    1: "MF", 2: "AF-S", 3: "automatic macro", 0x8004: "AF-C", 0x8005: "AF-A", 0x8006: "DMF"}
SINGLE_SHOT_DRIVE = 1  # 0x5013's low 16 bits: one frame per press (newer bodies add high bits: 0x00010002 continuous)
DRIVE_MODE_NAMES = {  # libgphoto2's config.c capture_mode table for Sony (low 16 bits)
    1: "single", 2: "continuous", 0x8012: "continuous low speed", 0x8004: "self-timer 10 s",
    0x8005: "self-timer 2 s", 0x8018: "white-balance bracket low", 0x8028: "white-balance bracket high",
    **{code: f"continuous bracket {steps} EV" for code, steps in ((0x8337, 0.3), (0x8377, 0.7), (0x8311, 1.0),
                                                                    (0x8321, 2.0), (0x8331, 3.0))},
    **{code: f"single bracket {steps} EV" for code, steps in ((0x8336, 0.3), (0x8376, 0.7), (0x8310, 1.0),
                                                                (0x8320, 2.0), (0x8330, 3.0))}}


def name(code: int) -> str:
    """A readable name for any code above, e.g. 'DEVICE_BUSY (0x2019)'."""
    for enum in (Operation, Response, Event, Property):
        try:
            return f"{enum(code).name} (0x{code:04X})"
        except ValueError:
            continue
    return f"0x{code:04X}"
