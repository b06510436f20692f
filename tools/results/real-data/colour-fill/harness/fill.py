"""Cross-channel fill variants on cached frames/outputs. Usage: python fill.py CACHEDIR [variant...]"""
import sys, os
from pathlib import Path
import numpy as np, cv2
sys.path.insert(0, os.environ.get("TREE", "."))
from hdrcam.evaluate.metrics import psnr_linear, pu21_psnr

CLIP = 0.999
from hdrcam.colorimetry import camera_from_srgb
_n = camera_from_srgb().sum(1)
NEUTRAL = {'srgb': (1.0, 1.0, 1.0), 'cam': tuple(_n / _n.max())}

def ratio_estimate(f, radius=15, min_ref=0.05):
    """Per clipped channel k on a pixel with some channel unclipped: f_j * (sum f_k / sum f_j) over
    neighbours unclipped in all channels with f_j > min_ref, j the unclipped channels (f_j-weighted)."""
    clipped = f >= CLIP
    ok = ~clipped.any(-1)
    est = np.zeros_like(f); have = np.zeros(f.shape, bool)
    size = (2 * radius + 1,) * 2
    for k in range(3):
        num_tot = np.zeros(f.shape[:2], np.float32); w_tot = np.zeros(f.shape[:2], np.float32)
        for j in range(3):
            if j == k: continue
            w = (ok & (f[..., j] > min_ref)).astype(np.float32)
            num = cv2.boxFilter(f[..., k] * w, -1, size, normalize=False, borderType=cv2.BORDER_REFLECT)
            den = cv2.boxFilter(f[..., j] * w, -1, size, normalize=False, borderType=cv2.BORDER_REFLECT)
            use = clipped[..., k] & ~clipped[..., j] & (den > 1e-3)
            r = np.where(use, num / np.maximum(den, 1e-3), 0)
            num_tot += np.where(use, f[..., j] * r * f[..., j], 0); w_tot += np.where(use, f[..., j], 0)
        sel = w_tot > 0
        est[..., k][sel] = np.maximum(num_tot[sel] / w_tot[sel], 1.0)
        have[..., k] = sel
    return est, have

def run(cache, variant):
    rows = []
    for p in sorted(Path(cache).glob("*.npz")):
        d = np.load(p); f, t, h = d["frame"], d["truth"], d["hdr"]
        if variant.startswith("rim"):
            opts = dict(kv.split("=") for kv in variant.split(":")[1:])
            est, have = ratio_estimate_rim(f, rim_px=int(opts.get("rim", 3)), power=float(opts.get("p", 2)),
                                           best_ref=opts.get("best", "0") == "1",
                                           alpha=float(opts.get("a", 1)), neutral=NEUTRAL[os.path.basename(cache.rstrip('/')).split('-')[-1]])
            variant_ = "max"
        else:
            est, have = ratio_estimate(f); variant_ = variant
        if variant_ == "max":
            o = np.where(have, np.maximum(h, est), h)
        elif variant_ == "replace":
            o = np.where(have, est, h)
        elif variant_ == "ldr":
            o = np.where(have, est, f)
        else:
            raise SystemExit(variant)
        rows.append((p.stem, psnr_linear(f, t), psnr_linear(h, t) - psnr_linear(f, t), psnr_linear(o, t) - psnr_linear(f, t),
                     pu21_psnr(h, t) - pu21_psnr(f, t), pu21_psnr(o, t) - pu21_psnr(f, t), int(have.sum())))
    for r in rows:
        print("%-42s LDR %6.2f hdrcam %+7.3f cand %+7.3f | PU21 %+6.2f %+6.2f n %d" % (r[0][:42], *r[1:]))
    a = np.array([r[1:6] for r in rows])
    worst = (a[:, 2]).min()
    print("%s %s: mean hdrcam %+.3f cand %+.3f (worst %+.3f, below -0.3: %d)  PU21 %+.3f %+.3f" % (
        cache, variant, a[:, 1].mean(), a[:, 2].mean(), worst, int((a[:, 2] < -0.3).sum()), a[:, 3].mean(), a[:, 4].mean()))


def ratio_estimate_rim(f, rim_px=3, radii=(7, 15, 31, 63), min_ref=0.05, power=2, best_ref=False, alpha=1.0, neutral=(1, 1, 1)):
    """Hue from the highlight's rim: unclipped pixels within rim_px of a pixel clipped in k, weighted f_j^power;
    the smallest window holding rim pixels decides."""
    clipped = f >= CLIP
    ok = ~clipped.any(-1)
    est = np.zeros_like(f); have = np.zeros(f.shape, bool)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * rim_px + 1,) * 2)
    for k in range(3):
        near = cv2.dilate(clipped[..., k].astype(np.uint8), kernel).astype(bool)
        cand = []
        for j in range(3):
            if j == k: continue
            w = (ok & near & (f[..., j] > min_ref)).astype(np.float32) * f[..., j] ** power
            r = np.zeros(f.shape[:2], np.float32); done = np.zeros(f.shape[:2], bool)
            for rad in radii:
                size = (2 * rad + 1,) * 2
                num = cv2.boxFilter(f[..., k] * w, -1, size, normalize=False, borderType=cv2.BORDER_REFLECT)
                den = cv2.boxFilter(f[..., j] * w, -1, size, normalize=False, borderType=cv2.BORDER_REFLECT)
                new = ~done & (den > 1e-4)
                r[new] = num[new] / den[new]; done |= new
            use = clipped[..., k] & ~clipped[..., j] & done
            r = np.exp(alpha * np.log(np.maximum(r, 1e-6)) + (1 - alpha) * np.log(neutral[k] / neutral[j]))
            cand.append((j, np.where(use, f[..., j] * r, 0), use))
        if best_ref:
            (j1, e1, u1), (j2, e2, u2) = cand
            pick1 = u1 & (~u2 | (f[..., j1] >= f[..., j2]))
            e = np.where(pick1, e1, e2); u = u1 | u2
        else:
            (j1, e1, u1), (j2, e2, u2) = cand
            w1 = np.where(u1, f[..., j1], 0); w2 = np.where(u2, f[..., j2], 0)
            u = u1 | u2
            e = np.where(u, (e1 * w1 + e2 * w2) / np.maximum(w1 + w2, 1e-9), 0)
        est[..., k][u] = np.maximum(e[u], 1.0); have[..., k] = u
    return est, have

if __name__ == '__main__':
    for v in sys.argv[2:]:
        run(sys.argv[1], v)
