"""The three stages of the reconstruction network (paper Sec. 4.1-4.3), NCHW, linear relative radiance.

- :class:`SplittingNet` f_U: LDR frame (optionally with its VGG-19 hypercolumn, bilinearly upsampled)
  -> 1x1 conv to C -> seven 3x3 convs with dilation 1..64 (InstanceNorm + LeakyReLU 0.2) -> 1x1 conv to
  6 channels: the unsaturated image I_U (3) and the residual I_r (3) that holds the encoded streaks.
  I_U is predicted as a correction of the input (I_U = LDR + first three channels): most of a frame is
  already its own unsaturated image, so the net only has to learn what to take away.
- :class:`HighlightUNet` f_S: (I_r, LDR) -> the highlight image I_S in [1, 2^8]. The paper feeds f_S the
  residual alone; we also give it the frame, which shows where the sensor clipped: on a CPU budget the net
  otherwise never learned to find the highlights (1000 steps left I_S = 1 everywhere). Five scales joined
  by 2x2 max-pools; decoder: nearest upsampling + 3x3 conv, skip concatenation, two 3x3 convs. First layer
  7x7, last 1x1; InstanceNorm + LeakyReLU everywhere except the last two layers. Output
  I_S = exp(min(softplus(y), ln 2^8)): at least 1, at most 2^8, and unlike a sigmoid it does not saturate
  at the bottom, where almost every pixel sits (a sigmoid output collapsed to I_S = 1 in training). The
  final bias starts at -2, so an untrained net predicts I_S ~ 1.1.
- :class:`FusionNet` f_F: two 3x3 convs on each of log I_U and log I_S, concatenated, 3x3 conv to
  C/2, 3x3 conv to 3. Its output y is a log-domain correction of the composite: I_hat = (I_U + I_S - 1)
  exp(y), which is exact when both stages are (I = min(I, 1) + max(I, 1) - 1). The last conv starts at
  zero, so an untrained fusion passes the composite through.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from hdrcam.recon.presets import NetworkPreset
from hdrcam.recon.vgg import HYPERCOLUMN_CHANNELS, HYPERCOLUMN_LAYERS, Vgg19Features

HIGHLIGHT_PEAK = 256.0  # 2^8: the highest radiance the highlight stage represents
LEAKY_SLOPE = 0.2
_LOG_FLOOR = 1e-4  # log(I_U) is taken of max(I_U, 1e-4): finite for black and negative pixels


def _block(in_channels: int, out_channels: int, kernel: int = 3, dilation: int = 1, norm: bool = True) -> nn.Sequential:
    padding = dilation * (kernel // 2)
    layers: list[nn.Module] = [nn.Conv2d(in_channels, out_channels, kernel, padding=padding, dilation=dilation)]
    if norm:
        layers.append(nn.InstanceNorm2d(out_channels, affine=True))
    layers.append(nn.LeakyReLU(LEAKY_SLOPE))
    return nn.Sequential(*layers)


class SplittingNet(nn.Module):
    """f_U: LDR (N, 3, H, W) in [0, 1] -> (I_U, I_r), each (N, 3, H, W)."""

    def __init__(self, preset: NetworkPreset, vgg: Vgg19Features | None = None):
        super().__init__()
        if preset.vgg_features and vgg is None:
            raise ValueError(f"preset {preset.name!r} needs VGG-19 features")
        self.vgg = vgg if preset.vgg_features else None
        channels = preset.splitting_channels
        inputs = 3 + (HYPERCOLUMN_CHANNELS if self.vgg is not None else 0)
        self.entry = _block(inputs, channels, kernel=1)
        self.context = nn.Sequential(*(_block(channels, channels, dilation=d) for d in preset.splitting_dilations))
        self.exit = nn.Conv2d(channels, 6, 1)

    def forward(self, ldr: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        features = [ldr]
        if self.vgg is not None:
            size = ldr.shape[-2:]
            activations = self.vgg(ldr.clamp(0.0, 1.0), HYPERCOLUMN_LAYERS)
            features += [F.interpolate(activations[name], size=size, mode="bilinear", align_corners=False)
                         for name in HYPERCOLUMN_LAYERS]
        output = self.exit(self.context(self.entry(torch.cat(features, dim=1))))
        return ldr + output[:, :3], output[:, 3:]


class HighlightUNet(nn.Module):
    """f_S: I_r and the LDR frame (N, 3, H, W each) -> I_S in [1, 2^8]. H and W multiples of 16 (four pools)."""

    def __init__(self, preset: NetworkPreset):
        super().__init__()
        widths = preset.unet_channels
        self.encoders = nn.ModuleList()
        previous = 6
        for scale, width in enumerate(widths):
            first = _block(previous, width, kernel=7 if scale == 0 else 3)
            self.encoders.append(nn.Sequential(first, _block(width, width)))
            previous = width
        self.upsamplers = nn.ModuleList()
        self.decoders = nn.ModuleList()
        for scale in reversed(range(len(widths) - 1)):
            width = widths[scale]
            self.upsamplers.append(_block(widths[scale + 1], width))
            last_scale = scale == 0
            self.decoders.append(nn.Sequential(_block(2 * width, width),
                                               _block(width, width, norm=not last_scale)))
        self.exit = nn.Conv2d(widths[0], 3, 1)
        nn.init.constant_(self.exit.bias, -2.0)
        self.levels = len(widths)

    def forward(self, residual: torch.Tensor, ldr: torch.Tensor) -> torch.Tensor:
        multiple = 2 ** (self.levels - 1)
        if residual.shape[-1] % multiple or residual.shape[-2] % multiple:
            raise ValueError(f"highlight U-Net input must be a multiple of {multiple} px, got "
                             f"{tuple(residual.shape[-2:])}")
        skips = []
        value = torch.cat([residual, ldr], dim=1)
        for scale, encoder in enumerate(self.encoders):
            if scale:
                value = F.max_pool2d(value, 2)
            value = encoder(value)
            skips.append(value)
        for upsample, decoder, skip in zip(self.upsamplers, self.decoders, reversed(skips[:-1])):
            value = upsample(F.interpolate(value, scale_factor=2, mode="nearest"))
            value = decoder(torch.cat([value, skip], dim=1))
        return torch.exp(F.softplus(self.exit(value)).clamp(max=math.log(HIGHLIGHT_PEAK)))


class FusionNet(nn.Module):
    """f_F: (I_U, I_S) -> I_hat, the HDR estimate (N, 3, H, W), in [0, 2^8]."""

    def __init__(self, preset: NetworkPreset):
        super().__init__()
        branch, joint = preset.fusion_channels
        self.unsaturated_branch = nn.Sequential(_block(3, branch, norm=False), _block(branch, branch, norm=False))
        self.highlight_branch = nn.Sequential(_block(3, branch, norm=False), _block(branch, branch, norm=False))
        self.joint = _block(2 * branch, joint, norm=False)
        self.exit = nn.Conv2d(joint, 3, 3, padding=1)
        nn.init.zeros_(self.exit.weight)
        nn.init.zeros_(self.exit.bias)

    def forward(self, unsaturated: torch.Tensor, highlight: torch.Tensor) -> torch.Tensor:
        composite = unsaturated.clamp(min=0.0) + highlight - 1.0
        features = torch.cat([self.unsaturated_branch(torch.log(unsaturated.clamp(min=_LOG_FLOOR))),
                              self.highlight_branch(torch.log(highlight))], dim=1)
        correction = self.exit(self.joint(features)).clamp(-math.log(HIGHLIGHT_PEAK), math.log(HIGHLIGHT_PEAK))
        return (composite.clamp(min=0.0) * torch.exp(correction)).clamp(max=HIGHLIGHT_PEAK)
