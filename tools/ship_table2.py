"""Ship the five Table 2 networks as hdrcam/checkpoints/table2/{rank1,freeform,dual-peak,star,dirac}.pt.

Each is the model.pt of its run in RUNS (tools/results/table2/train-table2.sh): the network, the PSF it was
trained behind and the profile. The learned rows also carry their DOE: the height map (metres) the PSF-first
design wrote to RUNS/NAME-optics/heightmap.exr, checked against the network's PSF by simulating it again
(largest difference <= 1e-5 per pixel). Files are written atomically; existing ones only with --overwrite.

Usage: python tools/ship_table2.py [--runs runs/table2] [--out hdrcam/checkpoints/table2] [--overwrite]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402

from hdrcam.errors import InputError  # noqa: E402
from hdrcam.optics.heightmap import load_heightmap  # noqa: E402
from hdrcam.optics.psf import OpticalSetup, PsfSimulator  # noqa: E402
from hdrcam.profiles import load_profile  # noqa: E402
from hdrcam.train.checkpoint import read_checkpoint, save_checkpoint  # noqa: E402

ROWS = {"rank1": "rank1", "freeform": "freeform", "dual-peak": "dual-peak", "star": "star8", "dirac": "dirac"}
MAX_BYTES = 6_000_000
PSF_TOLERANCE = 1e-5


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=Path, default=Path("runs/table2"))
    parser.add_argument("--out", type=Path, default=Path("hdrcam/checkpoints/table2"))
    parser.add_argument("--overwrite", action="store_true")
    arguments = parser.parse_args()
    for shipped, run in ROWS.items():
        state = read_checkpoint(arguments.runs / run / "model.pt")
        state = {key: value for key, value in state.items() if key != "format"}
        if run in ("rank1", "freeform"):
            state["doe"] = _designed_doe(arguments.runs / f"{run}-optics" / "heightmap.exr", run, state)
        path = arguments.out / f"{shipped}.pt"
        arguments.out.mkdir(parents=True, exist_ok=True)
        save_checkpoint(path, state, overwrite=arguments.overwrite)
        if path.stat().st_size > MAX_BYTES:
            raise InputError(f"{path} is {path.stat().st_size / 1e6:.1f} MB, over the 6 MB limit")
        print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB): step {state['step']}, profile {state['profile']}")
    return 0


def _designed_doe(heightmap_path: Path, kind: str, state: dict) -> dict:
    profile = load_profile(state["profile"])
    heightmap = load_heightmap(heightmap_path, profile.doe.aperture_m)
    with torch.no_grad():
        psf = PsfSimulator(OpticalSetup.from_profile(profile), heightmap)().psf
    difference = float((psf - state["psf"]).abs().max())
    if psf.shape != state["psf"].shape or difference > PSF_TOLERANCE:
        raise InputError(f"{heightmap_path} does not make the PSF its network was trained behind "
                         f"(largest difference {difference:.3g})")
    return {"kind": kind, "feature_pitch_m": heightmap.feature_pitch_m, "heights_m": heightmap().detach().cpu(),
            "parameters": {}}


if __name__ == "__main__":
    torch.set_num_threads(1)
    sys.exit(one_line_errors.run(main))
