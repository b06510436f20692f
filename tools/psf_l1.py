"""L1 of measured PSFs against their design: as designed, and the design centred on its green centroid by the
box model as calibration places a measured PSF (hdrcam.calibrate.psf_compare). Prints one line per PSF.

The design: `doe` (the profile's DOE PSF the simulated camera images pinholes through) or a PSF EXR (the demo's
design-psf.exr).
Usage: python tools/psf_l1.py --profile sony-a7-zeiss50-rank1 --design doe CALIBRATION/psf.exr [...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from one_line_errors import run  # noqa: E402

from hdrcam.calibrate.psf_compare import centred_on_green, psf_l1  # noqa: E402
from hdrcam.capture.simulated import simulation_psf  # noqa: E402
from hdrcam.optics.psf_file import load_psf  # noqa: E402
from hdrcam.profiles import load_profile  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("measured", type=Path, nargs="+", help="psf.exr written by hdrcam calibrate psf")
    parser.add_argument("--profile", default="sony-a7-zeiss50-rank1")
    parser.add_argument("--design", default="doe", help="doe (the profile's DOE) or a PSF EXR")
    arguments = parser.parse_args(argv)
    profile = load_profile(arguments.profile)
    design = simulation_psf(profile, "doe") if arguments.design == "doe" else \
        load_psf(Path(arguments.design), pixel_pitch_m=profile.camera.pixel_pitch_m)
    centred = centred_on_green(design.astype("float64"))
    for path in arguments.measured:
        measured = load_psf(path, pixel_pitch_m=profile.camera.pixel_pitch_m)
        shown = [" / ".join(f"{100 * value:.2f}" for value in psf_l1(measured, reference))
                 for reference in (design, centred)]
        print(f"{path}: L1 R/G/B % against the design {shown[0]}, against it centred {shown[1]}")
    return 0


if __name__ == "__main__":
    sys.exit(run(main))
