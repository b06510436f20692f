"""``hdrcam demo``: the whole user story on the simulated camera, in minutes on a laptop CPU.

1. the "fabricated" DOE is the shipped checkpoint's end-to-end design: its PSF is what the simulated
   camera sees;
2. capture a PSF calibration bracket of a pinhole array (5 exposures 3 EV apart, plus darks);
3. fuse it into linear HDR; 4. calibrate the PSF from it;
5. fine-tune the shipped network and its partner (a second network trained behind the same PSF) on the
   measured PSF (briefly);
6. capture a night scene through the DOE (1.5 % of the pixels clipped);
7. reconstruct it with the fine-tuned network and its partner, and score the frame and the reconstruction
   against the truth.
Every step is the same ``hdrcam`` command a user would run; OUT/index.md lists what went where.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from hdrcam.cli.arguments import non_negative_int, positive_int, random_seed
from hdrcam.errors import OutputExistsError, StepFailed


def register(commands) -> None:
    parser = commands.add_parser("demo", help="the whole chain on the simulated camera", description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("demo-out"), help="output folder (default demo-out)")
    parser.add_argument("--finetune-steps", type=non_negative_int, default=30, metavar="N",
                        help="fine-tuning steps of each network (the shipped one and its partner) on the measured "
                             "PSF; 0 reuses the shipped networks (default 30)")
    parser.add_argument("--size", type=positive_int, nargs=2, default=(768, 1024), metavar=("H", "W"),
                        help="night frame size (default 768 1024)")
    parser.add_argument("--seed", type=random_seed, default=3,
                        help="seed of every capture and of the fine-tuning (default 3)")
    parser.set_defaults(run=run)


def _step(label: str, argv: list[str], timings: dict) -> None:
    from hdrcam.cli import main

    print(f"== {label}: hdrcam {' '.join(argv)}", flush=True)
    started = time.perf_counter()
    status = main(argv, step=label)  # an interrupt is raised on, and reported as demo's, naming the step
    timings[label] = round(time.perf_counter() - started, 1)
    if status:
        raise StepFailed(status)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.evaluate.metrics import all_metrics
    from hdrcam.io.exr import read_exr, write_exr
    from hdrcam.io.atomic import write_text_atomic
    from hdrcam.io.png import write_png
    from hdrcam.calibrate.psf_compare import psf_l1 as psf_l1_of
    from hdrcam.optics.psf_file import load_psf
    from hdrcam.preview import log_average_luminance, tonemap_rgb
    from hdrcam.limits import check_image_size
    from hdrcam.train.checkpoint import load_model, partner_checkpoint
    from hdrcam.train.optical_capture import CAPTURE_BYTES_PER_PIXEL
    from hdrcam.stages import finetune_check_record

    height, width = arguments.size
    check_image_size("--size", height, width, CAPTURE_BYTES_PER_PIXEL, "use a smaller --size")
    out = arguments.out
    if out.exists() and any(out.iterdir()):
        raise OutputExistsError(f"{out} is not empty; choose another --out (the demo never overwrites results)")
    started = time.perf_counter()
    timings: dict[str, float] = {}
    shipped = load_model()
    design_psf = out / "design-psf.exr"
    write_exr(design_psf, shipped.psf.transpose(1, 2, 0), channel_names=("R", "G", "B"),
              attributes={"source": str(shipped.source)})
    seed = str(arguments.seed)
    bracket, calibration = out / "1-calibration-bracket", out / "3-calibration"
    _step("capture calibration bracket", ["capture", "bracket", "--camera", "sim", "--profile", "simulated",
                                          "--scene", "pinholes", "--psf", str(design_psf), "--darks", "--seed", seed,
                                          "--out", str(bracket)], timings)
    _step("fuse bracket", ["fuse", str(bracket), "--darks", str(bracket / "darks"), "--camera-rgb",
                           "--out", str(out / "2-calibration-fused.exr")], timings)
    _step("calibrate psf", ["calibrate", "psf", str(bracket), "--darks", str(bracket / "darks"), "--profile",
                            "simulated", "--out", str(calibration)], timings)
    checkpoint = shipped.source
    if arguments.finetune_steps > 0:
        _step("fine-tune on the measured PSF", ["finetune", "--psf", str(calibration / "psf.exr"), "--steps",
                                                str(arguments.finetune_steps), "--seed", seed,
                                                "--out", str(out / "4-finetune")], timings)
        checkpoint = out / "4-finetune" / "model.pt"
    frame, truth = out / "5-night-frame.exr", out / "5-night-truth.exr"
    _step("capture night scene", ["simulate", "night", "--psf", str(design_psf), "--size", str(height), str(width),
                                  "--seed", seed, "--out", str(frame), "--truth", str(truth)], timings)
    _step("reconstruct", ["reconstruct", str(frame), "--checkpoint", str(checkpoint), "--psf",
                          str(calibration / "psf.exr"), "--out", str(out / "6-reconstruction")], timings)

    measured = load_psf(calibration / "psf.exr")
    psf_l1 = [round(value, 4) for value in psf_l1_of(measured, shipped.psf)]
    truth_rgb = read_exr(truth).rgb()
    frame_rgb = read_exr(frame).rgb()
    hdr_rgb = read_exr(out / "6-reconstruction" / "5-night-frame.exr").rgb()
    scores = {"ldr": all_metrics(frame_rgb, truth_rgb), "reconstruction": all_metrics(hdr_rgb, truth_rgb)}
    exposure = log_average_luminance(truth_rgb)
    for name, image in (("truth", truth_rgb), ("ldr", frame_rgb), ("reconstruction", hdr_rgb)):
        write_png(out / f"preview-{name}.png", tonemap_rgb(image, log_average=exposure))
    seconds = round(time.perf_counter() - started, 1)
    partner = partner_checkpoint(checkpoint)  # reconstruct ran it with the checkpoint when it exists
    check = finetune_check_record(out / "4-finetune") if arguments.finetune_steps > 0 else None
    write_text_atomic(out / "index.md", _index(scores, timings, seconds, checkpoint, psf_l1,
                                               partner if partner.is_file() else None,
                                               finetuned=arguments.finetune_steps > 0, check=check))
    print(json.dumps({"out": str(out), "seconds": seconds, "step_seconds": timings,
                      "psnr_linear_db": {k: round(v["psnr_linear"], 2) for k, v in scores.items()},
                      "pu21_psnr_db": {k: round(v["pu21_psnr"], 2) for k, v in scores.items()},
                      "measured_psf_l1_vs_design": psf_l1,
                      "index": str(out / "index.md")}))
    return 0


def _index(scores: dict, timings: dict, seconds: float, checkpoint: Path, psf_l1, partner: Path | None, *,
           finetuned: bool, check: dict | None = None) -> str:
    rows = "\n".join(f"| {name} | {m['psnr_linear']:.2f} | {m['pu21_psnr']:.2f} | {m['psnr_mu']:.2f} |"
                     for name, m in scores.items())
    steps = "\n".join(f"| {label} | {value} |" for label, value in timings.items())
    networks = (f"Networks: `{checkpoint}` and its partner `{partner}` (reconstruct keeps what both paint, "
                "except where strong streaks bear one out)" if partner else f"Network: `{checkpoint}`")
    finetune_folder = ("`4-finetune/` (model.pt, log, plots; the partner's model-partner.pt and run partner/; "
                       "check.json), " if finetuned else "")
    if check:
        networks += f". Fine-tune check (4-finetune/check.json): {check['summary']}"

    return f"""# hdrcam demo

The whole chain on the simulated camera, {seconds} s in all. {networks}.

| scored against the truth | PSNR linear (dB, peak 2^8) | PU21-PSNR (dB) | PSNR-mu (dB) |
|---|---|---|---|
{rows}

| truth | captured frame (LDR) | reconstruction |
|---|---|---|
| ![](preview-truth.png) | ![](preview-ldr.png) | ![](preview-reconstruction.png) |

All three previews share the truth's exposure. The measured PSF (L1 against the design's R/G/B:
{' / '.join(f'{100 * v:.1f} %' for v in psf_l1)}): ![](3-calibration/psf.png)

| step | seconds |
|---|---|
{steps}

Where things are: `design-psf.exr` (the PSF of the designed DOE, which the simulated camera sees),
`1-calibration-bracket/` (RAW frames + bracket.json + darks), `2-calibration-fused.exr`, `3-calibration/`
(psf.exr, record.json, psf.png), {finetune_folder}`5-night-frame.exr` and `5-night-truth.exr`, `6-reconstruction/`
(HDR EXR with an `unreliable` mask channel, preview PNG).
"""
