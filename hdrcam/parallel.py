"""Per-pixel work on both (all) cores: strips of rows mapped over a thread pool (numpy, OpenCV and OpenEXR
release the GIL while they compute)."""

from __future__ import annotations

import os


def worker_threads() -> int:
    """Threads for per-pixel work: the cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def strips(height: int, rows: int) -> list[slice]:
    """Row slices of at most ``rows`` rows covering ``height``."""
    return [slice(top, min(top + rows, height)) for top in range(0, height, rows)]
