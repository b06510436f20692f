"""Does reconstruct's judge need the frame's ISO? Frames captured at a raised ISO, judged with the base-ISO noise.

reconstruct's judge (hdrcam.recon.consistency) weighs the frame's streak evidence against the noise of the
model's capture profile at base ISO (its full well and read noise). A frame taken at ISO 100 x GAIN holds GAIN
times fewer electrons at white, so its noise is sqrt(GAIN) times larger than the judge assumes. This tool scores
the default network (with its partner) on frames captured at each --gain (``hdrcam.sensor.Sensor.from_camera``:
the full well divided by the gain, read noise in electrons kept) with the judge's noise as shipped (``base``)
and matched to the frame (``matched``: full well / gain), through the network's own PSF and the bare lens
(``--dirac-psf``, a Dirac PSF EXR: a camera without a DOE, where the judge must invent nothing). The test
protocol is evaluate's (512 px crops, 1.5 % above 1, noise seed 0). Rows: mean linear-PSNR gain over the LDR
capture, the worst photograph's, how many fall more than 0.3 dB below it.

Usage: python tools/noise_at_iso.py --data runs/data/val [--data procedural --count 16] --dirac-psf PSF.exr
       [--gain 1 --gain 32] [--out tools/results/real-data/noise-at-iso.md]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from one_line_errors import run  # noqa: E402
from reports import add_report_options, publish  # noqa: E402

import hdrcam.evaluate.scoring as scoring  # noqa: E402
from hdrcam.data.scenes import SceneSource  # noqa: E402
from hdrcam.evaluate.metrics import HARM_DB  # noqa: E402
from hdrcam.optics.psf_file import load_psf  # noqa: E402
from hdrcam.profiles import load_profile  # noqa: E402
from hdrcam.recon.consistency import NoiseModel  # noqa: E402
from hdrcam.sensor import Sensor  # noqa: E402
from hdrcam.train.checkpoint import load_model  # noqa: E402

CHECKPOINT = Path(__file__).resolve().parents[1] / "hdrcam" / "checkpoints" / "simulated-rank1-fast.pt"


def scored(data: str, count: int, gain: float, psf: np.ndarray | None, matched: bool) -> np.ndarray:
    """Per photograph, the full pipeline's linear-PSNR gain over the LDR capture (dB)."""
    model = load_model(CHECKPOINT)
    camera = load_profile(model.profile).camera

    class CaptureAtGain(scoring.OpticalCapture):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.sensor = Sensor.from_camera(camera, iso_gain=gain)

    def reconstruct(frame, model, **options):
        if matched:
            options["noise"] = NoiseModel(camera.full_well_e / gain, camera.read_noise_e)
        return original(frame, model, **options)

    original, original_capture = scoring.reconstruct, scoring.OpticalCapture
    scoring.reconstruct, scoring.OpticalCapture = reconstruct, CaptureAtGain
    try:
        rows, _ = scoring.evaluate_models({"hdrcam": model}, SceneSource(data), size_px=512, count=count, psf=psf,
                                          examples=0)
    finally:
        scoring.reconstruct, scoring.OpticalCapture = original, original_capture
    psnr: dict[str, dict[str, float]] = {}
    for row in rows:
        psnr.setdefault(row.image, {})[row.method] = row.metrics["psnr_linear"]
    return np.array([methods["hdrcam"] - methods["ldr"] for methods in psnr.values()])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", action="append", required=True, help="as evaluate's --data (repeatable)")
    parser.add_argument("--count", type=int, default=16, help="scenes of a procedural --data")
    parser.add_argument("--gain", type=float, action="append", help="ISO / 100 of the frames (default 1 and 32)")
    parser.add_argument("--dirac-psf", type=Path, required=True, help="a Dirac PSF EXR (`hdrcam psf --doe dirac`)")
    add_report_options(parser, "tools/results/real-data/noise-at-iso.md")
    arguments = parser.parse_args()
    warnings.simplefilter("ignore")  # evaluate's per-photograph notes; the table says what matters
    torch.set_num_threads(1)
    dirac = load_psf(arguments.dirac_psf)
    started = time.perf_counter()
    lines = [f"`python tools/noise_at_iso.py {' '.join(sys.argv[1:])}` (one thread; default checkpoint and its "
             "partner; linear PSNR gain over the LDR capture, dB):", "",
             "| data | ISO gain | PSF | judge's noise | mean | worst | below -0.3 dB |",
             "|---|---|---|---|---|---|---|"]
    for data in arguments.data:
        for gain in arguments.gain or [1.0, 32.0]:
            for psf_name, psf in (("network's DOE", None), ("Dirac", dirac)):
                for matched in ((False,) if gain == 1 else (False, True)):
                    gains = scored(data, arguments.count, gain, psf, matched)
                    lines.append(f"| {data} | {gain:g} | {psf_name} | {'matched' if matched else 'base ISO'} | "
                                 f"{gains.mean():+.2f} | {gains.min():+.2f} | {int((gains < -HARM_DB).sum())} |")
                    print(lines[-1], flush=True)
    lines += ["", f"Wall time: {time.perf_counter() - started:.0f} s."]
    publish(arguments, lines)
    return 0


if __name__ == "__main__":
    sys.exit(run(main))
