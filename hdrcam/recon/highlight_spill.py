"""Unclipped pixels taken from the frame, less the light the clipped highlights spread onto them (paper Eq. 6).

Where the frame did not clip it measured the scene convolved with the PSF, y = P * H. What a highlight adds
to its unclipped surroundings beyond what a smooth continuation of them would is the spill of its excess over
the clip level, P * (H_c - 1)+: the part at the clip level is exchanged with the neighbours as any locally
smooth radiance is (each pixel loses to its neighbours about what it receives). So the background is
y - P * (H_c - 1)+, clamped at 0. Subtracting the full P * H_c instead darkens a band around every clipped
region by the light the neighbours themselves lost into it: on 12 real validation photographs (network after
:mod:`hdrcam.recon.consistency`) it cost 0.11 dB on average and up to 1 dB (snowy field, 79 dB frame).

This replaces the network's own output on unclipped pixels: its splitting and fusion stages change dark
backgrounds by more than the streaks they remove (coloured blotches a preview shows).

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
    H x W clipped mask -> H x W x 3 float32: ``hdr`` on clipped pixels, frame - P * (hdr - 1)+ of the clipped
    pixels elsewhere."""
    output = np.array(frame, np.float32, copy=True)
    if not clipped.any():
        return output
    kernel = torch.from_numpy(np.ascontiguousarray(psf, np.float32))
    spill = np.zeros_like(output)
    for crop, own in clipped_clusters(clipped, psf.shape[-1] // 2):
        highlights = np.where(own[..., None], np.clip(hdr[crop] - 1.0, 0.0, None), 0.0)
        highlights = highlights.astype(np.float32).transpose(2, 0, 1)
        spilled = fft_convolve(torch.from_numpy(np.ascontiguousarray(highlights)), kernel)
        spill[crop] += spilled.clamp(min=0.0).numpy().transpose(1, 2, 0)  # light is not negative: FFT round-off
    return np.where(clipped[..., None], hdr, np.clip(output - spill, 0.0, None)).astype(np.float32)
