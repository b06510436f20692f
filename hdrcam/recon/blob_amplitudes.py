"""Non-negative brightness of clipped blobs fitted to the light their PSF spread onto unclipped pixels.

Per channel, the amplitudes a_k (relative radiance) of the blobs' fixed shapes s_k minimise

    || w (t - K * sum_k a_k s_k) ||^2 + sum_k p_k (a_k - e_k)^2,      a_k >= 0,

with t the image the blobs must explain, w >= 0 the pixels that enter the fit, K the (spread part of the)
PSF, and an optional prior pulling a_k towards e_k with weight p_k. Damped Jacobi steps divide the gradient
by the Hessian's row sums, sum_l <K * s_k, w K * s_l>: every entry is non-negative (s, K, w >= 0), so a row
sum bounds the row's diagonal and off-diagonal pull together and the steps never overshoot.
Used by the streak fit of the DOE (hdrcam.recon.highlight_refinement) and of windshields
(hdrcam.recon.windshield_fit). Label 0 of ``index`` is the background: its amplitude stays 0.
"""

from __future__ import annotations

import torch

from hdrcam.sensor import fft_convolve


def blob_sums(values: torch.Tensor, index: torch.Tensor, blob_count: int) -> torch.Tensor:
    """(C, H, W) -> (C, blobs): the sum of each channel over each label of the flattened ``index``."""
    sums = torch.zeros(values.shape[0], blob_count, dtype=values.dtype)
    return sums.index_add_(1, index, values.reshape(values.shape[0], -1))


def hessian_row_sums(weight: torch.Tensor, shapes: torch.Tensor, index: torch.Tensor, blob_count: int,
                     kernel: torch.Tensor) -> torch.Tensor:
    """(C, blobs): sum_l <K * s_k, w K * s_l>, the data term's curvature along each a_k plus its coupling."""
    flipped = torch.flip(kernel, (-2, -1))  # convolving with it correlates with K (the adjoint of K *)
    return blob_sums(shapes * fft_convolve(weight * fft_convolve(shapes, kernel), flipped), index, blob_count)


def fit_blob_amplitudes(target: torch.Tensor, weight: torch.Tensor, shapes: torch.Tensor, index: torch.Tensor,
                        blob_count: int, kernel: torch.Tensor, iterations: int, *,
                        prior_weight: torch.Tensor | None = None, prior_mean: torch.Tensor | None = None,
                        row_sums: torch.Tensor | None = None) -> torch.Tensor:
    """(C, blobs) amplitudes a_k >= 0 after ``iterations`` Jacobi steps from ``prior_mean`` (or 0).

    ``target`` (C, H, W), ``weight`` broadcastable to it, ``shapes`` (C, H, W) holding every blob's shape on its
    own pixels (0 elsewhere), ``index`` the flattened (H * W) blob label of each pixel, ``kernel`` (C, k, k);
    ``prior_weight`` and ``prior_mean`` (C, blobs) or None for no prior; ``row_sums`` from
    :func:`hessian_row_sums` when the caller already has them.
    """
    channels = target.shape[0]
    flipped = torch.flip(kernel, (-2, -1))
    if row_sums is None:
        row_sums = hessian_row_sums(weight, shapes, index, blob_count, kernel)
    if prior_weight is None:
        prior_weight = torch.zeros(channels, blob_count)
    prior_mean = torch.zeros(channels, blob_count) if prior_mean is None else prior_mean
    amplitude = prior_mean.clone()
    amplitude[:, 0] = 0.0
    for _ in range(iterations):
        model = fft_convolve(amplitude[:, index].reshape(shapes.shape) * shapes, kernel)
        gradient = blob_sums(shapes * fft_convolve(weight * (target - model), flipped), index, blob_count)
        step = (gradient - prior_weight * (amplitude - prior_mean)) / (row_sums + prior_weight).clamp(min=1e-12)
        amplitude = (amplitude + step).clamp(min=0.0)
        amplitude[:, 0] = 0.0
    return amplitude
