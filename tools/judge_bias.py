"""How much of a wrong highlight the judge keeps: the frame-consistency judge alone, without a network.

The judge (hdrcam.recon.consistency) may only lower a proposed highlight. Under the paper's protocol (one
512 x 512 crop per image where it saturates, 1.5 % of pixels above 1, clipped at 2^8; hdrcam.data.scenes) each
image is captured through each checkpoint's PSF (with its profile's noise), and the judge is handed proposals
made from the truth itself: every clipped channel at 1 + k (truth - 1)+ for each factor k. It prints the excess
kept over the true excess (both summed over the clipped channels). A perfect judge keeps k for k <= 1 (the
proposal is already too dim; nothing may raise it) and 1 for k > 1 (it lowers a too-bright proposal to the
truth). Counted per checkpoint: images where it keeps more than twice the truth of the brightest proposal (a
hallucination let through) and less than half of the exact one (true light thrown away).

Usage: python tools/judge_bias.py --data runs/data/train --checkpoint shipped=hdrcam/checkpoints/simulated-rank1-fast.pt
           [--checkpoint LABEL=PATH ...] [--count 16] [--factors 0.25,1,4] [--out tools/results/judge-bias.md]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402
from highlight_evidence import add_test_set_options, capture  # noqa: E402
from reports import add_report_options, publish  # noqa: E402

from hdrcam.api import profile_noise
from hdrcam.data.scenes import SceneSource
from hdrcam.profiles import load_profile
from hdrcam.recon.consistency import NoiseModel, make_consistent
from hdrcam.recon.tiling import CLIP_LEVEL
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import OpticalCapture

SIZE_PX = 512
LET_THROUGH = 2.0  # kept / true excess of the brightest proposal above this: a hallucination let through
THROWN_AWAY = 0.5  # kept / true excess of the exact proposal below this: true light thrown away


def factors(text: str) -> list[float]:
    """'0.25,1,4' -> [0.25, 1.0, 4.0]; argparse reports anything else in one line."""
    try:
        values = [float(value) for value in text.split(",")]
    except ValueError:
        values = []
    if not values or any(not 0 < value < float("inf") for value in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers separated by commas, got {text!r}")
    return sorted(values)


def kept_shares(frame: np.ndarray, truth: np.ndarray, psf: np.ndarray, noise: NoiseModel,
                scales: list[float]) -> tuple[float, list[float]]:
    """(true excess over 1 on the frame's clipped channels, the judge's kept excess / true excess per factor)."""
    clipped = frame >= CLIP_LEVEL
    true_excess = np.where(clipped, np.clip(truth - 1.0, 0.0, None), 0.0)
    total = float(true_excess.sum())
    shares = []
    for scale in scales:
        proposal = np.where(clipped, 1.0 + scale * true_excess, frame).astype(np.float32)
        kept, _, _ = make_consistent(frame, proposal, psf, noise=noise)
        shares.append(float(np.where(clipped, kept - 1.0, 0.0).sum()) / total if total > 0 else float("nan"))
    return total, shares


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_test_set_options(parser, count=16)
    parser.add_argument("--factors", type=factors, default=[0.25, 1.0, 4.0],
                        help="proposal = 1 + k (truth - 1) on clipped channels, for each k (default 0.25,1,4)")
    add_report_options(parser, "tools/results/judge-bias.md")
    arguments = parser.parse_args()
    one_line_errors.refuse_existing(arguments.out, arguments.overwrite)
    scales = arguments.factors
    labelled = dict(arguments.checkpoint)
    models = {label: load_model(path) for label, path in labelled.items()}
    optics = {label: OpticalCapture(load_profile(model.profile), psf=model.psf) for label, model in models.items()}
    noises = {label: profile_noise(model) for label, model in models.items()}
    margin = max(optics_model.margin_px for optics_model in optics.values())
    head = ["image", f"true excess ({next(iter(models))})"]
    head += [f"{label}: k={scale:g}" for label in models for scale in scales]
    count = f" --count {arguments.count}" if arguments.data == "procedural" else ""
    lines = [f"`python tools/judge_bias.py --data {arguments.data} "
             + " ".join(f"--checkpoint {label}={path}" for label, path in labelled.items())
             + f"{count} --factors {','.join(f'{scale:g}' for scale in scales)}`", "",
             "Kept excess / true excess (clipped channels) when the judge is handed 1 + k (truth - 1); a perfect "
             "judge keeps min(k, 1).", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    shares: dict[str, list[list[float]]] = {label: [] for label in models}
    for index, (name, scene, _) in enumerate(SceneSource(arguments.data).test_scenes(SIZE_PX, margin, arguments.count)):
        truth = scene[margin:margin + SIZE_PX, margin:margin + SIZE_PX]
        cells, totals = [], []
        for label, model in models.items():
            extra = margin - optics[label].margin_px
            frame = capture(optics[label], scene[extra:scene.shape[0] - extra, extra:scene.shape[1] - extra], index)
            total, kept = kept_shares(frame, truth, np.asarray(model.psf, np.float32), noises[label], scales)
            totals.append(total)
            shares[label].append(kept)
            cells += [f"{share:.2f}" for share in kept]
        lines.append(f"| {name} | {totals[0]:.0f} | " + " | ".join(cells) + " |")
    lines += ["", "| checkpoint | " + " | ".join(f"median k={scale:g}" for scale in scales)
              + f" | images keeping > {LET_THROUGH:g} x truth at k={scales[-1]:g}"
              + f" | images keeping < {THROWN_AWAY:g} at k=1 |", "|" + "---|" * (len(scales) + 3)]
    for label, rows in shares.items():
        kept = np.array(rows)
        exact = [row[scales.index(1.0)] for row in rows] if 1.0 in scales else []
        lines.append(f"| {label} | " + " | ".join(f"{np.nanmedian(kept[:, i]):.2f}" for i in range(len(scales)))
                     + f" | {int((kept[:, -1] > LET_THROUGH).sum())} of {len(rows)}"
                     + (f" | {sum(share < THROWN_AWAY for share in exact)} of {len(rows)} |" if exact else " | - |"))
    publish(arguments, lines)
    return 0


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
