"""Judge time on a dark frame holding many hot pixels (a long exposure without darks).

Usage (repository root): python tools/results/real-data/hot-pixel/many_hot.py HEIGHT WIDTH COUNT
"""
import sys, time
import numpy as np
from hdrcam.train.checkpoint import load_model
from hdrcam.recon.consistency import judge_estimates
import torch
torch.set_num_threads(2)
height, width, count = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
rng = np.random.default_rng(0)
frame = (0.005 + 0.001 * rng.standard_normal((height, width, 3))).clip(0, 1).astype(np.float32)
rows, cols = rng.integers(8, height - 8, count), rng.integers(8, width - 8, count)
frame[rows, cols] = 1.0
psf = np.asarray(load_model().psf, np.float32)
t = time.perf_counter()
(out, conf, report), = judge_estimates(frame, [np.where(frame >= 0.99, 3.0, frame).astype(np.float32)], psf)
print(f"{height}x{width}, {count} hot pixels: judge {time.perf_counter() - t:.1f} s; clusters {report.clusters}, "
      f"defects {report.defect_pixels}, kept {report.kept_excess:.1f} of {report.proposed_excess:.1f}")
