"""What a test set's highlights demand, and how much of their light each PSF puts where the frame can see it.

Under the paper's protocol (one 512 x 512 crop per image where it saturates, 1.5 % of pixels above 1, clipped
at 2^8, linear PSNR with peak 2^8; hdrcam.data.scenes) this prints, per image:
- the LDR capture's linear PSNR through the first checkpoint's PSF, and the share of its squared error on
  pixels whose truth exceeds 16 and 64 (the few brightest pixels dominate the metric);
- two oracle bounds, each filling only the frame's clipped pixels: ``blob mean`` gives every 8-connected clipped
  blob its true mean per channel (what a perfect per-highlight brightness estimate earns), ``truth`` the
  true values there (what recovering every clipped pixel earns);
- per checkpoint: the share of the light above 16 (x white) that its PSF sends onto pixels the frame did not
  clip (the evidence a reconstruction can read: frame with those highlights minus frame with them lowered to
  1, same noise), and how many unclipped pixels that light raises by more than 0.01.

Usage: python tools/highlight_evidence.py --data runs/data/val --checkpoint rank1=hdrcam/checkpoints/table2/rank1.pt
           --checkpoint dirac=hdrcam/checkpoints/table2/dirac.pt [--count 14] [--out tools/results/highlight-evidence.md]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.ndimage as ndi
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402
from reports import add_report_options, publish  # noqa: E402

from hdrcam.data.scenes import SceneSource
from hdrcam.evaluate.metrics import psnr_linear
from hdrcam.profiles import load_profile
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import OpticalCapture

SIZE_PX = 512
BRIGHT = 16.0  # x white: the light whose evidence is measured
VISIBLE_RISE = 0.01  # x white: a raise of an unclipped pixel counted as visible (about 2 sigma of shot noise at 0.5)


def capture(optics: OpticalCapture, scene: np.ndarray, seed: int) -> np.ndarray:
    """(H + 2m) x (W + 2m) x 3 radiance -> H x W x 3 frame in [0, 1]."""
    with torch.no_grad():
        frame, _ = optics(torch.from_numpy(np.ascontiguousarray(scene)).permute(2, 0, 1)[None],
                          torch.Generator().manual_seed(seed))
    return frame[0].permute(1, 2, 0).numpy()


def blob_mean_fill(frame: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """The frame with each 8-connected clipped blob set to its true mean per channel (at least the frame)."""
    clipped = frame.max(axis=-1) >= 0.999
    labels, count = ndi.label(clipped, np.ones((3, 3)))
    filled = frame.copy()
    for channel in range(3):
        means = np.concatenate([[0.0], ndi.mean(truth[..., channel], labels, np.arange(1, count + 1))])
        filled[..., channel] = np.where(clipped, np.maximum(means[labels], frame[..., channel]), frame[..., channel])
    return filled


def evidence(optics: OpticalCapture, scene: np.ndarray, seed: int) -> tuple[float, int]:
    """(share of the light above BRIGHT landing on pixels unclipped in both frames, pixels it raises > 0.01)."""
    bright = scene.max(axis=-1) > BRIGHT
    lowered = scene.copy()
    lowered[bright] = 1.0
    with_light, without = capture(optics, scene, seed), capture(optics, lowered, seed)
    seen = (with_light.max(axis=-1) < 0.999) & (without.max(axis=-1) < 0.999)
    rise = (with_light - without)[seen]
    flux = float((scene - lowered).sum())
    return (float(rise.sum()) / flux if flux > 0 else float("nan")), int((rise.max(axis=-1) > VISIBLE_RISE).sum())


def labelled_path(text: str) -> tuple[str, str]:
    """LABEL=PATH -> (label, path); argparse reports anything else in one line."""
    label, equals, path = text.partition("=")
    if not (label and equals and path):
        raise argparse.ArgumentTypeError(f"expected LABEL=PATH, got {text!r}")
    return label, path


def add_test_set_options(parser: argparse.ArgumentParser, count: int) -> None:
    """--data (a folder of photographs or 'procedural'), --checkpoint LABEL=PATH (repeatable) and --count."""
    parser.add_argument("--data", required=True, help="folder of .hdr/.exr photographs, or 'procedural'")
    parser.add_argument("--checkpoint", action="append", required=True, type=labelled_path,
                        help="LABEL=PATH (repeatable): the PSF and profile to capture through")
    parser.add_argument("--count", type=int, default=count,
                        help=f"night scenes for 'procedural' (default {count}; a folder: every image)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_test_set_options(parser, count=14)
    add_report_options(parser, "tools/results/highlight-evidence.md")
    arguments = parser.parse_args()
    one_line_errors.refuse_existing(arguments.out, arguments.overwrite)
    labelled = dict(arguments.checkpoint)
    optics = {label: OpticalCapture(load_profile(model.profile), psf=model.psf)
              for label, model in ((label, load_model(path)) for label, path in labelled.items())}
    margin = max(capture_model.margin_px for capture_model in optics.values())
    first = next(iter(optics))
    head = ["image", "LDR (dB)", "err > 16", "err > 64", "blob mean (dB)", "truth (dB)"]
    head += [f"{label}: share seen, px" for label in optics]
    lines = [f"`python tools/highlight_evidence.py --data {arguments.data} "
             + " ".join(f"--checkpoint {label}={path}" for label, path in labelled.items())
             + f" --count {arguments.count}`", "",
             f"LDR and oracles through `{first}`'s PSF; evidence: share of the light above {BRIGHT:g} x white on "
             f"unclipped pixels, and pixels it raises by more than {VISIBLE_RISE:g}.", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    totals = []
    for index, (name, scene, _) in enumerate(SceneSource(arguments.data).test_scenes(SIZE_PX, margin, arguments.count)):
        truth = scene[margin:margin + SIZE_PX, margin:margin + SIZE_PX]
        local = {label: scene[margin - o.margin_px:scene.shape[0] - margin + o.margin_px,
                              margin - o.margin_px:scene.shape[1] - margin + o.margin_px]
                 for label, o in optics.items()}
        frame = capture(optics[first], local[first], index)
        error = ((frame - truth) ** 2).sum(axis=-1)
        brightest = truth.max(axis=-1)
        clipped = frame >= 0.999
        row = [psnr_linear(frame, truth),
               error[brightest > 16].sum() / error.sum(), error[brightest > 64].sum() / error.sum(),
               psnr_linear(blob_mean_fill(frame, truth), truth), psnr_linear(np.where(clipped, truth, frame), truth)]
        seen = [evidence(o, local[label], index) for label, o in optics.items()]
        totals.append(row[:1] + row[3:5])
        lines.append(f"| {name} | {row[0]:.2f} | {row[1]:.2f} | {row[2]:.2f} | {row[3]:.2f} | {row[4]:.2f} | "
                     + " | ".join("-" if np.isnan(share) else f"{100 * share:.2f} %, {pixels}"
                                  for share, pixels in seen) + " |")
    means = np.mean(totals, axis=0)
    lines.append(f"| mean | {means[0]:.2f} | | | {means[1]:.2f} | {means[2]:.2f} |" + " |" * len(optics))
    publish(arguments, lines)
    return 0


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
