import os, sys
import numpy as np
from pathlib import Path
sys.path.insert(0, os.environ.get("TREE", "."))
from hdrcam.evaluate.metrics import psnr_linear, pu21_psnr
base, new = Path(sys.argv[1]), Path(sys.argv[2])
g0, g1, p0, p1 = [], [], [], []
for f in sorted(new.glob("*.npz")):
    a, b = np.load(base / f.name), np.load(f)
    t, fr = b["truth"], b["frame"]
    l = psnr_linear(fr, t)
    g0.append(psnr_linear(a["hdr"], t) - l); g1.append(psnr_linear(b["hdr"], t) - l)
    p0.append(pu21_psnr(a["hdr"], t) - pu21_psnr(fr, t)); p1.append(pu21_psnr(b["hdr"], t) - pu21_psnr(fr, t))
    if abs(g1[-1] - g0[-1]) > 0.02 or len(sys.argv) > 3:
        print("%-42s %+7.3f -> %+7.3f" % (f.stem[:42], g0[-1], g1[-1]))
g0, g1 = np.array(g0), np.array(g1)
print(f"n {len(g0)} mean {g0.mean():+.3f} -> {g1.mean():+.3f} worst {g0.min():+.3f} -> {g1.min():+.3f} "
      f"PU21 {np.mean(p0):+.3f} -> {np.mean(p1):+.3f}")
