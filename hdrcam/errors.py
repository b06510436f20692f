"""Errors a user can act on, and the exit-status contract of the command line.

Exit statuses (``hdrcam.cli.main`` applies them, in this one place):

- 0 success;
- 1 every failure a user can act on: an :class:`HdrcamError`, an operating-system error (missing,
  unreadable or unwritable path, permission, read-only or full file system, file-size limit, a
  folder where a file belongs, a device gone) or too little memory; one line names the path or value and
  says what to do;
- 2 bad command-line usage (argparse);
- 3 a genuine bug (anything else);
- 128 + N when signal N (SIGINT, SIGTERM, SIGHUP) stopped the command, after it cleaned up.
"""

from __future__ import annotations

import errno
import re
import signal

EXIT_FAILURE, EXIT_USAGE, EXIT_BUG = 1, 2, 3


class HdrcamError(Exception):
    """Base class: the message says what is wrong and what to do about it."""


class InputError(HdrcamError):
    """An input file, argument or array is missing, damaged or out of range."""


class OutputExistsError(HdrcamError):
    """An output would overwrite an existing file or an input."""


class ProfileError(InputError):
    """A capture profile does not follow the schema."""


class SamplingError(HdrcamError):
    """An optical simulation setting would alias (undersample) the wave field."""


class TooLargeError(InputError):
    """A size would need more memory (or elements) than the machine has; refused before allocating."""


class StepFailed(HdrcamError):
    """A command run inside another (``demo``) failed and has already said why on stderr; the outer command
    ends with the same exit status and no second line."""

    def __init__(self, status: int):
        super().__init__(f"a step failed with exit status {status}")
        self.status = status


class Interrupted(KeyboardInterrupt):
    """A signal (SIGINT, SIGTERM, SIGHUP) raised as an exception, so that cleanup runs: temporary files
    removed, a capture's manifest written."""

    def __init__(self, signal_number: int):
        super().__init__(signal.Signals(signal_number).name)
        self.signal_number = signal_number


_ADVICE = {
    errno.ENOENT: "no such file or folder; check the path",
    errno.EACCES: "permission denied; choose a path you may use, or change its permissions",
    errno.EPERM: "operation not permitted; choose a path you may use, or change its permissions",
    errno.EROFS: "the file system is read-only; choose another destination",
    errno.ENOSPC: "no space left on the device; free some space or choose another destination",
    errno.EDQUOT: "disk quota exceeded; free some space or choose another destination",
    errno.EFBIG: "file too large for the file system or the file-size limit (ulimit -f); choose another "
                 "destination or raise the limit",
    errno.EISDIR: "is a folder where a file is expected; give a file path",
    errno.ENOTDIR: "a part of the path is not a folder; check the path",
    errno.ELOOP: "too many levels of symbolic links (a link loop?); check the links",
    errno.ENAMETOOLONG: "the name is too long for the file system; choose a shorter one",
    errno.EEXIST: "already exists; choose another output or pass --overwrite",
    errno.ENOTEMPTY: "the folder is not empty; choose another one",
    errno.EIO: "input/output error (a failing disk, or a device removed?); check the device and run again",
    errno.ENODEV: "no such device (disconnected?); check the cable and power, then run again",
    errno.ENXIO: "no such device (disconnected?); check the cable and power, then run again",
    errno.EMFILE: "too many open files; raise the limit (ulimit -n) or pass fewer files",
    errno.ETIMEDOUT: "timed out; check the device or connection and run again",
    errno.EBUSY: "the device or file is busy (another program using it?); close it and run again",
}


_USB_ADVICE = {
    errno.EACCES: "this user may not open the camera's USB device: add a udev rule giving it access (e.g. "
                  "SUBSYSTEM==\"usb\", ATTR{idVendor}==\"054c\", MODE=\"0666\") or join the group that owns it",
    errno.EPERM: "this user may not open the camera's USB device: add a udev rule giving it access or join the "
                 "group that owns it",
    errno.EBUSY: "another program holds the camera (a file manager's gvfs-gphoto2-volume-monitor, gphoto2, a "
                 "tethering tool): close it, then run again",
}
_USB_DEFAULT_ADVICE = ("check the camera's cable, power and PC-remote mode, then run again (capture bracket --resume "
                       "continues a bracket)")


def not_a_file_reason(path, expected: str) -> str:
    """Why ``path``, not a regular file, cannot be read as ``expected`` (e.g. 'an image file'), for a message after
    its path: "a folder, not EXPECTED", "not a regular file (a device, pipe or socket)" (/dev/null and a FIFO were
    called missing) or "no such file"."""
    import os

    if os.path.isdir(path):
        return f"a folder, not {expected}"
    return "not a regular file (a device, pipe or socket)" if os.path.exists(path) else "no such file"


def missing_input(path, expected: str, *, option: str | None = None, missing: str | None = None) -> InputError:
    """The one-line InputError for an input ``path`` that is not a regular file (:func:`not_a_file_reason`), where
    a path that does not exist says ``missing`` (default 'PATH: no such file'); ``option`` (e.g. '--psf') goes
    before the path."""
    import os

    named = f"{option} {path}" if option else f"{path}"
    if missing is not None and not os.path.exists(path):
        return InputError(missing)
    return InputError(f"{named}: {not_a_file_reason(path, expected)}")


def os_error_message(error: OSError) -> str:
    """One line for an operating-system error: the path(s) involved, what happened and what to do."""
    paths = [escaped_name(p.decode("utf-8", "surrogateescape") if isinstance(p, bytes) else str(p))
             for p in (error.filename, error.filename2) if p is not None]
    where = " -> ".join(paths) if paths else None
    module = type(error).__module__ or ""
    if module.startswith("usb"):  # pyusb's USBError is an OSError, usually without errno or path
        return f"USB: {error}; {_USB_ADVICE.get(error.errno, _USB_DEFAULT_ADVICE)}"
    advice = _ADVICE.get(error.errno)
    if advice is None:
        advice = error.strerror or str(error) or type(error).__name__
    return f"{where}: {advice}" if where else f"{advice} ({type(error).__name__})"


def memory_message(error: BaseException) -> str:
    detail = str(error).strip().splitlines()[0] if str(error).strip() else ""
    return ("not enough memory" + (f" ({detail[:200]})" if detail else "")
            + "; free memory, or give the command less to hold at once (fewer or smaller frames; --size, --tile, "
            "--crop or --batch where it has them)")


def is_out_of_memory(error: BaseException) -> bool:
    """MemoryError, and torch's allocator failures (a RuntimeError on CPU, OutOfMemoryError on CUDA)."""
    if isinstance(error, MemoryError):
        return True
    name = type(error).__name__
    return name == "OutOfMemoryError" or (isinstance(error, RuntimeError)
                                          and "can't allocate memory" in str(error))


def failure_message(error: BaseException) -> str | None:
    """The one-line message for a failure a user can act on (exit 1); None for a bug (exit 3)."""
    if isinstance(error, HdrcamError):
        return str(error)
    if isinstance(error, OSError):
        return os_error_message(error)
    if is_out_of_memory(error):
        return memory_message(error)
    return None


_OTHER_SURROGATES = re.compile("[\ud800-\udc7f\udd00-\udfff]")  # none stands for an undecodable byte (PEP 383)


def escaped_name(text: str) -> str:
    """``text`` with the bytes of a file name that is not valid UTF-8 (held by Python as lone surrogates) written
    as \\xNN, so it can be written out as UTF-8: b"caf\\xe9.exr" -> "caf\\xe9.exr". Any other lone surrogate (a
    JSON file's "\\ud800", say) is written as \\uNNNN."""
    text = _OTHER_SURROGATES.sub(lambda match: f"\\u{ord(match[0]):04x}", text)
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


def one_line(message: str) -> str:
    """``message`` with control characters (newlines in a file name, say) escaped, so it stays one line."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in message)
