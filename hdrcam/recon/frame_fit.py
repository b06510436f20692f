"""The network's HDR estimate made consistent with the frame it came from (paper Eq. 1: frame = PSF * scene).

Two steps, each in its own module: the brightness of every clipped blob is fitted to the streaks its light
left on unclipped pixels (:mod:`hdrcam.recon.highlight_refinement`), then the unclipped pixels are the frame
less the fitted highlights' spill (:mod:`hdrcam.recon.highlight_spill`). ``reconstruct`` and ``evaluate``
both call this, so the scores are those of what users get.
"""

from __future__ import annotations

import numpy as np

from hdrcam.recon.highlight_refinement import RefinementReport, refine_highlight_amplitudes
from hdrcam.recon.highlight_spill import subtract_highlight_spill
from hdrcam.recon.tiling import clipped_mask


def fit_to_frame(frame: np.ndarray, network_hdr: np.ndarray, psf: np.ndarray) -> tuple[np.ndarray, RefinementReport]:
    """H x W x 3 frame in [0, 1], the network's H x W x 3 reconstruction (relative radiance) and the (3, k, k)
    unit-sum PSF the frame was taken through -> (H x W x 3 float32 reconstruction, the streak fit's report)."""
    clipped = clipped_mask(frame)
    fitted, report = refine_highlight_amplitudes(frame, network_hdr, psf, clipped)
    return subtract_highlight_spill(frame, fitted, psf, clipped), report
