"""hdrcam.errors: one-line messages for operating-system errors on file names that are not UTF-8."""

from __future__ import annotations

import errno

from hdrcam.errors import os_error_message


def test_a_path_that_is_not_utf8_is_escaped_the_same_whether_given_as_bytes_or_str():
    """A file name's odd byte reads \\xNN in the message (as in evaluate's summary and EXR attributes), whether
    the OS error holds the name as bytes or as Python's surrogate-escaped str (a lone surrogate printed raw)."""
    for name in (b"caf\xe9.exr", "caf\udce9.exr"):
        message = os_error_message(FileNotFoundError(errno.ENOENT, "No such file or directory", name))
        assert message.startswith("caf\\xe9.exr: ") and message.encode("utf-8")
