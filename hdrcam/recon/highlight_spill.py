"""Unclipped pixels taken from the frame, less the light the clipped highlights spread onto them (Eq. 1).

Where the frame did not clip it measured the scene convolved with the PSF, y = P * H. Split H into the
radiance of the clipped pixels H_c (the reconstruction there: the network's highlights after the streak fit)
and the rest; on an unclipped pixel the rest contributes the background blurred by the PSF, which is the
background to within that blur, so the background is y - P * H_c, clamped at 0. This replaces the network's
own output on unclipped pixels: on a CPU training budget its splitting and fusion stages change dark
backgrounds by more than the streaks they remove (on the demo frame the network's mean absolute error on
unclipped pixels is 0.0099 against 0.0034 for the frame itself, in coloured blotches a preview shows).
Measured (tools/results/streak-fit.md; linear / PU21 PSNR in dB, streak fit alone -> with this): demo
52.66/31.07 -> 52.74/33.84 (the frame: 52.37/32.50), rank-1 32.53/29.27 -> 32.53/29.97, Dirac
34.43/34.56 -> 35.43/39.39, dual-peak 34.79/34.80 -> 34.99/36.73.

Only what the frame needs is computed: the spill of each cluster of clipped pixels is convolved in its own
crop (the cluster grown by the PSF radius); beyond that reach the output is the frame.
"""

from __future__ import annotations

import numpy as np
import torch

from hdrcam.recon.tiling import clipped_clusters
from hdrcam.sensor import fft_convolve


def subtract_highlight_spill(frame: np.ndarray, hdr: np.ndarray, psf: np.ndarray, clipped: np.ndarray) -> np.ndarray:
    """H x W x 3 frame in [0, 1], its HDR reconstruction (relative radiance), the (3, k, k) unit-sum PSF and the
    H x W clipped mask -> H x W x 3 float32: ``hdr`` on clipped pixels, frame - P * (hdr on clipped) elsewhere."""
    output = np.array(frame, np.float32, copy=True)
    if not clipped.any():
        return output
    kernel = torch.from_numpy(np.ascontiguousarray(psf, np.float32))
    spill = np.zeros_like(output)
    for crop, own in clipped_clusters(clipped, psf.shape[-1] // 2):
        highlights = np.where(own[..., None], hdr[crop], 0.0).astype(np.float32).transpose(2, 0, 1)
        spilled = fft_convolve(torch.from_numpy(np.ascontiguousarray(highlights)), kernel)
        spill[crop] += spilled.numpy().transpose(1, 2, 0)
    return np.where(clipped[..., None], hdr, np.clip(output - spill, 0.0, None)).astype(np.float32)
