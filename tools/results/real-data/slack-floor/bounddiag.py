"""Dev seed 11, night-gen-010: where the judge's upper bound cuts the pair's proposal below the truth."""
import numpy as np, torch, cv2
import hdrcam
import hdrcam.recon.consistency as C
from hdrcam.data.scenes import SceneSource
from hdrcam.train.checkpoint import load_model
from hdrcam.train.optical_capture import OpticalCapture
from hdrcam.profiles import load_profile
from hdrcam.api import resolve_partner

model = load_model(None); partner = resolve_partner(model, "auto")
cap = OpticalCapture(load_profile(model.profile), psf=model.psf); m = cap.margin_px
for name, scene, seed in SceneSource('/work/scratch/nightgen/dev11', lenient=True).test_scenes(512, m, 10**6):
    if name != 'night-gen-010': continue
    truth = scene[m:-m, m:-m]
    with torch.no_grad():
        ldr, _ = cap(torch.from_numpy(scene).permute(2, 0, 1)[None], torch.Generator().manual_seed(seed))
    frame = ldr[0].permute(1, 2, 0).numpy().astype(np.float32)
    stages = []
    orig = C._bounded_excess
    def spy(slack, unclipped, excess, kernel):
        bounded = excess.copy()
        window = np.ones((2 * C.LOCAL_BOUND_PX + 1,) * 2, np.uint8)
        for it in range(C.LOCAL_BOUND_ITERATIONS):
            headroom = C._headroom(slack, unclipped, C._convolve(bounded, kernel))
            for c in range(3):
                bounded[..., c] *= cv2.erode(headroom[..., c], window, borderType=cv2.BORDER_REPLICATE)
            stages.append((f'local {it+1}', float(bounded.sum())))
        spill = C._convolve(bounded, kernel)
        h = C._headroom(slack, unclipped, spill)
        scale = h.min(axis=(0, 1))
        if excess.sum() > 20000:
            for c in range(3):
                where = np.unravel_index(np.argmin(h[..., c]), h[..., c].shape)
                stages.append((f'ch{c} exact scale {scale[c]:.3f} at {where}, slack {slack[where][c]:.4f} '
                               f'spill {spill[where][c]:.4f}', 0))
        stages.append(('proposed', float(excess.sum())))
        return orig(slack, unclipped, excess, kernel)
    C._bounded_excess = spy
    r = hdrcam.reconstruct(frame, model, partner=partner)
    for s in stages:
        if 'exact' in s[0] or s[1] > 20000: print(s)
    clip = (frame >= 0.999).any(-1)
    print('truth excess', float(np.clip(truth - 1, 0, None)[frame >= 0.999].sum()))
    np.savez_compressed('/work/scratch/nightgen/ng010.npz', frame=frame, truth=truth, hdr=r.hdr, net=r.network_hdr)
