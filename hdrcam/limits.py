"""Bounds checked before allocating: a size that cannot fit is refused with the numbers, before work starts.

The limit is the memory this process may still use: the kernel's MemAvailable, lowered by a cgroup
memory limit and by the address-space rlimit where those are set. Estimates are a few times the largest
array of a step (intermediates included), so a refused size would have failed, not merely been slow.
"""

from __future__ import annotations

import os
import resource
from pathlib import Path

from hdrcam.errors import InputError, TooLargeError


def available_memory_bytes() -> int:
    """Bytes of memory this process can still allocate (an estimate; at least 64 MiB)."""
    candidates = [_meminfo_available_bytes()]
    candidates.append(_cgroup_headroom_bytes())
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        candidates.append(soft)
    known = [value for value in candidates if value is not None]
    return max(min(known), 64 << 20) if known else 8 << 30


def _meminfo_available_bytes() -> int | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _cgroup_headroom_bytes() -> int | None:
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit == "max":
            return None
        used = int(Path("/sys/fs/cgroup/memory.current").read_text())
        return int(limit) - used
    except (OSError, ValueError):
        return None


def format_bytes(count: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{count / 1e3:.3g} kB"


def check_memory(what: str, bytes_needed: float, advice: str) -> None:
    """Refuse ``what`` (e.g. '--size 100000x100000') when it needs more memory than is available."""
    available = available_memory_bytes()
    if bytes_needed > available:
        raise TooLargeError(f"{what} needs about {format_bytes(bytes_needed)} of memory, more than the "
                            f"{format_bytes(available)} available; {advice}")


def check_image_size(what: str, height_px: int, width_px: int, bytes_per_pixel: float, advice: str) -> None:
    """Refuse an image of ``height_px`` x ``width_px`` whose work needs ``bytes_per_pixel`` per pixel."""
    if height_px < 1 or width_px < 1:
        raise InputError(f"{what}: {width_px} x {height_px} px is empty; {advice}")
    check_memory(f"{what} ({width_px} x {height_px} px)", float(height_px) * float(width_px) * bytes_per_pixel,
                 advice)
