"""PSF energy regulariser (paper Sec. 3.3): keep ~94 % of the energy in the PSF centre."""

from __future__ import annotations

import torch


def centre_energy_fraction(psf: torch.Tensor, radius_px: int) -> torch.Tensor:
    """Energy in the (2r+1)^2 box about the axis (pixel S // 2) over the PSF's total, per channel."""
    size = psf.shape[-1]
    if size < 2 * radius_px + 1:  # a negative start would slice from the far edge
        raise ValueError(f"a {size} px PSF holds no {2 * radius_px + 1} px centre box")
    start = size // 2 - radius_px
    centre = psf[..., start:start + 2 * radius_px + 1, start:start + 2 * radius_px + 1]
    return centre.sum(dim=(-2, -1)) / psf.sum(dim=(-2, -1))


def energy_regulariser(centre_fraction: torch.Tensor, target: float | torch.Tensor = 0.94) -> torch.Tensor:
    """Mean squared deviation of the centre energy fraction from ``target`` (a number or one per channel)."""
    return ((centre_fraction - torch.as_tensor(target).to(centre_fraction)) ** 2).mean()
