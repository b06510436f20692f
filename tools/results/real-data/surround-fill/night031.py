import numpy as np, importlib.util
from hdrcam.train.checkpoint import load_model
from hdrcam.recon.tiling import clipped_mask, within_px
from hdrcam.recon.highlight_spill import subtract_highlight_spill as cand
from hdrcam.evaluate.metrics import pu21_psnr, pu21_encode, CANDELA_PER_UNIT
spec = importlib.util.spec_from_file_location('old_spill', '/work/main/hdrcam/recon/highlight_spill.py')
old_mod = importlib.util.module_from_spec(spec); spec.loader.exec_module(old_mod)
d = np.load('/work/scratch/spill/night-031.npz')
t, y, judged = d['t'], d['y'], d['old']
model = load_model(); psf = model.psf / model.psf.sum(axis=(1, 2), keepdims=True)
cm = clipped_mask(y)
old = old_mod.subtract_highlight_spill(y, judged, psf, cm); new = cand(y, judged, psf, cm)
print('pu21 old %.3f new %.3f' % (pu21_psnr(old, t), pu21_psnr(new, t)))
enc = lambda a: pu21_encode(np.clip(a, 0, None) * CANDELA_PER_UNIT)
et, eo, en = enc(t), enc(old), enc(new)
U = ~cm
for lo_, hi in ((0, 1), (1, 2), (2, 5), (5, 15), (15, 40)):
    band = (within_px(cm, hi) & ~within_px(cm, lo_) if lo_ else within_px(cm, hi)) & U
    print(f'band {lo_}-{hi}: n {band.sum()} truth {t[band].mean():.4f} frame {y[band].mean():.4f} old {old[band].mean():.4f} new {new[band].mean():.4f} '
          f'PU SE old {((eo-et)[band]**2).sum():.0f} new {((en-et)[band]**2).sum():.0f}')
# where are the worst increases
inc = ((en-et)**2 - (eo-et)**2).sum(-1)
idx = np.argsort(inc.ravel())[::-1][:8]
for i in idx:
    r_, c_ = np.unravel_index(i, inc.shape)
    print(r_, c_, 'inc %.1f' % inc[r_, c_], 't', t[r_, c_].round(3), 'y', y[r_, c_].round(3), 'old', old[r_, c_].round(3), 'new', new[r_, c_].round(3))
