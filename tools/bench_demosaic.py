"""Demosaicing candidates, speed against accuracy, on frames whose full-colour truth is known.

- Real: the Sony ILCE-7RM3 ARW in ../shared/data/raw, black-subtracted and binned 2 x 2 (R, the mean of the
  two greens, B of each Bayer quad: a full-colour image at half size, made of measured samples only), then
  mosaicked again (RGGB) - the usual way to give a real photograph a known truth.
- Simulated: procedural night scenes (hdrcam.data.night_scene, clipped to white) mosaicked RGGB.
Inputs are 14-bit integers (what a RAW file holds); float candidates get the same values as float32.
PSNR in dB against the truth (peak = white), 4-pixel border left out; time per megapixel, best of 3, scaled
to 24 MP. Candidates: OpenCV bilinear and edge-aware (integer), hdrcam's float bilinear (OpenCV's weights by
cv2.filter2D, for merged HDR data), colour-demosaicing's bilinear, Malvar 2004 and Menon 2007.
Usage: python tools/bench_demosaic.py [--raw FILE.ARW] [--out tools/results/demosaic.md]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import one_line_errors  # noqa: E402
from reports import add_report_options, publish  # noqa: E402

import numpy as np

from hdrcam.io.demosaic import cfa_masks, demosaic
from hdrcam.io.raw import read_raw

WHITE_DN = 2 ** 14 - 1
BORDER_PX = 4


def candidates() -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import colour_demosaicing as library
    return {
        "OpenCV bilinear (hdrcam default, integer data)": lambda b: demosaic(b, "RGGB", "bilinear"),
        "hdrcam float bilinear (OpenCV weights; fuse's default)": lambda b: demosaic(b.astype(np.float32), "RGGB"),
        "OpenCV edge-aware (--demosaic edge-aware)": lambda b: demosaic(b, "RGGB", "edge-aware"),
        "colour-demosaicing bilinear": lambda b: library.demosaicing_CFA_Bayer_bilinear(b.astype(np.float32), "RGGB"),
        "colour-demosaicing Malvar 2004": lambda b: library.demosaicing_CFA_Bayer_Malvar2004(b.astype(np.float32),
                                                                                             "RGGB"),
        "colour-demosaicing Menon 2007 (--demosaic menon2007)": lambda b: demosaic(b, "RGGB", "menon2007"),
    }


def real_truth(path: Path) -> np.ndarray:
    """Half-size RGB (DN above black, 0 .. white) of a RAW file, binned from its Bayer quads."""
    frame = read_raw(path)
    black = np.tile(frame.metadata.black_level_tile(), (frame.bayer_dn.shape[0] // 2 + 1,
                                                        frame.bayer_dn.shape[1] // 2 + 1))
    signal = frame.bayer_dn.astype(np.float32) - black[:frame.bayer_dn.shape[0], :frame.bayer_dn.shape[1]]
    height, width = (s // 2 * 2 for s in signal.shape)
    quads = {colour: [] for colour in "RGB"}
    for position, colour in enumerate(frame.metadata.cfa_pattern):
        row, column = divmod(position, 2)
        quads[colour].append(signal[row:height:2, column:width:2])
    rgb = np.stack([np.mean(quads[colour], axis=0) for colour in "RGB"], axis=-1)
    white = frame.metadata.white_level_dn - float(np.mean(frame.metadata.black_level_dn))
    return np.clip(rgb / white, 0.0, 1.0)


def simulated_truth(seed: int) -> np.ndarray:
    from hdrcam.data.night_scene import night_scene

    return np.clip(night_scene(1024, 1536, seed=seed) * 4.0, 0.0, 1.0)


def mosaic(truth: np.ndarray) -> np.ndarray:
    """14-bit RGGB samples of an RGB image in [0, 1]."""
    chosen = (cfa_masks(truth.shape[:2], "RGGB").transpose(1, 2, 0) * truth).sum(axis=-1)
    return np.round(chosen * WHITE_DN).astype(np.uint16)


def psnr_db(estimate: np.ndarray, truth: np.ndarray) -> float:
    inner = (slice(BORDER_PX, -BORDER_PX), slice(BORDER_PX, -BORDER_PX))
    error = np.mean((np.asarray(estimate, np.float64)[inner] / WHITE_DN - truth[inner]) ** 2)
    return float(10 * np.log10(1.0 / error))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--raw", type=Path, default=Path("../shared/data/raw/sony-ilce7rm3-DSC2164.ARW"))
    add_report_options(parser, "tools/results/demosaic.md")
    arguments = parser.parse_args()
    one_line_errors.refuse_existing(arguments.out, arguments.overwrite)
    truths = {"real (A7R III, binned)": real_truth(arguments.raw)}
    truths |= {f"simulated night {seed}": simulated_truth(seed) for seed in (1, 2)}
    mosaics = {name: mosaic(truth) for name, truth in truths.items()}
    lines = ["`python tools/bench_demosaic.py` (PSNR in dB against the known truth; s at 24 MP extrapolated from "
             f"the real frame's {mosaics['real (A7R III, binned)'].size / 1e6:.1f} MP, best of 3):", "",
             "| method | " + " | ".join(truths) + " | s at 24 MP |", "|---|" + "---|" * (len(truths) + 1)]
    for label, function in candidates().items():
        scores = [psnr_db(function(mosaics[name]), truths[name]) for name in truths]
        real = mosaics["real (A7R III, binned)"]
        times = []
        for _ in range(3):
            started = time.perf_counter()
            function(real)
            times.append(time.perf_counter() - started)
        per_24mp = min(times) * 24e6 / real.size
        lines.append(f"| {label} | " + " | ".join(f"{s:.2f}" for s in scores) + f" | {per_24mp:.2f} |")
        print(lines[-1], flush=True)
    lines += ["", f"Load average (1 min) at the end: {os.getloadavg()[0]:.1f}."]
    publish(arguments, lines)


if __name__ == "__main__":
    sys.exit(one_line_errors.run(main))
