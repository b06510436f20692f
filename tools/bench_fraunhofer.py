"""The chirp-z focal-plane PSF against the full Fresnel grid simulation, at a profile's scale.

For one height map (default: the profile's bare lens) it simulates the PSF with both models (same 255 px crop,
same 3 points per pixel, so the numbers compare the propagation, not the pixel integration), times both, and
reports the energy-vs-radius curves (fraction of the light through the aperture within radius r of the axis),
the energy beyond 50 and 100 px (the streaks), the crop energy, the largest per-pixel difference, and, for the
chirp-z model alone, what 7 points per pixel (the product's setting) and a 511 px crop change.
Writes OUT/optics.md and OUT/energy-radius.png.

Usage: python tools/bench_fraunhofer.py [--profile sony-a7-zeiss50-rank1] [--heightmap H.exr] --out DIR
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402

from hdrcam.io.png import write_png  # noqa: E402
from hdrcam.optics.fraunhofer import FRAUNHOFER_SUBPIXELS, fraunhofer_for  # noqa: E402
from hdrcam.optics.heightmap import heightmap_for_doe  # noqa: E402
from hdrcam.optics.psf import OpticalSetup, PsfSimulator  # noqa: E402
from hdrcam.preview import line_plot  # noqa: E402
from hdrcam.profiles import load_profile  # noqa: E402

RADII_PX = (2, 5, 10, 20, 50, 100, 127)


def energy_within(crop: np.ndarray, radii_px) -> np.ndarray:
    """(3, len(radii)) fraction of the light within each radius of the axis (pixel S // 2), per channel."""
    size = crop.shape[-1]
    offsets = np.arange(size) - size // 2
    radius = np.hypot(offsets[:, None], offsets[None, :])
    return np.stack([[channel[radius <= r].sum() for r in radii_px] for channel in crop])


def timed(function):
    started = time.perf_counter()
    with torch.no_grad():
        value = function()
    return value, time.perf_counter() - started


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="sony-a7-zeiss50-rank1")
    parser.add_argument("--heightmap", default="none", help="height-map EXR, or rank1/freeform/none")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--overwrite", action="store_true")
    arguments = parser.parse_args()
    report_path = arguments.out / "optics.md"
    one_line_errors.refuse_existing(report_path, arguments.overwrite)
    profile = load_profile(arguments.profile)
    fresnel_profile = dataclasses.replace(profile, simulation=dataclasses.replace(profile.simulation,
                                                                                    propagation="fresnel"))
    chirp_setup = OpticalSetup.from_profile(profile, psf_size_px=255)
    fresnel_setup = OpticalSetup.from_profile(fresnel_profile, psf_size_px=255)
    heightmap = heightmap_for_doe(profile.doe, arguments.heightmap)
    fresnel, fresnel_s = timed(lambda: PsfSimulator(fresnel_setup, heightmap)())
    fresnel_crop = (fresnel.psf * fresnel.crop_energy_fraction[:, None, None]).numpy()
    chirp3, chirp3_s = timed(lambda: fraunhofer_for(chirp_setup, heightmap, subpixels=3)(heightmap()))
    chirp7, chirp7_s = timed(lambda: fraunhofer_for(chirp_setup, heightmap, subpixels=FRAUNHOFER_SUBPIXELS)(heightmap()))
    wide_setup = dataclasses.replace(chirp_setup, psf_size_px=511)
    wide, wide_s = timed(lambda: fraunhofer_for(wide_setup, heightmap, subpixels=3)(heightmap()))
    rows = {"Fresnel grid, 3 pts/px, 255 px": (fresnel_crop, fresnel_s),
            "chirp-z, 3 pts/px, 255 px": (chirp3.numpy(), chirp3_s),
            f"chirp-z, {FRAUNHOFER_SUBPIXELS} pts/px, 255 px (product)": (chirp7.numpy(), chirp7_s),
            "chirp-z, 3 pts/px, 511 px": (wide.numpy(), wide_s)}
    lines = [f"# Chirp-z vs Fresnel PSF: profile {profile.name}, height map {arguments.heightmap}", "",
             f"Fresnel grid: {fresnel_setup.grid.size}^2 samples at {fresnel_setup.grid.pitch_m * 1e6:.3f} um. "
             f"Energies are fractions of the light through the aperture, per channel R, G, B.", "",
             "| model | seconds | crop energy | " + " | ".join(f"E(r<={r})" for r in RADII_PX) + " | beyond 50 px | "
             "beyond 100 px |", "|" + "---|" * (5 + len(RADII_PX))]
    series = {}
    for name, (crop, seconds) in rows.items():
        within = energy_within(crop, RADII_PX)
        total = crop.sum(axis=(-2, -1))
        beyond = [total - energy_within(crop, (r,))[:, 0] for r in (50, 100)]
        cells = [f"{seconds:.2f}", _rgb(total)] + [_rgb(within[:, i]) for i in range(len(RADII_PX))] + \
            [_rgb(b) for b in beyond]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        radii = np.arange(1, crop.shape[-1] // 2 + 1)
        series[name.split(",")[0] + name.split(",")[1]] = (radii, 1.0 - energy_within(crop[1:2], radii)[0])
    difference = np.abs(rows["chirp-z, 3 pts/px, 255 px"][0] - fresnel_crop)
    lines += ["", f"Largest per-pixel difference chirp-z vs Fresnel (3 pts/px both): {difference.max():.2e} "
                  f"(PSF peak {fresnel_crop.max():.3f}).",
              "Energy beyond a 255 px crop (chirp-z, 511 px): "
              f"{_rgb(rows['chirp-z, 3 pts/px, 511 px'][0].sum(axis=(-2, -1)) - energy_within(rows['chirp-z, 3 pts/px, 511 px'][0], (127,))[:, 0])}"
              " (counted as lost light in training; a circle of 127 px misses the crop's corners)."]
    arguments.out.mkdir(parents=True, exist_ok=True)
    write_png(arguments.out / "energy-radius.png",
              line_plot(series, "green: energy beyond radius r (px)"), overwrite=arguments.overwrite)
    report_path.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def _rgb(values) -> str:
    return "/".join(f"{v:.4f}" for v in np.asarray(values))


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
