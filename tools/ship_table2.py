"""Ship the five Table 2 networks as hdrcam/checkpoints/table2/{rank1,freeform,dual-peak,star,dirac}.pt.

Each is the model.pt of its run in RUNS (tools/results/table2/train-table2.sh): the network, the PSF it was
trained behind and the profile. The rank-1 row also carries its DOE in the paper's form (Eq. 3): the factors
V, Q (1527 x 3 each) of logit(h / h_max) recovered from the PSF-first design's height map
(RUNS/rank1-optics/heightmap.exr) by an SVD, and checked by simulating h_max sigmoid(V Q^T) again against the
network's PSF (largest difference <= 1e-5 per pixel). The free-form map (1527^2 heights, 9 MB) would break
the 6 MB limit; `tools/design_psf_first.py --doe freeform --seed 0` makes it again. Files are written
atomically; existing ones only with --overwrite.

Usage: python tools/ship_table2.py [--runs runs/table2] [--out hdrcam/checkpoints/table2] [--overwrite]
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402

from hdrcam.errors import InputError  # noqa: E402
from hdrcam.optics.heightmap import Rank1HeightMap, load_heightmap  # noqa: E402
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
        if run == "rank1":
            state["doe"] = _rank1_doe(arguments.runs / "rank1-optics" / "heightmap.exr", state)
        path = arguments.out / f"{shipped}.pt"
        encoded = io.BytesIO()
        torch.save(state, encoded)
        if encoded.tell() > MAX_BYTES:
            raise InputError(f"{path} would be {encoded.tell() / 1e6:.1f} MB, over the 6 MB limit")
        arguments.out.mkdir(parents=True, exist_ok=True)
        save_checkpoint(path, state, overwrite=arguments.overwrite)
        print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB): step {state['step']}, profile {state['profile']}")
    return 0


def _rank1_doe(heightmap_path: Path, state: dict) -> dict:
    profile = load_profile(state["profile"])
    heights = load_heightmap(heightmap_path, profile.doe.aperture_m, dtype=torch.float64)
    relative = (heights().numpy() / profile.doe.h_max_m).clip(1e-12, 1 - 1e-12)
    rank = profile.doe.rank
    u, singular, vt = np.linalg.svd(np.log(relative / (1 - relative)))
    v = u[:, :rank] * np.sqrt(singular[:rank])
    q = vt[:rank].T * np.sqrt(singular[:rank])
    factors = Rank1HeightMap(v.shape[0], heights.feature_pitch_m, profile.doe.h_max_m, rank=rank)
    factors.load_state_dict({"v": torch.from_numpy(v).float(), "q": torch.from_numpy(q).float()})
    with torch.no_grad():
        psf = PsfSimulator(OpticalSetup.from_profile(profile), factors)().psf
    difference = float((psf - state["psf"]).abs().max())
    if psf.shape != state["psf"].shape or difference > PSF_TOLERANCE:
        raise InputError(f"{heightmap_path}: h_max sigmoid(V Q^T) of rank {rank} does not make the PSF its network "
                         f"was trained behind (largest difference {difference:.3g})")
    return {"kind": "rank1", "feature_pitch_m": heights.feature_pitch_m, "h_max_m": profile.doe.h_max_m,
            "parameters": {"v": factors.v.detach().clone(), "q": factors.q.detach().clone()}}


if __name__ == "__main__":
    torch.set_num_threads(1)
    sys.exit(one_line_errors.run(main))
