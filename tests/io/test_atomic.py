"""Atomic writes leave either the whole new file or nothing."""

from __future__ import annotations

import os

import pytest

from hdrcam.errors import OutputExistsError
from hdrcam.io.atomic import atomic_path, check_writable, write_bytes_atomic, write_text_atomic


def test_failure_inside_the_write_leaves_no_file(tmp_path):
    with pytest.raises(RuntimeError):
        with atomic_path(tmp_path / "out.exr") as temporary:
            temporary.write_bytes(b"partial")
            raise RuntimeError("disk full")
    assert list(tmp_path.iterdir()) == []


def test_an_input_is_never_an_output(tmp_path):
    source = tmp_path / "in.exr"
    write_text_atomic(source, "data")
    with pytest.raises(OutputExistsError, match="is also an input"):
        check_writable(tmp_path / "." / "in.exr", overwrite=True, inputs=[source])
    assert source.read_text() == "data"


def test_written_files_get_the_usual_mode_not_mkstemps_0600(tmp_path):
    mask = os.umask(0o022)
    try:
        path = write_bytes_atomic(tmp_path / "out.bin", b"x")
    finally:
        os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o644
