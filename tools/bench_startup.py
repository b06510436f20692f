"""Start-up time of the command line against the imports a command needs, measured side by side in one run.

Each command is a fresh process of the ``hdrcam`` script beside this Python (``python -m hdrcam`` without one); the figure is
the median wall time of --repeats runs, interleaved so both sides see the same machine load. The reference is
``python -c "import numpy, rawpy, OpenEXR"``: what ``fuse`` needs to read RAW files and write an EXR.
Usage: python tools/bench_startup.py [--repeats 11] [--out tools/results/startup.md]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402
from reports import add_report_options, publish  # noqa: E402

REFERENCE = [sys.executable, "-c", "import numpy, rawpy, OpenEXR"]
COMMANDS = {"hdrcam --help": ["--help"], "hdrcam fuse --help": ["fuse", "--help"],
            "hdrcam reconstruct --help": ["reconstruct", "--help"], "hdrcam design --help": ["design", "--help"],
            "hdrcam capture bracket --help": ["capture", "bracket", "--help"],
            "hdrcam calibrate psf --help": ["calibrate", "psf", "--help"]}


HDRCAM = [str(Path(sys.executable).parent / "hdrcam")] if (Path(sys.executable).parent / "hdrcam").is_file() \
    else [sys.executable, "-m", "hdrcam"]


def wall_seconds(command: list[str]) -> float:
    started = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=11)
    add_report_options(parser, "tools/results/startup.md")
    arguments = parser.parse_args()
    one_line_errors.refuse_existing(arguments.out, arguments.overwrite)
    runs: dict[str, list[float]] = {"import numpy, rawpy, OpenEXR": []} | {label: [] for label in COMMANDS}
    for _ in range(arguments.repeats):
        runs["import numpy, rawpy, OpenEXR"].append(wall_seconds(REFERENCE))
        for label, argv in COMMANDS.items():
            runs[label].append(wall_seconds([*HDRCAM, *argv]))
    reference = statistics.median(runs["import numpy, rawpy, OpenEXR"])
    lines = [f"Start-up, median of {arguments.repeats} fresh processes each, interleaved "
             f"(`python tools/bench_startup.py --repeats {arguments.repeats}`):", "",
             "| command | wall (s) | x the import of numpy + rawpy + OpenEXR |", "|---|---|---|"]
    for label, seconds in runs.items():
        median = statistics.median(seconds)
        lines.append(f"| `{label}` | {median:.3f} | {median / reference:.2f} |")
    lines += ["", f"Load average (1 min) at the end: {os.getloadavg()[0]:.1f}."]
    publish(arguments, lines)


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
