"""A benchmark's timer: one warm-up call, then ``repeats`` timed calls, summarised by a statistic."""

from __future__ import annotations

import time
from typing import Callable


def timed_seconds(function: Callable[[], object], repeats: int, statistic: Callable = min) -> float:
    """``statistic`` (min: the best run; statistics.median: the typical one) of ``repeats`` wall times in seconds
    of ``function()``, after one untimed warm-up call."""
    function()
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        times.append(time.perf_counter() - started)
    return statistic(times)
