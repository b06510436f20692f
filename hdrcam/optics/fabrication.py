"""Fabrication export: quantise a height map to 2^k levels and split it into k binary lithography masks.

Level step = h_max / levels. Heights are rounded to the nearest level; a height that rounds to
``levels`` steps (= h_max, a full 2 pi at the design wavelength) wraps to level 0. A height map gives each
feature's height above the deepest etch, so the plate's top surface is the highest level (levels - 1) and a
feature of level L is etched (levels - 1 - L) steps deep. Mask b (b = 0..k-1) marks the features etched by 2^b
steps: sum_b 2^b mask_b = levels - 1 - L (masks of the level bits themselves would etch the relief inverted,
a phase of -phi, whose PSF is the design's turned 180 degrees; a plate turned face-reversed mirrors its PSF).

Efficiency estimates at the design wavelength (where h_max is 2 pi of phase):
- ideal multilevel: sinc^2(1 / levels) (Swanson 1989), 0.987 for 16 levels;
- of this map: |mean exp(j (phi_quantised - phi_continuous))|^2, the on-axis Strehl of the error.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass
class QuantisedHeightMap:
    levels: int
    step_m: float
    level_index: np.ndarray  # int, 0..levels-1
    heights_m: np.ndarray  # level_index * step_m

    def etch_steps(self) -> np.ndarray:
        """Each feature's etch depth in steps below the top surface (the highest level): levels - 1 - level."""
        return self.levels - 1 - self.level_index

    def masks(self) -> list[np.ndarray]:
        """Binary etch masks, least significant first: True where mask b etches 2^b steps."""
        depth = self.etch_steps()
        return [((depth >> bit) & 1).astype(bool) for bit in range(int(math.log2(self.levels)))]


def quantise_heightmap(heights_m: np.ndarray, h_max_m: float, levels: int) -> QuantisedHeightMap:
    """Round heights in [0, h_max] to ``levels`` equal steps (wrapping h_max to 0)."""
    if levels < 2 or levels & (levels - 1):
        raise ValueError(f"levels must be a power of two >= 2, got {levels}")
    heights = np.asarray(heights_m, dtype=np.float64)
    if not np.all(np.isfinite(heights)):
        raise ValueError("height map has NaN or Inf values")
    low, high = float(heights.min()), float(heights.max())
    if low < -1e-12 or high > h_max_m * (1 + 1e-6):
        raise ValueError(f"heights span [{low:.4g}, {high:.4g}] m, outside [0, h_max = {h_max_m:.4g}] m")
    step = h_max_m / levels
    index = np.rint(heights / step).astype(np.int64) % levels
    return QuantisedHeightMap(levels=levels, step_m=step, level_index=index, heights_m=index * step)


def ideal_multilevel_efficiency(levels: int) -> float:
    """First-order efficiency of an ideal ``levels``-step kinoform: sinc^2(1 / levels)."""
    x = math.pi / levels
    return (math.sin(x) / x) ** 2


def quantisation_strehl(heights_m: np.ndarray, quantised_m: np.ndarray, phase_per_height_rad_m: float) -> float:
    """|mean exp(j k (n - 1) (h_q - h))|^2: the fraction of the design's on-axis field the quantisation keeps."""
    error = phase_per_height_rad_m * (np.asarray(quantised_m, np.float64) - np.asarray(heights_m, np.float64))
    return float(np.abs(np.mean(np.exp(1j * error))) ** 2)


def design_wavelength_m(h_max_m: float, index_of_wavelength) -> float:
    """Wavelength at which h_max is one full wave of phase: lambda = h_max (n(lambda) - 1) (fixed point)."""
    wavelength = 550e-9
    for _ in range(50):
        wavelength = h_max_m * (float(index_of_wavelength(wavelength)) - 1.0)
    return wavelength
