"""How many clipped specks of a real frame (the ARW) the judge calls sensor defects.

Usage (repository root): python tools/results/real-data/hot-pixel/arw_defects.py FRAME
"""
import sys
from pathlib import Path
import numpy as np
from hdrcam.io.ldr_frame import read_ldr_frame
from hdrcam.train.checkpoint import load_model
from hdrcam.recon.consistency import _ClusterView, _Kernel, NoiseModel, CLIP_LEVEL
from hdrcam.recon.tiling import clipped_clusters
import cv2
frame = read_ldr_frame(Path(sys.argv[1])).astype(np.float32)
psf = np.asarray(load_model().psf, np.float32)
cc = frame >= CLIP_LEVEL
clipped = cc.any(-1)
n, labels, stats, _ = cv2.connectedComponentsWithStats(clipped.astype(np.uint8), connectivity=8)
print("frame", frame.shape, "clipped px", int(clipped.sum()), "blobs", n - 1, "specks <=4 px", int((stats[1:, 4] <= 4).sum()))
kernel = _Kernel(psf)
defects = np.zeros(clipped.shape, bool)
for crop, own in clipped_clusters(clipped, psf.shape[-1] // 2):
    v = _ClusterView.of(frame, cc, crop, own, psf, kernel, NoiseModel())
    d = np.zeros(clipped.shape, bool); d[v.region] = v.defect
    defects |= d
at = np.argwhere(defects)
print("defect pixels", len(at))
for r, c in at[:20]:
    print(r, c, frame[r, c].round(3), "neighbours max", frame[r-1:r+2, c-1:c+2].reshape(-1, 3).max(0).round(3),
          "mean", frame[r-2:r+3, c-2:c+3].reshape(-1, 3).mean(0).round(3))
