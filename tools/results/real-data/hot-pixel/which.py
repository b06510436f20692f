"""How many clipped specks the judge calls sensor defects on evaluate's captured frames (development sets only).

Usage (repository root): python tools/results/real-data/hot-pixel/which.py DATA [NAME ...] - DATA a folder of
HDR images or "procedural" (its 32 test scenes); prints each scene's clipped pixels and defect pixels, and the first
eight defects with their frame, truth and neighbours.
"""
import sys
import numpy as np, torch
from hdrcam.data.scenes import SceneSource
from hdrcam.profiles import load_profile
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import OpticalCapture
from hdrcam.recon.consistency import _ClusterView, _Kernel, NoiseModel, CLIP_LEVEL
from hdrcam.recon.tiling import clipped_clusters
model = load_model()
cap = OpticalCapture(load_profile(model.profile), psf=model.psf)
m = cap.margin_px
psf = np.asarray(model.psf, np.float32); kernel = _Kernel(psf); c = psf.shape[-1] // 2
names = set(sys.argv[2:])
for name, scene, seed in SceneSource(sys.argv[1], lenient=True).test_scenes(512, m, 32 if sys.argv[1] == "procedural" else 10**6):
    if names and not any(n in name for n in names):
        continue
    truth = scene[m:m+512, m:m+512]
    with torch.no_grad():
        ldr, _ = cap(torch.from_numpy(scene).permute(2, 0, 1)[None], torch.Generator().manual_seed(seed))
    frame = ldr[0].permute(1, 2, 0).numpy().astype(np.float32)
    cc = frame >= CLIP_LEVEL; clipped = cc.any(-1)
    defects = np.zeros(clipped.shape, bool)
    for crop, own in clipped_clusters(clipped, c):
        v = _ClusterView.of(frame, cc, crop, own, psf, kernel, NoiseModel())
        d = np.zeros(clipped.shape, bool); d[v.region] = v.defect; defects |= d
    print(name, "clipped", int(clipped.sum()), "defects", int(defects.sum()), flush=True)
    for r, col in np.argwhere(defects)[:8]:
        print("   ", r, col, "frame", frame[r, col].round(3), "truth", truth[r, col].round(3),
              "truth 3x3 max", truth[max(r-1,0):r+2, max(col-1,0):col+2].reshape(-1, 3).max(0).round(3),
              "frame nb min", frame[max(r-1,0):r+2, max(col-1,0):col+2].reshape(-1, 3).min(0).round(3))
