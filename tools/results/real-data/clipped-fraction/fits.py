"""night-gen-000 at 5 % clipped: the evidence fits of its large clusters and its excess against the truth (one
network, no mirror pass). Usage: python fits.py FOLDER_WITH_THE_SCENE 0.05"""
import sys
import numpy as np
import hdrcam.data.saturation as saturation
import hdrcam.data.scenes as scenes
import hdrcam.evaluate.scoring as scoring
import hdrcam.recon.consistency as C
fraction = float(sys.argv[2])
saturation.TEST_CLIPPED_FRACTION = scenes.TEST_CLIPPED_FRACTION = scoring.TEST_CLIPPED_FRACTION = fraction
orig = C._evidence_shares
def patched(observed, predicted, nuisance, unclipped, own, edge, sigma, outer_px):
    import cv2
    inner = cv2.dilate(edge.astype(np.uint8), np.ones((2 * C.EVIDENCE_INNER_PX + 1,) * 2, np.uint8)) > 0
    outer = cv2.dilate(own.astype(np.uint8), np.ones((2 * outer_px + 1,) * 2, np.uint8)) > 0
    line = []
    for ch in range(3):
        ring = outer & ~inner & unclipped[..., ch]
        s = predicted[..., ch][ring].astype(np.float64); v = observed[..., ch][ring].astype(np.float64)
        if ring.sum() < 8 or s @ s <= 0: line.append("-"); continue
        D = np.stack([s, nuisance[..., ch][ring].astype(np.float64), np.ones_like(s)], 1)
        c, f = C._least_squares(D, v)
        rv = np.mean((v - D @ c) ** 2); nv = np.mean(sigma[..., ch][ring] ** 2); f *= C.TEXTURE_CORRELATION
        z = c[0] / np.sqrt(max(f * max(rv, nv), 1e-30))
        line.append(f"a {c[0]:.2f} z {z:.1f} sT {np.sqrt(f * max(rv - nv, 0)):.3f}")
    out = orig(observed, predicted, nuisance, unclipped, own, edge, sigma, outer_px)
    if own.sum() > 500:
        print(f"  own {own.sum()} ring-px {outer_px}: " + " | ".join(line) + f" -> shares {np.round(out[0], 2)}")
    return out
C._evidence_shares = patched
from hdrcam import api
from hdrcam.data.scenes import SceneSource
model = api.load_network_model(None)
hook_store = {}
o = scoring.reconstruct
def hook(frame, m, **kw):
    r = o(frame, m, **kw); hook_store["r"] = r; hook_store["f"] = frame; return r
scoring.reconstruct = hook
rows, _ = scoring.evaluate_models({"hdrcam": model}, SceneSource(sys.argv[1]), size_px=512, count=1, examples=0,
                                  partner=None, mirror_check=False)
print({r.method: round(r.metrics["psnr_linear"], 2) for r in rows})
from hdrcam.train.optical_capture import OpticalCapture
from hdrcam.profiles import load_profile
r, f = hook_store["r"], hook_store["f"]
cc = f >= 1.0
cap = OpticalCapture(load_profile(model.profile), psf=np.asarray(model.psf))
for name, scene, seed in SceneSource(sys.argv[1]).test_scenes(512, cap.margin_px, 1):
    t = scene[cap.margin_px:-cap.margin_px, cap.margin_px:-cap.margin_px]
print("true excess on clipped channels", float(np.clip(t - 1, 0, None)[cc].sum()),
      "network", float((r.network_hdr - 1)[cc].clip(0).sum()), "kept", float((r.hdr - 1)[cc].clip(0).sum()))
w = np.clip(t - 1, 0, None)[cc]; n = (r.hdr - 1)[cc]
print("corr(truth excess, kept excess) on clipped channels", float(np.corrcoef(w, n)[0, 1]),
      "truth max", float(t.max()), "kept max", float(r.hdr.max()))
