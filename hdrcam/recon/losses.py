"""Training losses (paper Sec. 4, Eqs. 10-15) and the stage targets.

Targets, from the true scene radiance I (relative, 1.0 = full well, up to 2^8):
- I_U* = min(I, 1): what a camera without a DOE and with an infinite dynamic range above black would
  record below saturation (the sharp, streak-free, clipped image);
- I_S* = max(I, 1): the highlights, 1 where the scene is not saturated.
So I = I_U* + I_S* - 1 exactly.

L = L_U + L_S + L_F (Eq. 10) + w_E L_energy (the 94 % PSF regulariser, design runs only):
- L_U = a1 L_feat(I_U, I_U*) + a2 L_excl(I_U, I_r)            (Eq. 11; exclusion loss Eq. 12, Sec. 4.1)
- L_S = b L_feat(enc(I_S), enc(I_S*)), enc(x) = log2(x) / 8   (I_S in [1, 2^8] -> [0, 1])
- L_F = Huber((I_hat + eps)^0.5, (I + eps)^0.5)              (Eq. 15)
- L_gain = 10 log10(MSE(I_hat, I) / MSE(I_LDR, I)) (ours; weight 0 unless asked): minus the linear-PSNR gain over
  the captured frame, the evaluation's own measure, per scene. Eqs. 10-15 compress highlights (log2, square
  roots): a sun pixel at the 2^8 cap estimated at 1.5 costs L_S about 18 times a sky pixel at 2 estimated at
  1.5, where the squared linear error charges it about 260,000 times - and a few such pixels carry most of a
  daylight frame's linear error (tools/results/real-data/README.md, "Where the remaining gain lies").
L_feat is the VGG-19 perceptual loss on conv2_2, conv3_2 and conv4_2 (``paper`` preset) or, without VGG,
L1 of the image plus L1 of its x and y gradients (``lite``, ``fast``). The weights are ours: the paper does
not print them.

Class balance (ours): only 1-3 % of the pixels are saturated, so a plain mean lets the highlight terms
learn "no highlight anywhere" (it did). The non-VGG L_S and L_F are therefore means over the highlight
region plus means over the rest; an empty region contributes 0. The highlight region is where the truth
exceeds 1 (weight 1) or the frame clipped although the truth does not (weight HALO_WEIGHT): the PSF's core
makes a clipped blob larger than the source. Leaving that halo out of the region let the net paint whole
blobs several times too bright; giving it full weight made "no highlight" the median answer until the net
can localise sources, and training collapsed to I_S = 1.
"""

from __future__ import annotations

import dataclasses
import math

import torch
import torch.nn.functional as F

from hdrcam.recon.network import Reconstruction
from hdrcam.recon.stages import HIGHLIGHT_PEAK
from hdrcam.recon.vgg import PERCEPTUAL_LAYERS, Vgg19Features

SQRT_EPS = 1e-4  # eps of Eq. 15: keeps d sqrt(x)/dx finite (<= 50) at x = 0
HUBER_DELTA = 0.1
_GRADIENT_EPS = 1e-6
_EXCLUSION_EPS = 1e-10  # floor under the 4th root: keeps its gradient finite when the product is zero


@dataclasses.dataclass(frozen=True)
class LossWeights:
    feature_unsaturated: float = 1.0  # a1
    exclusion: float = 0.1  # a2
    feature_highlight: float = 2.0  # b
    fusion: float = 4.0  # the highlights are 1-3 % of the pixels but carry most of the linear error
    energy: float = 300.0  # w_E, only when the DOE is trained: 0.02 off target costs 0.12
    linear_gain: float = 0.0  # L_gain, per dB (0: the paper's Eq. 10 alone)


def stage_targets(radiance: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(I_U*, I_S*) = (min(I, 1), max(I, 1)) of the true radiance."""
    return radiance.clamp(max=1.0), radiance.clamp(min=1.0)


def highlight_encoding(highlight: torch.Tensor) -> torch.Tensor:
    """log2(I_S) / 8: [1, 2^8] -> [0, 1]."""
    return torch.log(highlight.clamp(min=1.0)) / math.log(HIGHLIGHT_PEAK)


def image_gradients(image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Forward differences along x and y."""
    return image[..., :, 1:] - image[..., :, :-1], image[..., 1:, :] - image[..., :-1, :]


CLIPPED_LEVEL = 0.99  # a frame pixel whose brightest channel reaches this counts as clipped
HALO_WEIGHT = 0.25


def highlight_region(radiance: torch.Tensor, ldr: torch.Tensor | None = None) -> torch.Tensor:
    """(N, 1, H, W) weights in [0, 1]: 1 where any channel of the true radiance exceeds 1, HALO_WEIGHT where
    only the frame clipped, 0 elsewhere."""
    region = (radiance.amax(dim=1, keepdim=True) > 1.0).to(radiance.dtype)
    if ldr is not None:
        halo = (ldr.amax(dim=1, keepdim=True) >= CLIPPED_LEVEL).to(radiance.dtype) * (1.0 - region)
        region = region + HALO_WEIGHT * halo
    return region


def balanced_mean(values: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Weighted mean over the region (weights ``mask`` in [0, 1]) plus the mean over its complement
    (weights 1 - mask); an empty side contributes 0."""
    mask = mask.expand_as(values)
    inside = (values * mask).sum() / mask.sum().clamp(min=1.0)
    outside = (values * (1.0 - mask)).sum() / (1.0 - mask).sum().clamp(min=1.0)
    return inside + outside


def feature_loss(estimate: torch.Tensor, target: torch.Tensor, vgg: Vgg19Features | None,
                 mask: torch.Tensor | None = None) -> torch.Tensor:
    """VGG perceptual loss (mean L1 over conv2_2, conv3_2, conv4_2) or, without VGG, L1 + gradient L1
    (class-balanced over ``mask`` when given)."""
    if vgg is not None:
        estimated = vgg(estimate.clamp(0.0, 1.0), PERCEPTUAL_LAYERS)
        wanted = vgg(target.clamp(0.0, 1.0), PERCEPTUAL_LAYERS)
        return sum(F.l1_loss(estimated[name], wanted[name]) for name in PERCEPTUAL_LAYERS) / len(PERCEPTUAL_LAYERS)
    gradient_loss = sum(F.l1_loss(a, b) for a, b in zip(image_gradients(estimate), image_gradients(target)))
    if mask is None:
        return F.l1_loss(estimate, target) + gradient_loss
    return balanced_mean((estimate - target).abs(), mask) + gradient_loss


def exclusion_loss(first: torch.Tensor, second: torch.Tensor, scales: int = 3) -> torch.Tensor:
    """Eq. 12: sum over scales of ||tanh(l1 |grad first|) * tanh(l2 |grad second|)||^(1/2), per axis.

    l1 = 1 and l2 = mean|grad first| / mean|grad second| balance the two images' gradient magnitudes
    (Zhang et al. 2018); l2 is not differentiated. Finite for constant or all-zero images.
    """
    total = first.new_zeros(())
    for scale in range(scales):
        if scale:
            first, second = F.avg_pool2d(first, 2), F.avg_pool2d(second, 2)
        for grad_first, grad_second in zip(image_gradients(first), image_gradients(second)):
            balance = (grad_first.abs().mean() / (grad_second.abs().mean() + _GRADIENT_EPS)).detach()
            product = torch.tanh(grad_first.abs()) * torch.tanh(balance * grad_second.abs())
            total = total + (product.pow(2).mean() + _EXCLUSION_EPS).pow(0.25)
    return total / scales


def sqrt_huber_loss(estimate: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Eq. 15: Huber loss between (x + eps)^0.5 of the estimate and of the truth (negative x taken as 0);
    class-balanced over ``mask`` when given."""
    huber = F.huber_loss(torch.sqrt(estimate.clamp(min=0.0) + SQRT_EPS), torch.sqrt(target.clamp(min=0.0) + SQRT_EPS),
                         delta=HUBER_DELTA, reduction="none")
    return huber.mean() if mask is None else balanced_mean(huber, mask)


GAIN_CEILING_DB = 30.0  # L_gain stops rewarding a scene once its error is 30 dB below the frame's


def linear_gain_loss(estimate: torch.Tensor, target: torch.Tensor, ldr: torch.Tensor) -> torch.Tensor:
    """Mean over the batch of 10 log10(MSE(estimate, target) / MSE(ldr, target)) in dB (both (N, 3, H, W),
    linear, white = 1): minus each scene's linear-PSNR gain over its captured frame. Both errors carry a floor
    of the frame's error x 10^(-GAIN_CEILING_DB / 10), so a scene the frame already gets right (no pixel above
    white: error 0) adds nothing and no scene's gradient grows without bound."""
    ldr_error = (ldr - target).pow(2).mean(dim=(1, 2, 3))
    error = (estimate - target).pow(2).mean(dim=(1, 2, 3))
    floor = ldr_error.detach() * 10 ** (-GAIN_CEILING_DB / 10) + torch.finfo(estimate.dtype).tiny
    return (10 * torch.log10((error + floor) / (ldr_error.detach() + floor))).mean()


def reconstruction_loss(output: Reconstruction, radiance: torch.Tensor, weights: LossWeights,
                        vgg: Vgg19Features | None, ldr: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """The terms of Eq. 10 and their sum ``total`` (energy regulariser excluded: see train.design);
    ``ldr``, the network's input, widens the highlight region to the pixels it clipped."""
    unsaturated_target, highlight_target = stage_targets(radiance)
    saturated = highlight_region(radiance, ldr)
    terms = {
        "unsaturated": weights.feature_unsaturated * feature_loss(output.unsaturated, unsaturated_target, vgg),
        "exclusion": weights.exclusion * exclusion_loss(output.unsaturated, output.residual),
        "highlight": weights.feature_highlight * feature_loss(highlight_encoding(output.highlight),
                                                              highlight_encoding(highlight_target), vgg, saturated),
        "fusion": weights.fusion * sqrt_huber_loss(output.hdr, radiance, None if vgg is not None else saturated),
    }
    if weights.linear_gain:
        if ldr is None:
            raise ValueError("the linear-gain loss needs the captured frame")
        terms["linear_gain"] = weights.linear_gain * linear_gain_loss(output.hdr, radiance, ldr)
    terms["total"] = sum(terms.values())
    return terms
