"""The bar of tests/recon/test_do_no_harm.py's border test, through the shipped DOE, judged by the tree on
sys.path: linear PSNR of the frame and of reconstruct (one network, then the default pair).
Usage (repository root): python tools/results/real-data/frame-border/bar_near_border.py SEED"""
import sys

import numpy as np

sys.path.insert(0, ".")
from hdrcam.api import reconstruct  # noqa: E402
from tests.recon.test_do_no_harm import capture, grid, load_model, psnr_linear  # noqa: E402

model = load_model()
margin, size, seed = 40, 128, int(sys.argv[1])
rows, columns = grid(size + 2 * margin, size + 2 * margin)
scene = np.repeat((0.2 + 0.2 * (columns - margin) / (size - 1))[..., None], 3, axis=-1)
scene[margin + 98:margin + 110, margin + 14:margin + 38] = 1.05
inside = (slice(margin, margin + size), slice(margin, margin + size))
frame, truth = capture(scene, model.psf, seed=seed)[inside], scene[inside]
for label, options in (("one network", dict(partner=None, mirror_check=False)), ("default pair", {})):
    result = reconstruct(frame, model, **options)
    print(f"seed {seed}, {label}: frame {psnr_linear(frame, truth):.2f} dB, reconstruction "
          f"{psnr_linear(result.hdr, truth):.2f} dB; {result.consistency.summary()}")
