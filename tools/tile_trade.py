"""What `reconstruct --tile` does to the result: the default pipeline (checkpoint and partner) scored by
`evaluate`'s protocol with every window core at most TILE px, or one window per crop (adaptive off).

Usage: OMP_NUM_THREADS=1 python tools/tile_trade.py TILE|full SET... [--out DIR]
  SET: nightNNNN (16 procedural night scenes of test seed base NNNN) or trainNNNN (the photographs of
  runs/data/train, crops of seed base NNNN). Dev cases: not the reported test sets (seed base 0 of
  `hdrcam evaluate`), so that a window size is not chosen on them.

Prints one line per set: mean gain over the LDR capture (dB), the worst image and the count more than 0.3 dB
below it, and the networks' own proposal; writes DIR/tileTILE-SET.json (per image, per method, dB over LDR).
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

import hdrcam.evaluate.scoring as scoring
from hdrcam import api
from hdrcam.data import scenes
from hdrcam.data.scenes import SceneSource
from hdrcam.evaluate.metrics import HARM_DB
from hdrcam.evaluate.report import paired_gains
from hdrcam.train.checkpoint import load_model
from one_line_errors import run  # tools/ is on sys.path when a tool runs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("tile", help="largest window core in px, or 'full' (one window per crop)")
    parser.add_argument("sets", nargs="+", help="nightNNNN or trainNNNN")
    parser.add_argument("--out", type=Path, default=Path("tools/results/tile-trade"))
    arguments = parser.parse_args(argv)
    scoring.reconstruct = functools.partial(api.reconstruct, tile_px=1024, adaptive=False) \
        if arguments.tile == "full" else functools.partial(api.reconstruct, tile_px=int(arguments.tile))
    model = load_model()
    arguments.out.mkdir(parents=True, exist_ok=True)
    for which in arguments.sets:
        started = time.perf_counter()
        scenes.TEST_SEED_BASE = int("".join(c for c in which if c.isdigit()))
        source, kwargs = (SceneSource("procedural"), dict(size_px=512, count=16)) if which.startswith("night") \
            else (SceneSource("runs/data/train"), dict(size_px=512, count=0))
        rows, _ = scoring.evaluate_models({"hdrcam": model}, source, examples=0, partner="auto", **kwargs)
        per_method = {method: dict(paired_gains(rows, method)) for method in ("hdrcam", "hdrcam-network",
                                                                                "hdrcnn-blend")}
        gains = {image: {method: values[image] for method, values in per_method.items()}
                 for image in per_method["hdrcam"]}
        (arguments.out / f"tile{arguments.tile}-{which}.json").write_text(json.dumps(gains, indent=1))
        full, network = (np.array(list(per_method[method].values())) for method in ("hdrcam", "hdrcam-network"))
        worst = min(per_method["hdrcam"], key=per_method["hdrcam"].get)
        print(f"tile {arguments.tile} {which}: mean {full.mean():+.3f} worst {full.min():+.2f} ({worst}) "
              f"below-{HARM_DB} {(full < -HARM_DB).sum()} network {network.mean():+.3f} "
              f"[{time.perf_counter() - started:.0f} s]", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(run(main))
