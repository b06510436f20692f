"""Silencing what C libraries print on the process's standard error while they read a file."""

from __future__ import annotations

import contextlib
import os
import sys
import threading

_silencing = threading.Lock()  # guards the two below: file descriptor 2 is shared by every thread
_silenced_readers = 0
_saved_stderr_fd: int | None = None


@contextlib.contextmanager
def c_stderr_silenced():
    """Send file descriptor 2 to /dev/null while a C library runs: LibRaw and OpenEXR print their own lines
    (e.g. "Unexpected end of file", "EXR_ERR_BAD_CHUNK_LEADER") for damaged files, which hdrcam already reports
    in one line of its own. What Python writes to stderr meanwhile is lost too, so keep the body to the library
    call.

    Frames are decoded on several threads at once and the descriptor is the process's: the first reader in
    saves it, the last one out restores it (each saving and restoring its own would let a reader save the
    silenced descriptor and restore it last, and every later error line would be lost)."""
    global _silenced_readers, _saved_stderr_fd
    with _silencing:
        if _silenced_readers == 0:
            sys.stderr.flush()
            with open(os.devnull, "w") as null:  # opened first: a failure leaves nothing to undo
                saved = os.dup(2)
                os.dup2(null.fileno(), 2)
            _saved_stderr_fd = saved
        _silenced_readers += 1
    try:
        yield
    finally:
        with _silencing:
            _silenced_readers -= 1
            if _silenced_readers == 0:
                os.dup2(_saved_stderr_fd, 2)
                os.close(_saved_stderr_fd)
                _saved_stderr_fd = None
