"""Make a fine-tuned network the shipped checkpoint, carrying the DOE it was trained behind.

    .venv/bin/python tools/ship_checkpoint.py runs/real-rank1-fast/model.pt \
        --doe-from hdrcam/checkpoints/simulated-rank1-fast.pt --out hdrcam/checkpoints/simulated-rank1-fast.pt \
        --overwrite

``hdrcam finetune`` trains a network behind a fixed PSF, so its model.pt has no height map. When that PSF is
the PSF of a designed DOE, the shipped checkpoint should still say which DOE it expects (for ``fabricate``
and for the record). This copies the ``doe`` entry of --doe-from into the network's checkpoint after checking
that the two checkpoints hold the same PSF (to 1e-6 per pixel), and keeps everything else of the network's.
The output is written atomically (hdrcam.train.checkpoint.save_checkpoint); an existing --out (it may be
--doe-from) is replaced only with --overwrite.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

from hdrcam.train.checkpoint import read_checkpoint, save_checkpoint
from one_line_errors import run  # tools/ is on sys.path when a tool runs

PSF_TOLERANCE = 1e-6


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("network", type=Path, help="the fine-tuned model.pt")
    parser.add_argument("--doe-from", type=Path, required=True, help="checkpoint holding the designed DOE")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--overwrite", action="store_true", help="replace --out if it exists (e.g. the shipped one)")
    arguments = parser.parse_args(argv)
    network, design = read_checkpoint(arguments.network), read_checkpoint(arguments.doe_from)
    if design["doe"] is None:
        print(f"error: {arguments.doe_from} holds no DOE", file=sys.stderr)
        return 1
    difference = float((network["psf"] - design["psf"]).abs().max())
    if network["psf"].shape != design["psf"].shape or difference > PSF_TOLERANCE:
        print(f"error: the network was trained behind another PSF than {arguments.doe_from}'s "
              f"(largest difference {difference:.3g})", file=sys.stderr)
        return 1
    state = {key: value for key, value in network.items() if key != "format"}
    state["doe"] = design["doe"]
    state["profile"] = design["profile"]
    save_checkpoint(arguments.out, state, overwrite=arguments.overwrite)
    size_mb = arguments.out.stat().st_size / 1e6
    print(f"wrote {arguments.out} ({size_mb:.1f} MB): network of {arguments.network} (step {network['step']}), "
          f"DOE of {arguments.doe_from}")
    return 0


if __name__ == "__main__":
    torch.set_num_threads(1)
    sys.exit(run(main))
