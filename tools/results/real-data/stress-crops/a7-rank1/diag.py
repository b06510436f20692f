import sys, numpy as np, torch
from hdrcam.data.scenes import SceneSource
from hdrcam.profiles import load_profile
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import OpticalCapture
from hdrcam.api import reconstruct
from hdrcam.recon.tiling import clipped_mask, clipped_clusters
torch.set_num_threads(2)
model = load_model('hdrcam/checkpoints/table2/rank1.pt')
cap = OpticalCapture(load_profile(model.profile), psf=model.psf)
m = cap.margin_px
for name, scene, seed in SceneSource(sys.argv[1]).test_scenes(512, m, 1):
    t = scene[m:m+512, m:m+512]
    with torch.no_grad():
        ldr, _ = cap(torch.from_numpy(scene).permute(2,0,1)[None], torch.Generator().manual_seed(seed))
    y = ldr[0].permute(1,2,0).numpy().astype(np.float32)
    r = reconstruct(y, model)
    cm = clipped_mask(y); tc = np.clip(t, 0, 256)
    se = lambda a, k: ((np.clip(a, 0, 256) - tc) ** 2)[k].sum()
    print(name, 'clipped', cm.sum(), r.consistency.summary())
    print('SE clipped ldr %.1f recon %.1f; unclipped ldr %.2f recon %.2f' % (se(y, cm), se(r.hdr, cm), se(y, ~cm), se(r.hdr, ~cm)))
    for crop, own in clipped_clusters(cm, model.psf.shape[-1] // 2):
        o = np.zeros(cm.shape, bool); o[crop] = own
        print(' cluster px', own.sum(), 'truth mean', t[o].mean(0).round(2), 'kept', r.hdr[o].mean(0).round(2), 'network', r.network_hdr[o].mean(0).round(2), 'SE ldr %.1f recon %.1f' % (se(y, o), se(r.hdr, o)))
    np.savez_compressed(f'{sys.argv[1]}/{name}.npz', t=t, y=y, r=r.hdr, net=r.network_hdr)
