"""LibRaw's own error lines are silenced on file descriptor 2 while frames decode on several threads at once;
stderr must come back whatever order the readers finish in."""

from __future__ import annotations

import os

from hdrcam.io.raw import _libraw_stderr_silenced


def _stderr_target() -> tuple[int, int]:
    status = os.fstat(2)
    return status.st_dev, status.st_ino


def test_stderr_is_restored_when_overlapping_readers_finish_in_either_order():
    original = _stderr_target()
    null = os.stat(os.devnull)
    for first_out in (0, 1):
        readers = [_libraw_stderr_silenced(), _libraw_stderr_silenced()]
        for reader in readers:  # both decoding at once, as two threads of read_bracket would be
            reader.__enter__()
            assert _stderr_target() == (null.st_dev, null.st_ino)
        readers[first_out].__exit__(None, None, None)
        assert _stderr_target() == (null.st_dev, null.st_ino)  # the other reader is still inside LibRaw
        readers[1 - first_out].__exit__(None, None, None)
        assert _stderr_target() == original


def test_stderr_is_restored_when_a_reader_fails():
    original = _stderr_target()
    try:
        with _libraw_stderr_silenced():
            raise ValueError("damaged file")
    except ValueError:
        pass
    assert _stderr_target() == original
