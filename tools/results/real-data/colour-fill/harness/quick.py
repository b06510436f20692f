"""Fill (module, worktree) applied to cached old-pipeline outputs; gains vs LDR. Usage: quick.py CACHE [GAP] [RIM]"""
import os, sys
import numpy as np
from pathlib import Path
sys.path.insert(0, os.environ.get("TREE", "."))
import hdrcam.recon.colour_fill as cf
from hdrcam.evaluate.metrics import psnr_linear
from hdrcam.colorimetry import camera_from_srgb
cache = Path(sys.argv[1]); cf.RIM_GAP_PX = int(sys.argv[2]); cf.RIM_PX = int(sys.argv[3])
n = tuple(camera_from_srgb().sum(1)) if "cam" in cache.name else (1, 1, 1)
g0, g1 = [], []
for f in sorted(cache.glob("*.npz")):
    d = np.load(f); fr, t, h = d["frame"], d["truth"], d["hdr"]
    o, _ = cf.fill_from_unclipped_channels(fr, h, n)
    l = psnr_linear(fr, t); g0.append(psnr_linear(h, t) - l); g1.append(psnr_linear(o, t) - l)
g0, g1 = np.array(g0), np.array(g1)
print(f"{cache.name} gap {cf.RIM_GAP_PX} rim {cf.RIM_PX}: {g0.mean():+.3f} -> {g1.mean():+.3f} worst {g1.min():+.3f} "
      f"worst change {np.min(g1 - g0):+.3f}")
