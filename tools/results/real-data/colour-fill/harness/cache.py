"""Cache evaluate-protocol frames, truths and hdrcam.reconstruct outputs (sRGB and camera-RGB variants).
Usage: TREE=... python cache.py DATA OUT [srgb|cam]"""
import sys, os
from pathlib import Path
import numpy as np, torch
TREE = os.environ.get("TREE", ".")
sys.path.insert(0, TREE)
from hdrcam.train.checkpoint import load_model
from hdrcam.data.scenes import SceneSource
from hdrcam.train.optical_capture import OpticalCapture
from hdrcam.profiles import load_profile
from hdrcam.api import reconstruct
from hdrcam.colorimetry import camera_from_srgb

data, out, space = sys.argv[1], Path(sys.argv[2]), sys.argv[3]
out.mkdir(parents=True, exist_ok=True)
model = load_model()
capture = OpticalCapture(load_profile(model.profile), psf=model.psf)
margin = capture.margin_px
M = camera_from_srgb().astype(np.float32)
source = SceneSource(data, lenient=True)
for name, scene, scene_seed in source.test_scenes(512, margin, 0):
    f = out / f"{name}.npz"
    if f.exists():
        continue
    if space == "cam":
        scene = np.clip(scene @ M.T, 0, None).astype(np.float32)
    radiance = torch.from_numpy(np.ascontiguousarray(scene)).permute(2, 0, 1)[None]
    with torch.no_grad():
        ldr, _ = capture(radiance, torch.Generator().manual_seed(0 * 100_003 + scene_seed))
    frame = ldr[0].permute(1, 2, 0).numpy().astype(np.float32)
    kw = {"neutral_rgb": tuple(M.sum(1))} if (space == "cam" and os.environ.get("NEUTRAL")) else {}
    result = reconstruct(frame, model, **kw)
    truth = scene[margin:margin + 512, margin:margin + 512]
    np.savez_compressed(f, frame=frame, truth=truth, hdr=result.hdr.astype(np.float32))
    print(name, flush=True)
