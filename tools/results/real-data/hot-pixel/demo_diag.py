"""Which specks the judge calls defects in the demo's night frame through its calibrated PSF and the design, and the
factor on the bounds each called speck needs to be explained.

Usage (repository root): python tools/results/real-data/hot-pixel/demo_diag.py DEMO_OUT
"""
import sys
import numpy as np
from hdrcam.io.exr import read_exr
from hdrcam.optics.psf_file import load_psf
from hdrcam.train.checkpoint import load_model
import hdrcam.recon.consistency as C
from hdrcam.recon.tiling import clipped_clusters
demo = sys.argv[1]
frame = read_exr(f"{demo}/5-night-frame.exr").rgb().astype(np.float32)
truth = read_exr(f"{demo}/5-night-truth.exr").rgb()
for label, psf in (("calibrated", np.asarray(load_psf(f"{demo}/3-calibration/psf.exr"), np.float32)),
                   ("design", np.asarray(load_model().psf, np.float32))):
    cc = frame >= C.CLIP_LEVEL; clipped = cc.any(-1)
    kernel = C._Kernel(psf)
    defects = np.zeros(clipped.shape, bool)
    for crop, own in clipped_clusters(clipped, psf.shape[-1] // 2):
        v = C._ClusterView.of(frame, cc, crop, own, psf, kernel, C.NoiseModel())
        d = np.zeros(clipped.shape, bool); d[v.region] = v.defect; defects |= d
    print(label, "psf", psf.shape, "centre", psf[:, psf.shape[1] // 2, psf.shape[2] // 2].round(3),
          "defects", int(defects.sum()))
    for r, c in np.argwhere(defects)[:6]:
        print("   defect", r, c, "truth", truth[r, c].round(2), "frame", frame[r, c].round(2))

# the least factor on y + allowance that makes each called speck explainable, through the calibrated PSF
from scipy.optimize import linprog
psf = np.asarray(load_psf(f"{demo}/3-calibration/psf.exr"), np.float32)
orig = C._light_explains
factors = []
def needed_factor(psf_c, sources, lit, needed, unclipped, most_received):
    at_least = C._transfer(psf_c, (sources[0][lit], sources[1][lit]), sources)
    at_most = C._transfer(psf_c, unclipped, sources)
    n = len(lit)
    # variables H (n) and m: minimise m; at_least H >= needed; at_most H - m most_received <= 0
    A = np.vstack([np.hstack([-at_least, np.zeros((len(at_least), 1))]), np.hstack([at_most, -most_received[:, None]])])
    b = np.concatenate([-needed, np.zeros(len(at_most))])
    r = linprog(np.r_[np.zeros(n), 1.0], A_ub=A, b_ub=b, bounds=(0, None), method="highs")
    return r.fun if r.status == 0 else np.inf
def spy(psf_c, sources, lit, needed, unclipped, most_received):
    ok = orig(psf_c, sources, lit, needed, unclipped, most_received)
    if not ok:
        factors.append(needed_factor(psf_c, sources, lit, needed, unclipped, most_received))
    return ok
C._light_explains = spy
cc = frame >= C.CLIP_LEVEL; clipped = cc.any(-1); kernel = C._Kernel(psf)
for crop, own in clipped_clusters(clipped, psf.shape[-1] // 2):
    C._ClusterView.of(frame, cc, crop, own, psf, kernel, C.NoiseModel())
print("factors needed for the called specks:", np.round(sorted(factors), 2)[-10:], "count", len(factors))
