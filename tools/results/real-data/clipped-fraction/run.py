"""evaluate's protocol with another clipped fraction (scenes scaled so this share of pixels exceeds 1; default
pair, judge, one thread): is the do-no-harm bar held when a frame clips more or less than the protocol's 1.5 %?"""
import sys, time
import numpy as np
import hdrcam.data.saturation as saturation
import hdrcam.data.scenes as scenes
import hdrcam.evaluate.scoring as scoring
fraction = float(sys.argv[2])
saturation.TEST_CLIPPED_FRACTION = scenes.TEST_CLIPPED_FRACTION = scoring.TEST_CLIPPED_FRACTION = fraction
from hdrcam.api import load_network_model
from hdrcam.data.scenes import SceneSource
t = time.perf_counter()
rows, _ = scoring.evaluate_models({"hdrcam": load_network_model(None)}, SceneSource(sys.argv[1]), size_px=512,
                                  count=100, examples=0)
by = {}
for r in rows:
    by.setdefault(r.image, {})[r.method] = (r.metrics["psnr_linear"], r.clipped_fraction)
gains = []
for image, m in by.items():
    g = m["hdrcam"][0] - m["ldr"][0]; gains.append(g)
    print(f"{image:55s} clipped {m['ldr'][1]:.4f} ldr {m['ldr'][0]:.2f} gain {g:+.3f}")
gains = np.array(gains)
print(f"fraction {fraction} {sys.argv[1]}: mean {gains.mean():+.3f} worst {gains.min():+.3f} below-0.3 "
      f"{(gains < -0.3).sum()} of {len(gains)} ({time.perf_counter() - t:.0f} s)")
