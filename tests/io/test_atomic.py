"""Atomic writes leave either the whole new file or nothing."""

from __future__ import annotations

import pytest

from hdrcam.errors import OutputExistsError
from hdrcam.io.atomic import atomic_path, check_writable, write_text_atomic


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
