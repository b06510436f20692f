"""The whole reconstruction network: f_U -> f_S -> f_F (paper Fig. 3), with the preset it was built from."""

from __future__ import annotations

import dataclasses

import torch
from torch import nn

from hdrcam.recon.presets import NetworkPreset
from hdrcam.recon.stages import FusionNet, HighlightUNet, SplittingNet
from hdrcam.recon.vgg import Vgg19Features


@dataclasses.dataclass
class Reconstruction:
    """Outputs of one forward pass (N, 3, H, W each), linear relative radiance (1.0 = sensor full well)."""

    unsaturated: torch.Tensor  # I_U, the frame without streaks, in about [0, 1]
    residual: torch.Tensor  # I_r, the streak residual the highlight stage reads
    highlight: torch.Tensor  # I_S in [1, 2^8]
    hdr: torch.Tensor  # I_hat, the HDR estimate


class ReconstructionNet(nn.Module):
    """LDR frame (N, 3, H, W) in [0, 1], H and W multiples of 16 -> :class:`Reconstruction`."""

    def __init__(self, preset: NetworkPreset, vgg: Vgg19Features | None = None):
        super().__init__()
        self.preset = preset
        self.splitting = SplittingNet(preset, vgg)
        self.highlight = HighlightUNet(preset)
        self.fusion = FusionNet(preset)

    def forward(self, ldr: torch.Tensor, *, highlights: bool = True) -> Reconstruction:
        """``highlights`` False skips f_S and f_F (a frame with nothing clipped): I_hat = I_U."""
        unsaturated, residual = self.splitting(ldr)
        if not highlights:
            ones = torch.ones_like(unsaturated)
            return Reconstruction(unsaturated, residual, ones, unsaturated.clamp(min=0.0))
        highlight = self.highlight(residual, ldr)
        return Reconstruction(unsaturated, residual, highlight, self.fusion(unsaturated, highlight))

    def trainable_state(self) -> dict[str, torch.Tensor]:
        """The state dict without the frozen VGG-19 (shipped checkpoints stay small)."""
        return {key: value for key, value in self.state_dict().items() if not key.startswith("splitting.vgg.")}
