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
import time
from pathlib import Path

import numpy as np

import hdrcam.evaluate.scoring as scoring
from hdrcam import api
from hdrcam.data import scenes
from hdrcam.data.scenes import SceneSource
from hdrcam.train.checkpoint import load_model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("tile", help="largest window core in px, or 'full' (one window per crop)")
    parser.add_argument("sets", nargs="+", help="nightNNNN or trainNNNN")
    parser.add_argument("--out", type=Path, default=Path("tools/results/tile-trade"))
    arguments = parser.parse_args()
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
        by_image: dict[str, dict[str, float]] = {}
        for row in rows:
            by_image.setdefault(row.image, {})[row.method] = row.metrics["psnr_linear"]
        gains = {image: {method: value - methods["ldr"] for method, value in methods.items()}
                 for image, methods in by_image.items()}
        (arguments.out / f"tile{arguments.tile}-{which}.json").write_text(json.dumps(gains, indent=1))
        full = np.array([g["hdrcam"] for g in gains.values()])
        network = np.array([g["hdrcam-network"] for g in gains.values()])
        worst = min(gains, key=lambda image: gains[image]["hdrcam"])
        print(f"tile {arguments.tile} {which}: mean {full.mean():+.3f} worst {full.min():+.2f} ({worst}) "
              f"below-0.3 {(full < -0.3).sum()} network {network.mean():+.3f} [{time.perf_counter() - started:.0f} s]",
              flush=True)


if __name__ == "__main__":
    main()
