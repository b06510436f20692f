"""Where `hdrcam fuse` spends its time: the command run in this process with its stages timed in place.

Each listed function of the fuse path is wrapped to record when it started (seconds since this tool began,
imports included) and how long it took; the command then runs as a user runs it.
Usage: python tools/fuse_stages.py BRACKET --out X.exr [fuse's other options]   (add --overwrite to repeat)
"""

from __future__ import annotations

import sys
import time

STARTED = time.perf_counter()

import hdrcam.hdr.fuse as fuse_module  # noqa: E402
import hdrcam.hdr.merge as merge_module  # noqa: E402
import hdrcam.io.atomic as atomic_module  # noqa: E402
import hdrcam.io.exr as exr_module  # noqa: E402
from hdrcam.cli import main  # noqa: E402

STAGES = [(fuse_module, "fuse"), (fuse_module, "read_bracket"), (fuse_module, "merge_bayer"),
          (merge_module, "estimate_exposures"), (fuse_module, "demosaic"), (fuse_module, "transformed"),
          (exr_module, "write_exr_channels"), (atomic_module, "_flush_to_disk"), (atomic_module, "_publish_all")]
timings: list[tuple[str, float, float]] = []


def timed(module, name: str) -> None:
    function = getattr(module, name)

    def wrapper(*arguments, **options):
        started = time.perf_counter()
        try:
            return function(*arguments, **options)
        finally:
            timings.append((name, started - STARTED, time.perf_counter() - started))

    setattr(module, name, wrapper)


if __name__ == "__main__":
    for module, name in STAGES:
        timed(module, name)
    status = main(["fuse", *sys.argv[1:]])
    for name, start, seconds in sorted(timings, key=lambda timing: timing[1]):
        print(f"{name:22s} from {start:6.3f} s  {seconds:6.3f} s", file=sys.stderr)
    print(f"{'whole run':22s} {time.perf_counter() - STARTED:6.3f} s", file=sys.stderr)
    sys.exit(status)
