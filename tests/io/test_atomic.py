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


@pytest.mark.parametrize("overwrite", [False, True])
def test_outputs_published_together_fail_together(tmp_path, monkeypatch, overwrite):
    """The second output's publication fails: a new pair leaves neither; with overwrite the first output (which
    replaced its old file) stays new rather than leaving neither, and the second keeps its old bytes."""
    import errno

    from hdrcam.io import atomic

    first, second = tmp_path / "a.exr", tmp_path / "a.png"
    if overwrite:
        first.write_bytes(b"old exr")
        second.write_bytes(b"old png")
    publish = atomic._publish

    def fail_the_second(temporary, path, overwrite):
        if path == second:
            raise OSError(errno.EIO, "Input/output error", str(path))
        publish(temporary, path, overwrite)

    monkeypatch.setattr(atomic, "_publish", fail_the_second)
    with pytest.raises(OSError, match="a.png"):
        with atomic.atomic_paths([first, second], overwrite=overwrite) as (new_first, new_second):
            new_first.write_bytes(b"new exr")
            new_second.write_bytes(b"new png")
    left = {path.name: path.read_bytes() for path in tmp_path.iterdir()}
    assert left == ({"a.exr": b"new exr", "a.png": b"old png"} if overwrite else {})
