"""Score the user's RAW path on real HDR photographs: `hdrcam capture bracket --camera sim` -> DNG ->
`hdrcam reconstruct`, against the photograph's truth (not `hdrcam evaluate`'s idealised RGB sensor).

Usage: OMP_NUM_THREADS=1 python tools/bench_raw_path.py runs/data/val [--count 3] [--seed 0]
       [--checkpoint hdrcam/checkpoints/simulated-rank1-fast.pt] [--out /tmp/raw_path.md]

Per photograph (the folder's .exr/.hdr files, sorted, as `hdrcam evaluate --data FOLDER` lists them):

1. Test crop as `hdrcam evaluate` takes it (hdrcam.data.scenes.SceneSource.test_scenes): hdrcam.data.crops.scored_crop,
   512 + 2 m px (m = PSF size // 2 = 31 for the shipped 63 px PSF) about a bright pixel in its centre 512 px, with rng
   seed TEST_SEED_BASE + the CRC-32 of the file's name, scaled by scale_to_clipped_fraction so exactly 1.5 % of the
   centre 512 x 512 pixels have a channel above 1, clipped at 2^8. Units: linear sRGB, 1.0 = clip (the scene as evaluate uses it).
2. Capture with the simulated A7 as a user would: the padded crop is written as a scene EXR and the
   checkpoint's PSF as a PSF EXR, then
       hdrcam capture bracket --camera sim --profile PROFILE --scene scene.exr --psf psf.exr
           --size 574x574 --stops 1 --shortest 1/60 --iso 100 --seed SEED --exposure-error 0.02 --out DIR
   (PROFILE = the checkpoint's profile, `simulated` for the shipped one; size = the padded crop, so
   `load_scene`'s cover-resize is the identity and the sensor sees the light from outside the 512 px centre).
   Radiometry of hdrcam/capture/simulated.py (SimulatedCamera.render_dn, camera_irradiance):
       irradiance_cam = PSF * clip(M . radiance, 0),   M = colorimetry.camera_from_srgb()
                        (sRGB -> Sony A7 camera RGB, scaled so sRGB white -> (0.36, 1.00, 0.81): max channel 1)
       charge [full wells] = mosaic_RGGB(irradiance_cam) * t_true / t_ref * ISO/100,  t_ref = 1/60 s
       DN = clip(512 + (Poisson(charge * 25000 e) capped at 1.05 full wells + N(0, 4 e)) * 15871/25000, 0, 16383)
   so camera-RGB radiance 1.0 at base ISO fills the well exactly (DN 16383 = white) when t_true = t_ref.
   The shutter cannot give 1/60 s: the notch labelled 1/60 really is 2^-6 = 1/64 s, times a fixed per-notch
   error (1 + U(-0.02, 0.02), seeded by --seed and the notch; the DNG records only the label). The script
   predicts t_true with SimulatedCamera.true_exposure_s (checked afterwards against bracket.json's
   true_exposure_s) and writes the scene EXR multiplied by k = t_ref / t_true (about 64/60), so that
   radiance 1.0 of the crop lands exactly at the clip level: 1 full well = the DNG's white level.
   Hot pixels (2e-5 of the sensor, the CLI default) are left on, as a user's camera has them.
3. `hdrcam reconstruct DIR/frame-00.dng --out DIR/recon --checkpoint C`: RAW decode (black subtracted,
   / (white - black)), bilinear demosaic, camera RGB relative to the frame's white, no white balance.
4. Truth in the frame's units and colour space: the camera applies the colour matrix M (not a white balance;
   the DNG's AsShotNeutral is metadata only and neither read_ldr_frame nor reconstruct applies it), so the
   truth is replicated, not undone: truth_cam = clip(crop @ M.T, 0) (relative radiance, 1.0 = the frame's white,
   camera RGB), centre 512 x 512. The decoded frame (hdrcam.io.ldr_frame.read_ldr_frame, as reconstruct reads
   it) and the reconstruction's R, G, B are cropped to the same centre and scored with
   hdrcam.evaluate.metrics.psnr_linear (peak 2^8) and pu21_psnr.
   Radiometric check: the expected sensor signal PSF * truth_cam (full padded frame, hdrcam.sensor.fft_convolve,
   computed here independently of the camera code) against (a) the Bayer samples of the DNG, (dn - black) /
   (white - black), on centre samples whose expected value lies in [0.02, 0.9] (unclipped, above the read-noise
   floor): median relative error, and z = (measured - expected) / sigma_shot+read (mean ~ 0 and std ~ 1 when the
   frame matches to within noise); and (b) the demosaiced LDR frame on centre pixels with every expected channel
   in [0.02, 0.9] (includes bilinear-demosaic error): median relative error. "frame clip %" is the share of
   centre pixels with a channel >= 0.999 in the decoded frame; "sRGB >1 %" the crop's share strictly above 1
   (below 1.5 % when pixels tie at the quantile, e.g. RGBE-quantised .hdr files: the tied ones sit at exactly 1).
   In camera RGB fewer pixels exceed 1 than in sRGB (each row of M sums to at most 1, red to 0.36), while the
   PSF and the demosaic spread clipping to neighbours, so the frame's share differs from 1.5 % either way.

Commands run as ``python -m hdrcam`` with the hdrcam this script imported first on PYTHONPATH (an installed entry
point runs the tree it was installed from: from another checkout, that tree's code, not the one measured). A
failing command stops the script with one line naming it and its last stderr line.

Prints a markdown table (photograph, LDR dB, reconstruct dB, gain, PU21) with means, the radiometric
check per photograph and the wall time; writes the same text to --out (a .md file) when given.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import hdrcam
from hdrcam.capture.notches import nearest_shutter
from hdrcam.capture.scene import Scene
from hdrcam.capture.simulated import BASE_ISO, DEFAULT_REFERENCE_EXPOSURE_S, SimulatedCamera
from hdrcam.colorimetry import camera_from_srgb
from hdrcam.data.crops import scored_crop
from hdrcam.data.hdr_folder import hdr_files, read_hdr_image
from hdrcam.data.saturation import TEST_CLIPPED_FRACTION, clipped_fraction, scale_to_clipped_fraction
from hdrcam.data.scenes import TEST_CONTEXT_PX, TEST_SEED_BASE, name_seed
from hdrcam.errors import HdrcamError
from hdrcam.evaluate.metrics import psnr_linear, pu21_psnr
from hdrcam.io.exr import read_exr, write_exr
from hdrcam.io.ldr_frame import read_ldr_frame
from hdrcam.io.raw import read_raw
from hdrcam.profiles import load_profile
from hdrcam.sensor import bayer_mosaic, fft_convolve
from hdrcam.train.checkpoint import load_model

SIZE_PX = 512  # `hdrcam evaluate`'s default test crop
SHUTTER_LABEL = "1/60"  # the notch nearest the simulated camera's reference exposure (true time 1/64 s)
SHUTTER_S = 1.0 / 60.0
ISO = BASE_ISO
EXPOSURE_ERROR = 0.02  # the CLI's default per-notch shutter error, passed explicitly so the prediction matches
CHECK_RANGE = (0.02, 0.9)  # expected signal (fraction of white) of the samples the radiometric check uses
CLIP_LEVEL = 0.999


class BenchError(Exception):
    """A failed step; main() prints it as one line."""


def run_cli(arguments: list[str]) -> str:
    """``python -m hdrcam ARGUMENTS`` with the hdrcam this script imported first on the path: an installed
    entry point would run the tree it was installed from (another checkout's code, not the one measured)."""
    root = str(Path(hdrcam.__file__).resolve().parents[1])
    path = os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])])
    result = subprocess.run([sys.executable, "-m", "hdrcam", *arguments], capture_output=True, text=True,
                            env={**os.environ, "PYTHONPATH": path})
    if result.returncode != 0:
        last = (result.stderr.strip().splitlines() or result.stdout.strip().splitlines() or ["no output"])[-1]
        raise BenchError(f"`hdrcam {' '.join(arguments[:2])}` failed (exit {result.returncode}): {last}")
    return result.stdout


def evaluate_crop(path: Path, margin_px: int) -> np.ndarray:
    """`hdrcam evaluate`'s test scene of the file (SceneSource.test_scenes)."""
    rng = np.random.default_rng(TEST_SEED_BASE + name_seed(path.name))
    crop = scored_crop(read_hdr_image(path), SIZE_PX, margin_px, TEST_CONTEXT_PX, rng)
    centre = crop[margin_px:crop.shape[0] - margin_px, margin_px:crop.shape[1] - margin_px]
    return scale_to_clipped_fraction(crop, TEST_CLIPPED_FRACTION, scale_region=centre)


def true_exposure_s(profile, psf: np.ndarray, seed: int) -> float:
    """The shutter time the simulated camera really gives at the 1/60 notch with this seed."""
    camera = SimulatedCamera(profile, Scene(2, 2), psf, seed=seed, hot_pixel_fraction=0.0,
                             exposure_error=EXPOSURE_ERROR)
    return camera.true_exposure_s(nearest_shutter(SHUTTER_S))


def radiometric_check(dng: Path, frame: np.ndarray, expected: np.ndarray, margin_px: int, camera) -> dict:
    """Decoded DNG (Bayer and demosaiced) against the expected signal PSF * truth_cam (H x W x 3)."""
    raw = read_raw(dng)
    black = np.tile(raw.metadata.black_level_tile(), (raw.bayer_dn.shape[0] // 2 + 1, raw.bayer_dn.shape[1] // 2 + 1))
    black = black[:raw.bayer_dn.shape[0], :raw.bayer_dn.shape[1]]
    measured = (raw.bayer_dn.astype(np.float64) - black) / (raw.metadata.white_level_dn - black)
    mosaic = bayer_mosaic(torch.from_numpy(np.ascontiguousarray(expected.transpose(2, 0, 1), np.float64)),
                          raw.metadata.cfa_pattern).numpy()
    centre = (slice(margin_px, margin_px + SIZE_PX),) * 2
    measured, mosaic = measured[centre], mosaic[centre]
    used = (mosaic >= CHECK_RANGE[0]) & (mosaic <= CHECK_RANGE[1])
    electrons = mosaic[used] * camera.full_well_e
    sigma = np.sqrt(electrons + camera.read_noise_e ** 2) / camera.full_well_e
    z = (measured[used] - mosaic[used]) / sigma
    relative = measured[used] / mosaic[used] - 1.0
    rgb_expected, rgb_frame = expected[centre], frame[centre]
    rgb_used = np.all((rgb_expected >= CHECK_RANGE[0]) & (rgb_expected <= CHECK_RANGE[1]), axis=-1)
    rgb_relative = rgb_frame[rgb_used] / rgb_expected[rgb_used] - 1.0
    return {"bayer_samples": int(used.sum()), "bayer_median_rel": float(np.median(relative)),
            "bayer_median_abs_rel": float(np.median(np.abs(relative))),
            "noise_median_abs_rel": float(np.median(0.6745 * sigma / mosaic[used])),
            "z_mean": float(z.mean()), "z_std": float(z.std()),
            "rgb_pixels": int(rgb_used.sum()), "rgb_median_rel": float(np.median(rgb_relative)),
            "rgb_median_abs_rel": float(np.median(np.abs(rgb_relative)))}


def bench_one(path: Path, model, checkpoint: Path, profile, seed: int, work: Path,
              reconstruct_options: list[str]) -> dict:
    psf = model.psf.astype(np.float32)
    margin = psf.shape[-1] // 2
    crop = evaluate_crop(path, margin)  # sRGB, 1.0 = clip, (512 + 2m)^2 x 3
    t_true = true_exposure_s(profile, psf, seed)
    gain = DEFAULT_REFERENCE_EXPOSURE_S / t_true  # radiance 1.0 -> exactly one full well = white
    folder = work / path.stem
    folder.mkdir()
    scene_file, psf_file = folder / "scene.exr", folder / "psf.exr"
    write_exr(scene_file, crop * np.float32(gain), channel_names=("R", "G", "B"))
    write_exr(psf_file, psf.transpose(1, 2, 0), channel_names=("R", "G", "B"))
    height, width = crop.shape[:2]
    run_cli(["capture", "bracket", "--camera", "sim", "--profile", model.profile, "--scene", str(scene_file),
             "--psf", str(psf_file), "--size", f"{width}x{height}", "--stops", "1", "--shortest", SHUTTER_LABEL,
             "--iso", str(ISO), "--seed", str(seed), "--exposure-error", str(EXPOSURE_ERROR),
             "--out", str(folder / "capture")])
    manifest = json.loads((folder / "capture" / "bracket.json").read_text())
    (shot,) = manifest["frames"]
    if not math.isclose(shot["true_exposure_s"], t_true, rel_tol=1e-9):
        raise BenchError(f"{path.name}: the camera exposed {shot['true_exposure_s']:.6g} s, predicted {t_true:.6g} s")
    dng = folder / "capture" / shot["file"]
    stdout = run_cli(["reconstruct", str(dng), "--out", str(folder / "recon"), "--checkpoint", str(checkpoint),
                      *reconstruct_options])
    report = json.loads(stdout.strip().splitlines()[-1])
    hdr = read_exr(Path(report["hdr"])).rgb()
    frame = read_ldr_frame(dng)

    truth_cam = np.clip(crop.astype(np.float64) @ camera_from_srgb().T, 0.0, None)  # frame units, camera RGB
    expected = fft_convolve(torch.from_numpy(np.ascontiguousarray(truth_cam.transpose(2, 0, 1))),
                            torch.from_numpy(psf.astype(np.float64))).numpy().transpose(1, 2, 0)
    check = radiometric_check(dng, frame, expected, margin, profile.camera)
    centre = (slice(margin, margin + SIZE_PX),) * 2
    truth, ldr, recon = truth_cam[centre], frame[centre], hdr[centre]
    return {"name": path.stem, "ldr": psnr_linear(ldr, truth), "recon": psnr_linear(recon, truth),
            "ldr_pu21": pu21_psnr(ldr, truth), "recon_pu21": pu21_psnr(recon, truth),
            "srgb_clip": 100 * clipped_fraction(crop[centre]),
            "frame_clip": 100 * float(np.mean(ldr.max(axis=-1) >= CLIP_LEVEL)),
            "exposure": t_true, "k": gain, "seconds": report["seconds"], **check}


def table(rows: list[dict], arguments, checkpoint: Path, seconds: float) -> str:
    lines = [f"RAW path on {arguments.folder} ({len(rows)} photographs, {SIZE_PX} px test crops as `hdrcam "
             f"evaluate`), checkpoint {checkpoint}"
             f"{' (reconstruct --no-mirror-check)' if arguments.no_mirror_check else ''}"
             f"{f' (reconstruct --partner {arguments.partner})' if arguments.partner else ''}"
             f"{' (reconstruct --no-partner)' if arguments.no_partner else ''}"
             f"{'' if arguments.partner or arguments.no_partner else ' (with its partner beside it, if any)'}, "
             f"noise seed {arguments.seed}; truth in camera RGB (colour "
             "matrix of the simulated A7 applied), 1.0 = DNG white. PSNR linear, peak 2^8.", "",
             "| photograph | LDR dB | reconstruct dB | gain dB | LDR PU21 | reconstruct PU21 |",
             "|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['name']} | {row['ldr']:.2f} | {row['recon']:.2f} | {row['recon'] - row['ldr']:+.2f} | "
                     f"{row['ldr_pu21']:.2f} | {row['recon_pu21']:.2f} |")
    mean = {key: float(np.mean([row[key] for row in rows])) for key in ("ldr", "recon", "ldr_pu21", "recon_pu21")}
    lines.append(f"| **mean** | {mean['ldr']:.2f} | {mean['recon']:.2f} | {mean['recon'] - mean['ldr']:+.2f} | "
                 f"{mean['ldr_pu21']:.2f} | {mean['recon_pu21']:.2f} |")
    lines += ["", f"Radiometric check (expected = PSF * truth; samples with expected in {list(CHECK_RANGE)} of white, "
                  "centre crop). Bayer: median relative error (signed, absolute; shot+read noise alone gives the "
                  "'noise' median), z = error / sigma. RGB: demosaiced LDR frame.", "",
              "| photograph | shutter true s | scene x k | sRGB >1 % | frame clip % | Bayer samples | median rel | "
              "median abs rel | noise abs rel | z mean | z std | RGB median rel | RGB median abs rel | recon s |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['name']} | {row['exposure']:.6f} | {row['k']:.4f} | {row['srgb_clip']:.2f} | "
                     f"{row['frame_clip']:.2f} | {row['bayer_samples']} | {100 * row['bayer_median_rel']:+.3f} % | "
                     f"{100 * row['bayer_median_abs_rel']:.3f} % | {100 * row['noise_median_abs_rel']:.3f} % | "
                     f"{row['z_mean']:+.3f} | {row['z_std']:.3f} | {100 * row['rgb_median_rel']:+.3f} % | "
                     f"{100 * row['rgb_median_abs_rel']:.3f} % | {row['seconds']:.1f} |")
    lines += ["", f"Wall time: {seconds:.1f} s."]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="folder of .exr/.hdr photographs (e.g. runs/data/val)")
    parser.add_argument("--checkpoint", type=Path, default=None, help="default: the shipped checkpoint")
    parser.add_argument("--out", type=Path, default=None, help="markdown file for the tables")
    parser.add_argument("--count", type=int, default=None, help="only the first N photographs")
    parser.add_argument("--seed", type=int, default=0, help="simulated camera seed (noise, shutter error, defects)")
    parser.add_argument("--no-mirror-check", action="store_true", help="pass --no-mirror-check to reconstruct")
    partners = parser.add_mutually_exclusive_group()
    partners.add_argument("--partner", type=Path, default=None, help="pass --partner CHECKPOINT to reconstruct")
    partners.add_argument("--no-partner", action="store_true", help="pass --no-partner to reconstruct")
    arguments = parser.parse_args()
    if arguments.count is not None and arguments.count < 1:
        parser.error(f"--count must be at least 1, got {arguments.count}")
    started = time.perf_counter()
    try:
        model = load_model(arguments.checkpoint)
        checkpoint = Path(model.source)
        profile = load_profile(model.profile)
        files = hdr_files(arguments.folder)[:arguments.count]
        rows = []
        with tempfile.TemporaryDirectory(prefix="bench_raw_path_") as work:
            for path in files:
                rows.append(bench_one(path, model, checkpoint, profile, arguments.seed, Path(work),
                                      (["--no-mirror-check"] if arguments.no_mirror_check else []) +
                                      (["--partner", str(arguments.partner)] if arguments.partner else []) +
                                      (["--no-partner"] if arguments.no_partner else [])))
                row = rows[-1]
                print(f"{row['name']}: LDR {row['ldr']:.2f} dB, reconstruct {row['recon']:.2f} dB, Bayer median "
                      f"rel {100 * row['bayer_median_rel']:+.3f} %, z {row['z_mean']:+.3f} +- {row['z_std']:.3f}",
                      file=sys.stderr, flush=True)
    except (BenchError, HdrcamError) as error:
        print(f"bench_raw_path: error: {error}", file=sys.stderr)
        return 1
    text = table(rows, arguments, checkpoint, time.perf_counter() - started)
    print(text)
    if arguments.out:
        arguments.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
