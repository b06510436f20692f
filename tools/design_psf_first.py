"""PSF-first design of a rank-1 or free-form DOE at a profile's scale (the first stage of a two-stage design).

Stage one shapes the optics alone; stage two trains the network behind the fixed PSF (`hdrcam design --psf`).
A CPU cannot afford the paper's joint optimisation at the A7's scale (one step of the network with a
differentiable 1527-feature DOE took 11-17 s on one thread here), so this tool does the optics stage:

- Initialisation. Rank-1 (paper Eq. 3): V = 1 + e, Q = 1 + d with e, d smooth random profiles, so
  V Q^T ~ 1 + e_i + d_j is nearly additive and the phase nearly separable: the PSF is the outer product of two
  line spreads - a bright centre and two streaks along the axes. Free-form: W = 1 + a smooth 2-D random field:
  the same scattered energy spread as a 2-D halo. The profiles keep spatial frequencies below
  streak_px * pixel pitch / (lambda_red L) cycles per metre, so the streaks end inside the PSF crop.
- Optimisation of the paper's energy regulariser (Sec. 3.3: the centre keeps 94 % of the bare lens's centre
  energy) plus a term that keeps the scattered light inside the crop, on the chirp-z PSF at 3 sub-pixels.

Writes OUT/heightmap.exr (metres); simulate its PSF with `hdrcam psf --doe OUT/heightmap.exr`.
Usage: python tools/design_psf_first.py --profile sony-a7-zeiss50-rank1 --doe rank1 --out DIR
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402

from hdrcam.optics.energy import centre_energy_fraction  # noqa: E402
from hdrcam.optics.fraunhofer import fraunhofer_for  # noqa: E402
from hdrcam.optics.heightmap import heightmap_for_doe, save_heightmap  # noqa: E402
from hdrcam.optics.psf import OpticalSetup  # noqa: E402
from hdrcam.profiles import load_profile  # noqa: E402

DESIGN_SUBPIXELS = 3


def smooth_noise(shape: tuple[int, ...], cutoff_cycles_per_feature: float, rng: np.random.Generator) -> np.ndarray:
    """Unit-variance white noise low-passed to |f| < cutoff (cycles per feature), over the last axes of ``shape``."""
    noise = rng.standard_normal(shape)
    axes = tuple(range(len(shape)))
    spectrum = np.fft.fftn(noise, axes=axes)
    frequencies = np.meshgrid(*[np.fft.fftfreq(n) for n in shape], indexing="ij")
    spectrum[np.sqrt(sum(f ** 2 for f in frequencies)) >= cutoff_cycles_per_feature] = 0.0
    smooth = np.fft.ifftn(spectrum, axes=axes).real
    return smooth / smooth.std()


def initialise(heightmap, doe: str, cutoff: float, phase_std_per_unit: float, scatter: float,
               rng: np.random.Generator) -> None:
    """Set the parameters so the phase fluctuation scatters ``scatter`` of the light (1 - exp(-sigma^2))."""
    phase_std = float(np.sqrt(-np.log(1.0 - scatter)))
    with torch.no_grad():
        if doe == "rank1":
            features, rank = heightmap.v.shape
            per_axis = phase_std / np.sqrt(2.0) / phase_std_per_unit  # two axes share the scattered light
            v = np.zeros((features, rank))
            q = np.zeros((features, rank))
            v[:, 0] = 1.0 + per_axis * smooth_noise((features,), cutoff, rng)
            q[:, 0] = 1.0 + per_axis * smooth_noise((features,), cutoff, rng)
            heightmap.v.copy_(torch.from_numpy(v))
            heightmap.q.copy_(torch.from_numpy(q))
        else:
            features = heightmap.w.shape[0]
            w = 1.0 + phase_std / phase_std_per_unit * smooth_noise((features, features), cutoff, rng)
            heightmap.w.copy_(torch.from_numpy(w))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="sony-a7-zeiss50-rank1")
    parser.add_argument("--doe", choices=("rank1", "freeform"), default="rank1")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--streak-px", type=float, default=120.0, help="longest deflection in the red band, pixels")
    parser.add_argument("--scatter", type=float, default=0.06, help="fraction of the light the DOE scatters")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--overwrite", action="store_true")
    arguments = parser.parse_args()
    out_path = arguments.out / "heightmap.exr"
    one_line_errors.refuse_existing(out_path, arguments.overwrite)
    profile = load_profile(arguments.profile)
    setup = OpticalSetup.from_profile(profile)
    heightmap = heightmap_for_doe(profile.doe, arguments.doe, seed=arguments.seed, dtype=torch.float64)
    model = fraunhofer_for(setup, heightmap, subpixels=DESIGN_SUBPIXELS, dtype=torch.float32)
    bare = heightmap_for_doe(profile.doe, "none")
    with torch.no_grad():
        bare_crop = model(bare())
    radius = setup.energy_centre_radius_px
    bare_centre = centre_energy_fraction(bare_crop, radius) * bare_crop.sum(dim=(-2, -1))
    target = profile.simulation.energy_target * bare_centre
    red_m = max(setup.band_wavelengths_m[0])
    cutoff = arguments.streak_px * setup.pixel_pitch_m / (red_m * setup.sensor_distance_m) * heightmap.feature_pitch_m
    green_m = float(np.mean(setup.band_wavelengths_m[1]))
    phase_per_height = float(model.phase_per_height[len(setup.band_wavelengths_m[0])])
    phase_std_per_unit = phase_per_height * profile.doe.h_max_m * 0.25 * (1 - np.tanh(0.5) ** 2)  # sigmoid'(1)
    initialise(heightmap, arguments.doe, cutoff, phase_std_per_unit, arguments.scatter,
               np.random.default_rng(arguments.seed))
    optimiser = torch.optim.Adam(heightmap.parameters(), lr=1e-2)
    log = []
    for step in range(arguments.steps + 1):
        crop = model(heightmap().float())
        crop_energy = crop.sum(dim=(-2, -1))
        centre = centre_energy_fraction(crop, radius) * crop_energy
        loss = ((centre - target) ** 2).mean() + ((bare_crop.sum(dim=(-2, -1)) - crop_energy).clamp(min=0) ** 2).mean()
        log.append({"step": step, "loss": float(loss), "centre": centre.tolist(), "crop": crop_energy.tolist()})
        print(json.dumps(log[-1]), flush=True)
        if step == arguments.steps:
            break
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    arguments.out.mkdir(parents=True, exist_ok=True)
    save_heightmap(out_path, heightmap().detach().numpy(), heightmap.feature_pitch_m, overwrite=arguments.overwrite,
                   attributes={"design": json.dumps({"tool": "design_psf_first", **{k: str(v) for k, v in
                                                      vars(arguments).items()}, "green_m": green_m,
                                                      "target_centre": target.tolist()})})
    (arguments.out / "design-log.json").write_text(json.dumps(log, indent=1) + "\n")
    print(f"wrote {out_path}")
    return 0


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
