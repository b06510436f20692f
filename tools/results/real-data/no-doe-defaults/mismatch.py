"""Frames captured through the bare lens (no DOE), reconstructed with the defaults (the shipped DOE's PSF):
what a user with an ordinary camera gets from `hdrcam reconstruct RAW` without --psf. evaluate's protocol."""
import sys, time
from pathlib import Path
import numpy as np
from hdrcam.evaluate import scoring
from hdrcam.data.scenes import SceneSource
from hdrcam.optics.psf_file import load_psf
from hdrcam.api import load_network_model

data, mode = sys.argv[1], sys.argv[2]  # mode: default (DOE PSF in the judge) or matched (bare lens PSF)
original = scoring.reconstruct
if mode == "default":
    scoring.reconstruct = lambda frame, model, psf=None, **kw: original(frame, model, psf=None, **kw)
dirac = load_psf(Path("runs/dirac-psf/psf.exr"))
model = load_network_model(None)
t = time.perf_counter()
rows, _ = scoring.evaluate_models({"hdrcam": model}, SceneSource(data), size_px=512, count=100, psf=dirac, examples=0)
by = {}
for r in rows:
    by.setdefault(r.image, {})[r.method] = r.metrics["psnr_linear"]
gains = []
for image, m in by.items():
    g = m["hdrcam"] - m["ldr"]; gains.append(g)
    print(f"{image:55s} ldr {m['ldr']:.2f} hdrcam {m['hdrcam']:.2f} gain {g:+.3f}")
gains = np.array(gains)
print(f"{mode} {data}: mean {gains.mean():+.3f} worst {gains.min():+.3f} below-0.3 {(gains < -0.3).sum()} "
      f"of {len(gains)} ({time.perf_counter() - t:.0f} s)")
