"""Network presets: the paper's widths, and narrower ones that train and run on a CPU.

Every preset has the same three stages (paper Sec. 4). ``paper`` feeds the splitting net a VGG-19
hypercolumn and trains with VGG perceptual losses; ``lite`` and ``fast`` use no pretrained network at all
(their losses are L1 on a log encoding plus gradient terms). Parameters and GFLOPs per preset are measured
by ``tools/bench_recon.py`` and listed in the README.
"""

from __future__ import annotations

import dataclasses

from hdrcam.errors import InputError


@dataclasses.dataclass(frozen=True)
class NetworkPreset:
    """Widths (channels) of the three stages."""

    name: str
    splitting_channels: int  # paper: 64
    splitting_dilations: tuple[int, ...]  # paper: 1, 2, 4, ..., 64 (seven 3x3 convs)
    unet_channels: tuple[int, ...]  # channels at each of the 5 U-Net scales; paper: 64 .. 1024
    fusion_channels: tuple[int, int]  # (per-input convs, the joint conv); paper: (64, 32)
    vgg_features: bool  # VGG-19 hypercolumn into the splitting net, VGG perceptual losses


PRESETS = {
    "paper": NetworkPreset("paper", 64, (1, 2, 4, 8, 16, 32, 64), (64, 128, 256, 512, 1024), (64, 32), True),
    "lite": NetworkPreset("lite", 32, (1, 2, 4, 8, 16, 32, 64), (16, 32, 64, 128, 256), (32, 16), False),
    "fast": NetworkPreset("fast", 16, (1, 2, 4, 8, 16, 32, 64), (8, 16, 32, 64, 128), (16, 8), False),
}


def preset(name: str) -> NetworkPreset:
    """The preset called ``name``."""
    if name not in PRESETS:
        raise InputError(f"unknown network preset {name!r}; choose one of {', '.join(PRESETS)}")
    return PRESETS[name]
