import numpy as np, sys, cv2
import hdrcam.recon.consistency as C
from hdrcam.train.checkpoint import load_model
orig = C._evidence_shares
def patched(observed, predicted, nuisance, unclipped, own, edge, sigma, outer_px):
    inner = cv2.dilate(edge.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    outer = cv2.dilate(own.astype(np.uint8), np.ones((2 * outer_px + 1,) * 2, np.uint8)) > 0
    for ch in range(3):
        ring = outer & ~inner & unclipped[..., ch]
        s = predicted[..., ch][ring].astype(np.float64)
        if ring.sum() < 8 or s @ s <= 0: continue
        v = observed[..., ch][ring].astype(np.float64); n = nuisance[..., ch][ring].astype(np.float64)
        D = np.stack([s, n, np.ones_like(s)], 1)
        sv = np.linalg.svd(D, compute_uv=False)
        f = np.linalg.pinv(D.T @ D)[0, 0]
        print(f'ch {ch} own {own.sum()} |signal| {np.linalg.norm(s):.3e} max {np.abs(s).max():.3e} |nuis| {np.linalg.norm(n):.3e} |obs| {np.linalg.norm(v):.3e} sv {sv} pinv00 {f:.3e} 1/|s|^2 {1/(s@s):.3e} corr(s,n) {np.corrcoef(s,n)[0,1]:.4f}')
    return orig(observed, predicted, nuisance, unclipped, own, edge, sigma, outer_px)
C._evidence_shares = patched
d = np.load(sys.argv[1]); model = load_model(); psf = model.psf / model.psf.sum(axis=(1, 2), keepdims=True)
C.make_consistent(d['y'], d['net'], psf)
