"""Parameter and floating-point-operation counts of a network (convolutions and their biases)."""

from __future__ import annotations

import torch
from torch import nn


def parameter_count(module: nn.Module, trainable_only: bool = True) -> int:
    return sum(p.numel() for p in module.parameters() if p.requires_grad or not trainable_only)


def forward_gflops(module: nn.Module, example: torch.Tensor, **kwargs) -> float:
    """GFLOPs of one forward pass on ``example``: 2 x multiply-adds of every Conv2d (the usual convention)."""
    total = [0]

    def count(layer: nn.Conv2d, _inputs, output: torch.Tensor) -> None:
        kernel = layer.kernel_size[0] * layer.kernel_size[1] * layer.in_channels // layer.groups
        total[0] += 2 * kernel * output.numel()

    handles = [layer.register_forward_hook(count) for layer in module.modules() if isinstance(layer, nn.Conv2d)]
    try:
        with torch.no_grad():
            module(example, **kwargs)
    finally:
        for handle in handles:
            handle.remove()
    return total[0] / 1e9
