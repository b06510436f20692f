"""How long the judge takes on a large frame: `hdrcam.reconstruct`'s default pair judged (network_agreement.judge_pair).

The frame is tools/bench_reconstruct.py's clustered night scene (a dark frame whose lights fill a block of 1/4 x
1/2 of it), captured through the shipped checkpoint's PSF; the two networks run once (their proposals are what
`reconstruct` hands the judge), then the judge alone is timed ``--repeats`` times in this process. Prints the
wall times, the peak RSS of the process and a checksum of the judged image (the same on every run of the same
code: an optimisation of the judge must leave it unchanged).
Usage: python tools/bench_judge.py [--size 4000x6000] [--repeats 2] [--seed 0]
"""

from __future__ import annotations

import argparse
import hashlib
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_reconstruct import test_frame  # noqa: E402

import hdrcam.api as api  # noqa: E402
from hdrcam.profiles import load_profile  # noqa: E402
from hdrcam.recon.network_agreement import judge_pair  # noqa: E402
from hdrcam.train.checkpoint import load_model  # noqa: E402


def frame_size(text: str) -> tuple[int, int]:
    """HEIGHTxWIDTH (px) -> (height, width); argparse's usage error otherwise."""
    try:
        height, width = (int(side) for side in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: HEIGHTxWIDTH in pixels, e.g. 4000x6000") from None
    if min(height, width) < 64:
        raise argparse.ArgumentTypeError(f"{text!r}: at least 64 px a side")
    return height, width


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=frame_size, default=(4000, 6000), help="HEIGHTxWIDTH of the frame, px")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    arguments = parser.parse_args()
    height, width = arguments.size
    model = load_model()
    psf = np.asarray(model.psf, np.float32)
    frame, _ = test_frame(height, width, arguments.seed, psf, load_profile(model.profile), "clustered")
    proposals = {}

    def kept_proposals(frame_, first, second, psf_, *, noise):
        proposals.update(first=first, second=second, noise=noise)
        return judge_pair(frame_, first, second, psf_, noise=noise)

    api.judge_pair = kept_proposals  # the networks' proposals, as reconstruct hands them to the judge
    api.reconstruct(frame, model)
    for repeat in range(arguments.repeats):
        started = time.perf_counter()
        _, judged, _, report = judge_pair(frame, proposals["first"], proposals["second"], psf,
                                          noise=proposals["noise"])
        print(f"judge_pair {time.perf_counter() - started:.2f} s ({report.clusters} clusters, "
              f"{report.clipped_pixels} clipped pixels)")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{height} x {width} px; peak RSS {peak_mb:.0f} MB; judged image sha256 "
          f"{hashlib.sha256(np.ascontiguousarray(judged).tobytes()).hexdigest()[:16]}")


if __name__ == "__main__":
    main()
