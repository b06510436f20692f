import numpy as np, sys
import hdrcam.recon.consistency as C
from hdrcam.train.checkpoint import load_model
orig = C._evidence_shares
def patched(observed, predicted, nuisance, unclipped, own, edge, sigma, outer_px):
    import cv2
    inner = cv2.dilate(edge.astype(np.uint8), np.ones((2 * C.EVIDENCE_INNER_PX + 1,) * 2, np.uint8)) > 0
    outer = cv2.dilate(own.astype(np.uint8), np.ones((2 * outer_px + 1,) * 2, np.uint8)) > 0
    for ch in range(3):
        ring = outer & ~inner & unclipped[..., ch]
        s = predicted[..., ch][ring].astype(np.float64); v = observed[..., ch][ring].astype(np.float64)
        if ring.sum() < 8 or s @ s <= 0: print(' ch', ch, 'no fit'); continue
        D = np.stack([s, nuisance[..., ch][ring].astype(np.float64), np.ones_like(s)], 1)
        c, *_ = np.linalg.lstsq(D, v, rcond=None)
        rv = np.mean((v - D @ c) ** 2); nv = np.mean(sigma[..., ch][ring] ** 2)
        f = np.linalg.pinv(D.T @ D)[0, 0] * C.TEXTURE_CORRELATION
        z = c[0] / np.sqrt(max(f * max(rv, nv), 1e-30)); tsd = np.sqrt(f * max(rv - nv, 0))
        print(f' ch {ch} own {own.sum()} ring {ring.sum()} a {c[0]:.3f} b {c[1]:.3f} z {z:.1f} s {np.sqrt(f*max(rv,nv)):.3f} texture_sd {tsd:.3f} resid/noise var {rv/nv:.2f} share {min(1,(c[0]+16*tsd)*(1-(3/z)**2)) if z>3 else 0:.3f}')
    out = orig(observed, predicted, nuisance, unclipped, own, edge, sigma, outer_px)
    print(' shares', out)
    return out
C._evidence_shares = patched
d = np.load(sys.argv[1])
model = load_model()
psf = model.psf / model.psf.sum(axis=(1, 2), keepdims=True)
for name, est in [('network (pair min)', d['net']), ('truth', np.where(d['y'] >= 1, np.maximum(d['t'], 1), d['y']))]:
    print(name)
    out, conf, rep = C.make_consistent(d['y'], est, psf)
    cm = (d['y'] >= 1).any(-1)
    print(' kept mean on clipped', out[cm].mean(0), 'truth', d['t'][cm].mean(0), rep.summary())
