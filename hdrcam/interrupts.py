"""Termination signals as exceptions, and the short steps they must not split.

While a command runs, SIGINT, SIGTERM and SIGHUP raise :class:`hdrcam.errors.Interrupted` in the main thread,
so every ``finally`` and cleanup handler runs before the process ends. Python runs a signal handler between
any two bytecodes, so an exception raised that way could land inside a cleanup step itself (after an output
was published but before its temporary file was removed). Such steps run inside :func:`interrupts_deferred`:
a signal arriving there is held and raised the moment the outermost deferred block ends.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

from hdrcam.errors import Interrupted

_TERMINATION_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_deferred_depth = 0
_held_signal: int | None = None


def _raise_or_hold(number: int, frame) -> None:
    global _held_signal
    if _deferred_depth:
        if _held_signal is None:
            _held_signal = number
        return
    raise Interrupted(number)


@contextlib.contextmanager
def termination_signals_raised() -> Iterator[None]:
    """Within this block SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` (a KeyboardInterrupt); the
    previous handlers return afterwards. Only the main thread can install handlers: elsewhere it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {number: signal.signal(number, _raise_or_hold) for number in _TERMINATION_SIGNALS}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Run a short step whole: a termination signal arriving inside is raised as :class:`Interrupted` when
    the outermost such block ends (its body's own exception, if any, is then chained). Signals go to the main
    thread only, so in other threads this does nothing."""
    global _deferred_depth, _held_signal
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _deferred_depth += 1
    try:
        yield
    finally:
        _deferred_depth -= 1
        if not _deferred_depth and _held_signal is not None:
            number, _held_signal = _held_signal, None
            raise Interrupted(number)
