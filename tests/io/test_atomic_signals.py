"""A termination signal at any line of an atomic write leaves the whole file or nothing, and no temporary."""

from __future__ import annotations

import contextlib
import inspect
import signal
import sys

import pytest

from hdrcam.errors import Interrupted
from hdrcam.interrupts import interrupts_deferred, termination_signals_raised
from hdrcam.io.atomic import TEMPORARY_SUFFIX, atomic_path, write_bytes_atomic

ATOMIC_PATH_CODE = inspect.unwrap(atomic_path).__code__


@contextlib.contextmanager
def traced_lines(on_line):
    """Call ``on_line(number)`` at every line event of atomic_path's own frame (a generator: each resumption
    is traced too)."""
    def local(frame, event, argument):
        if event == "line":
            on_line(frame.f_lineno)
        return local

    def global_(frame, event, argument):
        return local if frame.f_code is ATOMIC_PATH_CODE else None

    sys.settrace(global_)
    try:
        yield
    finally:
        sys.settrace(None)


def test_a_signal_at_any_line_of_an_atomic_write_leaves_the_whole_file_or_nothing(tmp_path):
    lines: list[int] = []
    with traced_lines(lines.append):
        write_bytes_atomic(tmp_path / "plain.bin", b"data")
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
                    write_bytes_atomic(folder / "out.bin", b"data")
            except Interrupted as interruption:
                assert interruption.signal_number == signal.SIGTERM
                interrupted += 1
        assert sent == [line]
        left = {path.name: path.read_bytes() for path in folder.iterdir()}
        assert left in ({}, {"out.bin": b"data"}), f"signal at atomic.py line {line} left {sorted(left)}"
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
