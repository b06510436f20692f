"""LibRaw's and OpenEXR's own error lines are silenced on file descriptor 2 while frames decode on several threads
at once; stderr must come back whatever order the readers finish in."""

from __future__ import annotations

import os

import numpy as np
import pytest

from hdrcam.errors import InputError
from hdrcam.io.c_stderr import c_stderr_silenced
from hdrcam.io.exr import read_exr, write_exr


def _stderr_target() -> tuple[int, int]:
    status = os.fstat(2)
    return status.st_dev, status.st_ino


def test_stderr_is_restored_when_overlapping_readers_finish_in_either_order():
    original = _stderr_target()
    null = os.stat(os.devnull)
    for first_out in (0, 1):
        readers = [c_stderr_silenced(), c_stderr_silenced()]
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
        with c_stderr_silenced():
            raise ValueError("damaged file")
    except ValueError:
        pass
    assert _stderr_target() == original



def test_a_truncated_exr_is_one_hdrcam_error_and_nothing_from_openexr(tmp_path, capfd):
    whole = tmp_path / "whole.exr"
    write_exr(whole, np.random.default_rng(0).uniform(0, 1, (64, 64, 3)).astype(np.float32))
    data = whole.read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[:len(data) * 2 // 3])  # a copy stopped two thirds through
    capfd.readouterr()
    with pytest.raises(InputError, match="cut.exr: not a readable OpenEXR file"):
        read_exr(tmp_path / "cut.exr")
    printed = capfd.readouterr()
    assert printed.out == "" and printed.err == ""
    assert _stderr_target() != (os.stat(os.devnull).st_dev, os.stat(os.devnull).st_ino)
