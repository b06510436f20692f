"""A termination signal at any line of an atomic write leaves the whole file or nothing, and no temporary; of a
write of several outputs together, all of them or none."""

from __future__ import annotations

import contextlib
import inspect
import signal
import sys

import pytest

from hdrcam.errors import Interrupted
from hdrcam.interrupts import interrupts_deferred, termination_signals_raised
from hdrcam.io import atomic
from hdrcam.io.atomic import TEMPORARY_SUFFIX, atomic_path, atomic_paths, write_bytes_atomic

ATOMIC_CODES = {inspect.unwrap(function).__code__ for function in (atomic_path, atomic_paths, atomic._publish_all)}


@contextlib.contextmanager
def traced_lines(on_line):
    """Call ``on_line(number)`` at every line event of atomic_path's, atomic_paths' and _publish_all's own frames
    (generators: each resumption is traced too)."""
    def local(frame, event, argument):
        if event == "line":
            on_line(frame.f_lineno)
        return local

    def global_(frame, event, argument):
        return local if frame.f_code in ATOMIC_CODES else None

    sys.settrace(global_)
    try:
        yield
    finally:
        sys.settrace(None)


def write_one(folder):
    write_bytes_atomic(folder / "out.bin", b"data")


def write_two(folder):
    with atomic_paths([folder / "out.bin", folder / "out.png"]) as (first, second):
        first.write_bytes(b"data")
        second.write_bytes(b"preview")


@pytest.mark.parametrize("write, whole", [(write_one, {"out.bin": b"data"}),
                                          (write_two, {"out.bin": b"data", "out.png": b"preview"})])
def test_a_signal_at_any_line_of_an_atomic_write_leaves_the_whole_file_or_nothing(write, whole, tmp_path):
    lines: list[int] = []
    (tmp_path / "plain").mkdir()
    with traced_lines(lines.append):
        write(tmp_path / "plain")
    assert len(set(lines)) > 5

    interrupted = 0
    for index, line in enumerate(dict.fromkeys(lines)):
        folder = tmp_path / f"at-line-{line}"
        folder.mkdir()
        sent = []

        def signal_once(number, line=line, sent=sent):
            if number == line and not sent:
                sent.append(line)
                signal.raise_signal(signal.SIGTERM)

        with termination_signals_raised():
            try:
                with traced_lines(signal_once):
                    write(folder)
            except Interrupted as interruption:
                assert interruption.signal_number == signal.SIGTERM
                interrupted += 1
        assert sent == [line]
        left = {path.name: path.read_bytes() for path in folder.iterdir()}
        assert left in ({}, whole), f"signal at atomic.py line {line} left {sorted(left)}"
        assert not any(TEMPORARY_SUFFIX in name for name in left)
    assert interrupted == len(set(lines))


def test_a_deferred_signal_is_raised_when_the_outermost_block_ends():
    steps = []
    with termination_signals_raised():
        with pytest.raises(Interrupted):
            with interrupts_deferred():
                with interrupts_deferred():
                    signal.raise_signal(signal.SIGINT)
                    steps.append("inner finished")
                steps.append("outer finished")
        steps.append("raised")
    assert steps == ["inner finished", "outer finished", "raised"]


def test_outside_a_deferred_block_a_signal_is_raised_at_once():
    with termination_signals_raised():
        with pytest.raises(Interrupted):
            signal.raise_signal(signal.SIGINT)
            pytest.fail("the signal was not raised at once")


def test_a_second_signal_while_the_temporaries_are_removed_leaves_none(tmp_path, monkeypatch):
    """A second Ctrl-C during the cleanup of the first is held until every temporary is gone."""
    import os
    from pathlib import Path

    unlink, calls = Path.unlink, []

    def unlink_and_signal_once(path, missing_ok=False):
        if not calls:
            calls.append(path)
            os.kill(os.getpid(), signal.SIGINT)
        return unlink(path, missing_ok=missing_ok)

    with termination_signals_raised(), pytest.raises(Interrupted):
        monkeypatch.setattr(Path, "unlink", unlink_and_signal_once)
        with atomic_paths([tmp_path / "out.bin", tmp_path / "out.png"]) as (first, _):
            first.write_bytes(b"data")
            raise Interrupted(signal.SIGINT)
    monkeypatch.undo()
    assert calls and list(tmp_path.iterdir()) == []
