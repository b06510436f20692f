"""The windshield streak fit on real photographs: does it help where there are streaks, and leave alone where
there are none?

Each EXR photograph in DIR: its centre crop (--size px), scaled so 1.5 % of its pixels exceed 1, captured
through a windshield streak (a 2-point star at an angle drawn from the paper's range, seeded) and through a
Dirac PSF (the clean reference, same noise seed), on the `simulated` profile. Scores (PSNR, peak 1, against the
clean frame): the streaked frame, the streak fit of it, and the streak fit of the clean frame (150 = left as
it was).
Usage: python tools/bench_destreak_photos.py DIR [--size 320] [--out tools/results/destreak/photos.md]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from hdrcam.evaluate.metrics import psnr
from hdrcam.io.exr import read_exr
from hdrcam.optics.analytic import dirac, sample_windshield_angle_deg, two_point_star
from hdrcam.profiles import load_profile
from hdrcam.recon.windshield_fit import subtract_windshield_streaks
from hdrcam.train.optical_capture import capture_scene

PSF_SIZE_PX = 63
CLIPPED_FRACTION = 0.015


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("photos", type=Path)
    parser.add_argument("--size", type=int, default=320)
    parser.add_argument("--out", type=Path, default=Path("tools/results/destreak/photos.md"))
    arguments = parser.parse_args()
    profile, angles, half = load_profile("simulated"), np.random.default_rng(0), arguments.size // 2
    rows = []
    for path in sorted(arguments.photos.glob("*.exr")):
        image = read_exr(path).rgb()
        middle_y, middle_x = image.shape[0] // 2, image.shape[1] // 2
        crop = np.ascontiguousarray(image[middle_y - half:middle_y + half, middle_x - half:middle_x + half])
        crop = crop / np.quantile(crop.max(axis=-1), 1 - CLIPPED_FRACTION)
        angle = sample_windshield_angle_deg(angles)
        streaked = capture_scene(crop, two_point_star(PSF_SIZE_PX, angle), profile, seed=1)
        clean = capture_scene(crop, dirac(PSF_SIZE_PX), profile, seed=1)
        fitted, report = subtract_windshield_streaks(streaked)
        left_alone, _ = subtract_windshield_streaks(clean)
        rows.append(f"| {path.name} | {angle:+.1f} | {psnr(streaked, clean, 1.0):.2f} | "
                    f"{psnr(fitted, clean, 1.0):.2f} | {psnr(left_alone, clean, 1.0):.2f} | "
                    f"{report.clusters - report.clusters_left} of {report.clusters} |")
        print(rows[-1], flush=True)
    table = ("# The windshield streak fit on real photographs\n\n"
             f"`python tools/bench_destreak_photos.py {arguments.photos} --size {arguments.size}`: centre crops "
             f"scaled so {100 * CLIPPED_FRACTION:g} % of the pixels exceed 1; PSNR (dB, peak 1) against the same "
             "crop through a clean windshield.\n\n"
             "| photograph | angle (deg) | streaked | streak fit | fit of the clean frame | clusters fitted |\n"
             "|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n")
    arguments.out.parent.mkdir(parents=True, exist_ok=True)
    arguments.out.write_text(table)
    print(table)


if __name__ == "__main__":
    main()
